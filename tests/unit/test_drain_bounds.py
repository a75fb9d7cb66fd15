"""Bounded work per wake-up of the process executor, on real ZeroMQ sockets: a
``latest`` backlog costs one decode and one handler call, injected frames pass a
token bucket and go to ``latest`` inputs newest only."""

from __future__ import annotations

import time
from contextlib import contextmanager

import numpy as np
import pytest
import zmq

from slipstack.messages import Header, Wrench, encode
from slipstack.nodes.runtime import process
from slipstack.nodes.runtime.node import Input, Node
from slipstack.nodes.runtime.process import RunSpec, _Member
from slipstack.nodes.runtime.transport import make_pub


class _Recorder(Node):
    """Remembers the device_seq of every wrench handled, per input."""

    name = "recorder_node"
    inputs = {"latest": Input("ft/wrench", Wrench), "queued": Input("grip/wrench", Wrench, policy="queue", depth=10_000)}

    def __init__(self) -> None:
        super().__init__()
        self.handled: dict[str, list[int]] = {"latest": [], "queued": []}

    def on_latest(self, msg: Wrench, ctx) -> None:
        self.handled["latest"].append(msg.device_seq)

    def on_queued(self, msg: Wrench, ctx) -> None:
        self.handled["queued"].append(msg.device_seq)


def _wrench(k: int, stamp_ns: int = 1) -> bytes:
    return encode(Wrench(force=np.zeros(3), torque=np.zeros(3), device_seq=k), Header(stamp_ns, k, stamp_ns, {}))


@contextmanager
def _injected(ctx: zmq.Context, tmp_path, **spec):
    """(node, member, tool): a _Recorder member whose injection endpoint takes every
    input topic, and a tool XPUB connected to it that every topic has joined."""
    endpoint = f"ipc://{tmp_path}/r.inject"
    node = _Recorder()
    member = _Member(node, RunSpec(name="r", inject={t: endpoint for t in spec.pop("topics")}, **spec), ctx)
    tool = ctx.socket(zmq.XPUB)
    tool.setsockopt(zmq.LINGER, 0)
    tool.connect(endpoint)
    try:
        joined: set[bytes] = set()
        deadline = time.monotonic() + 10
        while len(joined) < len(member.inject_routes):
            member.inject_sock.getsockopt(zmq.EVENTS)  # a socket attaches its peers when used
            if tool.poll(10):
                joined.add(tool.recv())
            assert time.monotonic() < deadline, "the member never subscribed"
        yield node, member, tool
    finally:
        tool.close(linger=0)
        for sock in member.sockets():
            sock.close(linger=0)


@pytest.fixture
def ctx():
    return zmq.Context.instance()


def _settle(seconds: float = 0.5) -> None:
    time.sleep(seconds)  # let ZeroMQ's I/O thread move every sent frame into the receiving queue


def test_a_latest_backlog_is_decoded_newest_first_and_handled_once(ctx, tmp_path, monkeypatch):
    endpoint = f"ipc://{tmp_path}/src.pub"
    pub = make_pub(ctx, endpoint)
    node = _Recorder()
    member = _Member(node, RunSpec(name="r", subs={"ft/wrench": [endpoint]}), ctx)
    sock = next(s for s, (name, _, _) in member.sub_topic.items() if name == "latest")
    try:
        deadline = time.monotonic() + 10
        while not member.missing_subscribers() == {} or not pub.poll(10):
            sock.getsockopt(zmq.EVENTS)
            assert time.monotonic() < deadline
        pub.recv()
        for k in range(90):  # below both high-water marks (100 at the subscriber)
            pub.send_multipart([b"ft/wrench", _wrench(k)])
        _settle()
        decoded = []
        real_receive = member.host.receive
        monkeypatch.setattr(member.host, "receive", lambda *a, **kw: decoded.append(a[1]) or real_receive(*a, **kw))
        member.drain("latest", sock)
        assert node.handled["latest"] == [89]
        assert len(decoded) == 1
        c = member.host.counters
        assert c["in.ft/wrench.received"] == 90 and c["in.ft/wrench.dropped"] == 89
        assert c["in.ft/wrench.lost"] == 0  # skipped frames are not a sequence gap
    finally:
        for s in member.sockets():
            s.close(linger=0)
        pub.close(linger=0)


