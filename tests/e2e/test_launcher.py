"""The launcher end to end: real processes, real sockets, the CLI as a subprocess."""

from __future__ import annotations

import os
import signal
import time

import msgpack
import pytest
import zmq

from slipstack.messages import decode

from .conftest import pid_alive

pytestmark = pytest.mark.e2e


def _pids(graph: dict) -> dict[str, int]:
    return {name: n["pid"] for name, n in graph["nodes"].items()}


def _echo_once(g, topic: str) -> str:
    out = g.cli("topic", "echo", topic, "--once", "--timeout", "10")
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_demo_graph_respawns_a_killed_node_and_stops_cleanly_on_each_signal(launch):
    for sig in (signal.SIGINT, signal.SIGTERM):
        g = launch("demo")
        graph = g.wait_ready()
        pids = _pids(graph)
        assert len(pids) == 3 and all(pid_alive(p) for p in pids.values())
        assert "seq:" in _echo_once(g, "ft/relayed")

        os.kill(pids["relay"], signal.SIGKILL)
        deadline = time.monotonic() + 15
        while time.monotonic() < deadline:
            now = g.graph()["nodes"]["relay"]
            if now["restarts"] == 1 and now["pid"] != pids["relay"] and pid_alive(now["pid"]):
                break
            time.sleep(0.05)
        else:
            pytest.fail(f"relay not respawned:\n{g.log()}")
        assert "seq:" in _echo_once(g, "ft/relayed")  # data flows again through the new relay

        all_pids = [*_pids(g.graph()).values(), g.proc.pid]
        t0 = time.monotonic()
        g.proc.send_signal(sig)
        g.proc.wait(10)
        while any(pid_alive(p) for p in all_pids) and time.monotonic() - t0 < 3.0:
            time.sleep(0.02)
        gone_after = time.monotonic() - t0
        assert not any(pid_alive(p) for p in all_pids), f"processes left after {sig.name}"
        assert gone_after < 3.0
        assert g.proc.returncode == 0, g.log()


def _read_diagnostics(endpoint: str, node: str, want: str, timeout: float = 10.0) -> dict:
    ctx = zmq.Context.instance()
    sub = ctx.socket(zmq.SUB)
    sub.setsockopt(zmq.LINGER, 0)
    sub.setsockopt(zmq.SUBSCRIBE, b"diagnostics")
    sub.connect(endpoint)
    try:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if sub.poll(200):
                _, payload = sub.recv_multipart()
                diag = decode(payload)
                if diag.node == node and diag.counters.get(want, 0) >= 1:
                    return diag.counters
        raise AssertionError(f"no diagnostics from {node} with {want} >= 1")
    finally:
        sub.close()


def test_malformed_frame_is_counted_and_dropped_and_the_node_keeps_running(launch):
    g = launch("demo")
    graph = g.wait_ready()
    relay = graph["nodes"]["relay"]
    ctx = zmq.Context.instance()
    pub = ctx.socket(zmq.XPUB)
    pub.setsockopt(zmq.LINGER, 0)
    pub.connect(relay["inject"]["ft/wrench"])
    assert pub.poll(5000), "relay never subscribed to the injection socket"
    pub.recv()
    pub.send_multipart([b"ft/wrench", b"\xc1 not msgpack"])
    pub.send_multipart([b"ft/wrench", msgpack.packb(["slipstack/Wrench", 1, [0, 0, 0, {}], [[1, 2]]])])
    counters = _read_diagnostics(relay["pub"], "relay", "in.ft/wrench.rejected")
    pub.close()
    assert pid_alive(relay["pid"])
    assert g.graph()["nodes"]["relay"]["restarts"] == 0
    assert "seq:" in _echo_once(g, "ft/relayed")
    assert counters["in.ft/wrench.received"] > counters["in.ft/wrench.rejected"] >= 1


def test_a_bad_parameter_stops_the_launch_naming_the_node(launch, run_root):
    bad = run_root / "bad.toml"
    bad.write_text('[[node]]\nname = "src"\ntype = "wrench_source"\nparams = { rate_hz = "fast" }\n')
    g = launch(str(bad))
    assert g.proc.wait(30) != 0
    assert "src" in g.log() and "rate_hz" in g.log()


def test_a_container_runs_its_nodes_in_one_process_hands_messages_over_and_respawns_whole(launch):
    g = launch("demo", "container:=pipeline")
    graph = g.wait_ready()
    nodes = graph["nodes"]
    assert nodes["relay"]["pid"] == nodes["sink"]["pid"] != nodes["source"]["pid"]
    assert nodes["relay"]["process"] == nodes["sink"]["process"] == "pipeline"
    # the relay still publishes on the bus for everyone else ...
    assert "seq:" in _echo_once(g, "ft/relayed")
    # ... and the sink, which has no socket to the relay, gets every message in-process
    counters = _read_diagnostics(nodes["sink"]["pub"], "sink", "in.ft/relayed.received")
    assert counters["in.ft/relayed.received"] >= 1
    assert counters.get("in.ft/relayed.lost", 0) == 0

    os.kill(nodes["sink"]["pid"], signal.SIGKILL)  # the container goes down as one
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline:
        now = g.graph()["nodes"]
        if now["relay"]["restarts"] == now["sink"]["restarts"] == 1 and pid_alive(now["sink"]["pid"]):
            break
        time.sleep(0.05)
    else:
        pytest.fail(f"container not respawned:\n{g.log()}")
    assert now["relay"]["pid"] == now["sink"]["pid"] != nodes["sink"]["pid"]
    assert "seq:" in _echo_once(g, "ft/relayed")
    assert "in 2 processes: pipeline (relay, sink), source" in g.log()
    assert g.stop() == 0


def test_container_members_must_share_their_process_settings(launch, run_root):
    bad = run_root / "bad.toml"
    bad.write_text('[[node]]\nname = "relay"\ntype = "relay"\ncontainer = "c"\nrespawn = true\n'
                   '[[node]]\nname = "sink"\ntype = "sink"\ncontainer = "c"\n')
    g = launch(str(bad))
    assert g.proc.wait(30) != 0
    assert "relay and sink share container 'c'" in g.log()
