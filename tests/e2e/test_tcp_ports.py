"""tcp nodes stay available: a crashed node's port is still the launch's while it restarts (no
other local user can take it first), and connections that never finish their handshake are
closed within seconds, not held for 30 s each.

A real launched graph with its relay on tcp and the graph's CURVE keys (a user's
configuration, as in docs/architecture.md §5)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time

import pytest

from slipstack.nodes.runtime.transport import HANDSHAKE_MS

from .conftest import pid_alive

pytestmark = pytest.mark.e2e

GRAPH = """
[launch]
description = "relay on tcp"
keys = "{keys}"

[[node]]
name = "source"
type = "wrench_source"
params = {{ rate_hz = 500.0 }}

[[node]]
name = "relay"
type = "relay"
transport = "tcp"
respawn = true

[[node]]
name = "sink"
type = "sink"
"""


def _tcp_graph(tmp_path):
    keys = tmp_path / "keys"
    made = subprocess.run([sys.executable, "-m", "slipstack.launch.cli", "keys", str(keys)],
                          capture_output=True, text=True, timeout=60)
    assert made.returncode == 0, made.stderr
    path = tmp_path / "tcp.toml"
    path.write_text(GRAPH.format(keys=keys))
    return path


def _host_port(endpoint: str) -> tuple[str, int]:
    host, _, port = endpoint[len("tcp://"):].rpartition(":")
    return host, int(port)


def _fds(pid: int) -> int:
    return len(os.listdir(f"/proc/{pid}/fd"))


def test_a_crashed_tcp_node_keeps_its_port_and_comes_back(launch, tmp_path):
    g = launch(str(_tcp_graph(tmp_path)))
    graph = g.wait_ready(timeout=90)
    relay = graph["nodes"]["relay"]
    host, port = _host_port(relay["pub"])
    os.kill(relay["pid"], signal.SIGKILL)
    squatter = socket.socket(socket.AF_INET, socket.SOCK_STREAM)  # another local user, as fast as it can
    squatter.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # past the closed connections' TIME_WAIT
    squatted = False
    deadline = time.monotonic() + 2.0
    while time.monotonic() < deadline and not squatted:
        try:
            squatter.bind((host, port))
            squatter.listen(1)
            squatted = True
        except OSError:
            time.sleep(0.001)
    try:
        assert not squatted, "another process took the crashed node's port"
        deadline = time.monotonic() + 60
        while not ((pid := g.graph()["nodes"]["relay"].get("pid")) and pid != relay["pid"] and pid_alive(pid)):
            assert time.monotonic() < deadline and "ABANDONED" not in g.log(), g.log()[-3000:]
            time.sleep(0.05)
        echo = g.cli("topic", "echo", "ft/relayed", "--once", timeout=60)  # it publishes on its port again
        assert echo.returncode == 0 and "force" in echo.stdout, (echo.stderr, g.log()[-3000:])
    finally:
        squatter.close()


def test_silent_connections_are_closed_after_the_handshake_limit(launch, tmp_path):
    g = launch(str(_tcp_graph(tmp_path)))
    graph = g.wait_ready(timeout=90)
    relay = graph["nodes"]["relay"]
    host, port = _host_port(relay["pub"])
    before = _fds(relay["pid"])
    silent = []
    for _ in range(300):  # connect and never say a word
        s = socket.create_connection((host, port), timeout=5)
        silent.append(s)
    try:
        time.sleep(1.0)
        assert _fds(relay["pid"]) > before + 100  # the node did accept them
        deadline = time.monotonic() + 2.5 * HANDSHAKE_MS / 1e3  # ZeroMQ's default held them 30 s and more
        while _fds(relay["pid"]) > before + 20:
            assert time.monotonic() < deadline, (before, _fds(relay["pid"]))
            time.sleep(0.2)
    finally:
        for s in silent:
            s.close()
