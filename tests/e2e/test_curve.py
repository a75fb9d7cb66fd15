"""tcp links only with ZeroMQ CURVE: a stranger on the machine can neither listen nor pass for a node.

A real launched graph (synthetic source → relay → sink) with the source on tcp. With
the graph's keys the relay and an authorised subscriber receive every frame; a plain
subscriber (another local user, no keys) and a CURVE client with a key pair of its own
receive nothing. Without keys the launch is
refused, unless the file says ``insecure = true``.
"""

from __future__ import annotations

import subprocess
import sys

import pytest
import zmq
import zmq.auth

from slipstack.nodes.runtime import curve
from slipstack.nodes.runtime.transport import make_sub

from .conftest import count_frames

pytestmark = pytest.mark.e2e

GRAPH = """
[launch]
description = "source on tcp"
{security}

[[node]]
name = "source"
type = "wrench_source"
transport = "tcp"
params = {{ rate_hz = 500.0 }}

[[node]]
name = "relay"
type = "relay"

[[node]]
name = "sink"
type = "sink"
"""


def _launch_file(tmp_path, security: str):
    path = tmp_path / "tcp.toml"
    path.write_text(GRAPH.format(security=security))
    return path


def test_tcp_without_keys_is_refused_with_what_to_do(launch, tmp_path):
    g = launch(str(_launch_file(tmp_path, "")))
    assert g.wait_exit(60) != 0
    assert "slipstack keys" in g.log() and "insecure = true" in g.log()


def test_only_holders_of_the_keys_receivecount_frames(launch, tmp_path):
    keys = tmp_path / "keys"
    made = subprocess.run([sys.executable, "-m", "slipstack.launch.cli", "keys", str(keys)],
                          capture_output=True, text=True, timeout=60)
    assert made.returncode == 0, made.stderr
    assert (keys.stat().st_mode & 0o777) == 0o700
    g = launch(str(_launch_file(tmp_path, f'keys = "{keys}"')))
    graph = g.wait_ready(timeout=90)
    endpoint = graph["nodes"]["source"]["pub"]
    assert endpoint.startswith("tcp://") and graph["keys"] == str(keys.resolve())

    ctx = zmq.Context()
    try:
        stranger = ctx.socket(zmq.SUB)  # another local user: no keys
        stranger.setsockopt(zmq.SUBSCRIBE, b"")
        stranger.setsockopt(zmq.LINGER, 0)
        stranger.connect(endpoint)
        impostor = ctx.socket(zmq.SUB)  # a CURVE client with a key pair of its own and the graph's public key
        impostor.curve_publickey, impostor.curve_secretkey = zmq.curve_keypair()
        impostor.curve_serverkey = zmq.auth.load_certificate(keys / "graph.key")[0]  # no secret
        impostor.setsockopt(zmq.SUBSCRIBE, b"")
        impostor.setsockopt(zmq.LINGER, 0)
        impostor.connect(endpoint)
        curve.use_keys(keys)
        try:
            member = make_sub(ctx, [endpoint], None)
        finally:
            curve.use_keys(None)
        assert count_frames(member, 2.0) > 100  # 500 Hz: the authorised subscriber is served
        assert count_frames(stranger, 1.0) == 0
        assert count_frames(impostor, 1.0) == 0
    finally:
        ctx.destroy(linger=0)  # closes the sockets also when an assertion failed (term would wait on them)
    echo = g.cli("topic", "echo", "ft/relayed", "--once", timeout=60)  # the relay got through, and tools attach
    assert echo.returncode == 0 and "force" in echo.stdout, echo.stderr


def test_insecure_is_an_explicit_opt_in(launch, tmp_path):
    g = launch(str(_launch_file(tmp_path, "insecure = true")))
    graph = g.wait_ready(timeout=90)
    ctx = zmq.Context()
    try:
        plain = ctx.socket(zmq.SUB)
        plain.setsockopt(zmq.SUBSCRIBE, b"")
        plain.setsockopt(zmq.LINGER, 0)
        plain.connect(graph["nodes"]["source"]["pub"])
        assert count_frames(plain, 2.0) > 100
        plain.close()
    finally:
        ctx.term()
