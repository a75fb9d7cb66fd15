"""Floods through the injection endpoint (what ``topic pub`` and ``bag play`` reach)
against a launched demo graph: the node admits at most its injection rate, says how
many it dropped, and its bus input carries on during and after the flood."""

from __future__ import annotations

import time

import numpy as np
import pytest
import zmq

from slipstack.messages import Header, Wrench, decode, encode
from slipstack.nodes.runtime.process import RunSpec
from slipstack.nodes.tools.topic_pub import Injector
from slipstack.nodes.tools.topic_tools import resolve_topic
from slipstack.nodes.runtime.transport import make_sub

pytestmark = pytest.mark.e2e

MARK = 777_777  # device_seq of the injected frames
FLOOD = 20_000


def _flood_frame(k: int) -> bytes:
    msg = Wrench(force=np.array([0.0, 0.0, 99.0]), torque=np.zeros(3), device_seq=MARK)
    return encode(msg, Header(1, k, 1, {}))  # stale-stamped: sample time 1 ns after boot


def _diagnostics(sock: zmq.Socket, node: str, want: str, timeout_s: float = 15.0) -> dict:
    """The first diagnostics of ``node`` with a counter whose name starts with ``want``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if sock.poll(100):
            topic, payload = sock.recv_multipart()
            if topic == b"diagnostics":
                d = decode(payload)
                if d.node == node and any(k.startswith(want) for k in d.counters):
                    return d.counters
    raise AssertionError(f"no diagnostics of {node} with {want}")


def test_an_injection_flood_is_rate_limited_counted_and_the_bus_carries_on(launch):
    g = launch("demo", "duration_s:=40")
    graph = g.wait_ready()
    relay = graph["nodes"]["relay"]
    ctx = zmq.Context.instance()
    out = make_sub(ctx, [relay["pub"]], None, rcvhwm=10 * FLOOD)
    injector = Injector(resolve_topic(graph, "ft/wrench"))
    try:
        assert injector.wait_for_subscribers(10.0) == 1
        time.sleep(0.3)  # the SUB to the relay's output joins (it reads from then on)
        t0 = time.monotonic()
        for k in range(FLOOD):  # as fast as this process can: tens of kHz
            injector.send(_flood_frame(k))
        flood_end_ns = time.monotonic_ns()
        relayed_marked = 0
        fresh_after_flood = 0
        last_marked = t0
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and fresh_after_flood < 50:
            if not out.poll(100):
                continue
            topic, payload = out.recv_multipart()
            if topic != b"ft/relayed":
                continue
            msg = decode(payload, Wrench)
            if msg.device_seq == MARK:
                relayed_marked += 1
                last_marked = time.monotonic()
            elif msg.header.stamp_ns > flood_end_ns:
                fresh_after_flood += 1
        # the bus input carries on after the flood: fresh source samples come through
        assert fresh_after_flood >= 50
        # the relay handled at most what its token bucket admits over the time it read
        # the flood (wall time only loosens this bound on a loaded machine)
        spec = RunSpec(name="defaults")
        admitted = spec.inject_rate_hz * (last_marked - t0 + 0.5) + spec.inject_burst
        assert 0 < relayed_marked <= admitted, (relayed_marked, admitted)
        counters = _diagnostics(out, "relay", "inject.dropped_")  # over the rate, or queued meanwhile
        dropped = sum(v for k, v in counters.items() if k.startswith("inject.dropped_"))
        assert 0 < dropped <= FLOOD - relayed_marked, counters
    finally:
        injector.close()
        out.close()