def test_injected_frames_pass_a_token_bucket_and_latest_inputs_get_the_newest(ctx, tmp_path):
    with _injected(ctx, tmp_path, topics=["ft/wrench", "grip/wrench"], inject_rate_hz=1000.0,
                   inject_burst=50) as (node, member, tool):
        for k in range(40):
            tool.send_multipart([b"ft/wrench", _wrench(k)])
            tool.send_multipart([b"grip/wrench", _wrench(1000 + k)])
        _settle()
        t0 = 10**12
        member.drain_injected(t0)  # 80 frames against a full bucket of 50
        c = member.host.counters
        assert c["inject.dropped_rate"] == 30
        assert node.handled["latest"] == [24]  # 25 of ft/wrench admitted: the newest handled
        assert node.handled["queued"] == [1000 + k for k in range(25)]  # every admitted one, in order
        assert c["in.ft/wrench.dropped"] == 24

        for k in range(40, 60):
            tool.send_multipart([b"ft/wrench", _wrench(k)])
        _settle()
        member.drain_injected(t0 + 10_000_000)  # 10 ms later: 10 tokens earned
        assert c["inject.dropped_rate"] == 40
        assert node.handled["latest"] == [24, 49]


def test_one_wake_up_reads_a_bounded_number_of_injected_frames(ctx, tmp_path, monkeypatch):
    monkeypatch.setattr(process, "_INJECT_READ_LIMIT", 100)
    with _injected(ctx, tmp_path, topics=["ft/wrench"], inject_burst=1000) as (node, member, tool):
        for k in range(300):
            tool.send_multipart([b"ft/wrench", _wrench(k, stamp_ns=5)])  # stale-stamped flood
        _settle()
        c = member.host.counters

        def taken() -> int:
            return c["in.ft/wrench.received"] + c["inject.dropped_rate"]

        # wake up until all 300 are taken (on a loaded machine ZeroMQ may still be moving
        # some into the queue): never more than the limit per wake-up
        reads, deadline = [], time.monotonic() + 30.0
        while taken() < 300 and time.monotonic() < deadline:
            before = taken()
            member.drain_injected(10**12)
            reads.append(taken() - before)
            if not reads[-1]:
                time.sleep(0.05)
        assert taken() == 300 and all(r <= 100 for r in reads), reads
        woke = [r for r in reads if r]
        assert len(woke) >= 3 and len(node.handled["latest"]) == len(woke)  # one handler call per wake-up


def test_a_flood_over_the_rate_pauses_reading_after_a_bounded_number_of_frames(ctx, tmp_path):
    with _injected(ctx, tmp_path, topics=["ft/wrench"], inject_burst=10) as (node, member, tool):
        for k in range(500):
            tool.send_multipart([b"ft/wrench", _wrench(k)])
        _settle()
        t0 = 10**12
        member.drain_injected(t0)
        c = member.host.counters
        assert c["in.ft/wrench.received"] == 10  # the burst
        assert c["inject.dropped_rate"] == process._OVER_RATE_READS  # then a bounded number read and dropped
        assert c["inject.pauses"] == 1
        assert member.inject_resume_ns == t0 + process._INJECT_PAUSE_NS
        member.start_clock(t0)  # next diagnostics in 1 s
        assert member.next_due() == member.inject_resume_ns  # the loop wakes to resume reading
        assert member.inject_sock.getsockopt(zmq.EVENTS) & zmq.POLLIN  # the rest is left unread


class _Heavy(Node):
    """A queue input whose every frame costs its handler ``COST_S`` of work (a heavy legal frame)."""

    COST_S = 0.005
    name = "heavy_node"
    inputs = {"queued": Input("grip/wrench", Wrench, policy="queue", depth=10_000)}

    def __init__(self) -> None:
        super().__init__()
        self.handled = 0

    def on_queued(self, msg: Wrench, ctx) -> None:
        end = time.thread_time() + self.COST_S  # CPU time, as the executor charges it, on a busy host too
        while time.thread_time() < end:
            pass
        self.handled += 1


def test_injected_work_takes_at_most_its_share_of_the_node_whatever_each_frame_costs(ctx, tmp_path):
    """A 5 kHz flood of legal frames, 5 ms of handler work each, within the frame and byte budgets:
    over one second of the node's clock they may take 20 % of it (and the 20 ms burst), not all of
    it (before: the frame bucket admitted 200 at once, a second of work); what queued while it
    was paused is dropped, not handled late."""
    endpoint = f"ipc://{tmp_path}/h.inject"
    node = _Heavy()
    member = _Member(node, RunSpec(name="h", inject={"grip/wrench": endpoint}, inject_rate_hz=100_000.0,
                                   inject_burst=100_000), ctx)
    tool = ctx.socket(zmq.XPUB)
    tool.setsockopt(zmq.LINGER, 0)
    tool.connect(endpoint)
    try:
        deadline = time.monotonic() + 10
        while not tool.poll(10):
            member.inject_sock.getsockopt(zmq.EVENTS)
            assert time.monotonic() < deadline, "the member never subscribed"
        tool.recv()
        t0, now, work, k = 10**12, 10**12, 0, 0
        while now < t0 + 1_000_000_000:  # one second of the node's clock, in 1 ms wake-ups, 5 frames each
            for _ in range(5):
                tool.send_multipart([b"grip/wrench", _wrench(k)], zmq.NOBLOCK)
                k += 1
            if member.inject_resume_ns is None or now >= member.inject_resume_ns:
                member.inject_resume_ns = None
                w0 = time.thread_time_ns()
                member.drain_injected(now)
                spent = time.thread_time_ns() - w0
                member.charge_injected_work(spent, now)
                work += spent
            now += 1_000_000
        share = RunSpec.inject_work_share
        assert node.handled >= 2, dict(member.host.counters)  # not vacuous: the share was used
        assert work <= share * 1e9 + RunSpec.inject_work_burst_s * 1e9 + 2 * _Heavy.COST_S * 1e9, work / 1e6
        assert node.handled <= (share + RunSpec.inject_work_burst_s) / _Heavy.COST_S + 2, node.handled
        assert member.host.counters["inject.work_pauses"] >= 1
        assert member.host.counters["inject.dropped_backlog"] > 0
    finally:
        tool.close(linger=0)
        for sock in member.sockets():
            sock.close(linger=0)


def test_a_frame_over_the_byte_budget_is_dropped_before_it_is_decoded(ctx, tmp_path, monkeypatch):
    """A wrench of ~55 KB (8000 header sources: a frame of the right shape, 200 times a wrench's size) against a
    byte burst of 16 KB: read and counted, never unpacked."""
    heavy = encode(Wrench(force=np.zeros(3), torque=np.zeros(3)), Header(1, 0, 1, {f"s{k}": 1 for k in range(8000)}))
    with _injected(ctx, tmp_path, topics=["ft/wrench"], inject_burst_bytes=16_384) as (node, member, tool):
        decoded = []
        real_receive = member.host.receive
        monkeypatch.setattr(member.host, "receive", lambda *a, **kw: decoded.append(a[1]) or real_receive(*a, **kw))
        for k in range(5):
            tool.send_multipart([b"ft/wrench", heavy])
        tool.send_multipart([b"ft/wrench", _wrench(7)])
        _settle()
        member.drain_injected(10**12)
        c = member.host.counters
        assert len(heavy) > 50_000 and c["inject.dropped_bytes"] == 5 and decoded == [_wrench(7)]
        assert node.handled["latest"] == [7]
