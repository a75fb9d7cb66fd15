"""The ``batch`` input policy in each executor: what one wake-up finds queued for the
input reaches its handler as one tuple, oldest first; a rejected frame is counted and
left out; at most ``depth`` messages, the older overflow counted as dropped."""

from __future__ import annotations

import time

import numpy as np
import pytest
import zmq

from slipstack.lib.errors import ConfigError
from slipstack.messages import Header, Wrench, encode
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from slipstack.nodes.runtime.node import Input, Node, Output
from slipstack.nodes.runtime.process import ProcessExecutor, RunSpec, _Member
from slipstack.nodes.runtime.transport import make_pub

DEPTH = 8


class _Gatherer(Node):
    """Remembers each call of its ``batch`` input as the tuple of device_seq it was given."""

    name = "gatherer"
    inputs = {"wrench": Input("ft/wrench", Wrench, policy="batch", depth=DEPTH)}

    def __init__(self) -> None:
        super().__init__()
        self.calls: list[tuple[int, ...]] = []

    def on_wrench(self, msgs: tuple[Wrench, ...], ctx) -> None:
        assert isinstance(msgs, tuple)
        self.calls.append(tuple(m.device_seq for m in msgs))


class _Device(Node):
    """One device read per call: publishes the wrenches of ``self.read`` (device_seq; a
    negative one is published with a NaN force, which every receiver must refuse)."""

    name = "device"
    outputs = {"out": Output("ft/wrench", Wrench)}
    read: tuple[int, ...] = ()

    def on_readable(self, source, ctx) -> None:
        for k in self.read:
            ctx.publish("out", _wrench_msg(k), stamp_ns=ctx.now_ns())


def _wrench_msg(k: int) -> Wrench:
    force = np.array([np.nan if k < 0 else 0.0, 0.0, 0.0])
    return Wrench(force=force, torque=np.zeros(3), device_seq=max(k, 0) if k >= 0 else 0)


def _payload(k: int, seq: int) -> bytes:
    """An encoded wrench; ``k < 0``: one with a NaN force (rejected on decode)."""
    return encode(_wrench_msg(k), Header(seq + 1, seq, seq + 1, {}))


def test_the_policy_is_checked():
    with pytest.raises(ConfigError, match="batch"):
        Input("ft/wrench", Wrench, policy="every")
    with pytest.raises(ConfigError, match="depth"):
        Input("ft/wrench", Wrench, policy="batch", depth=0)


# -- process executor, from the bus -----------------------------------------------------
def _subscribed_member(ctx: zmq.Context, tmp_path, node: Node | None = None):
    endpoint = f"ipc://{tmp_path}/src.pub"
    pub = make_pub(ctx, endpoint)
    node = node or _Gatherer()
    member = _Member(node, RunSpec(name="g", subs={"ft/wrench": [endpoint]}), ctx)
    sock = next(iter(member.sub_topic))
    deadline = time.monotonic() + 10
    while not pub.poll(10):
        sock.getsockopt(zmq.EVENTS)  # a socket attaches its peers when used
        assert time.monotonic() < deadline, "the member never subscribed"
    pub.recv()
    return pub, node, member, sock


def _send_and_drain(pub, member, sock, payloads: list[bytes]) -> None:
    c = member.host.counters
    total = c["in.ft/wrench.received"] + len(payloads)
    for p in payloads:
        pub.send_multipart([b"ft/wrench", p])
    deadline = time.monotonic() + 20
    while True:  # every frame reaches the socket eventually; drain until all were taken
        if sock.getsockopt(zmq.EVENTS) & zmq.POLLIN:
            member.drain("wrench", sock)
        if c["in.ft/wrench.received"] >= total:
            return
        assert time.monotonic() < deadline, f"only {c['in.ft/wrench.received']} of {len(payloads)} arrived"
        time.sleep(0.01)


def test_process_executor_hands_a_bus_backlog_over_as_one_tuple_oldest_first(tmp_path):
    ctx = zmq.Context.instance()
    pub, node, member, sock = _subscribed_member(ctx, tmp_path)
    try:
        # a rejected frame (NaN) in the middle: counted, left out, the others handled in order
        _send_and_drain(pub, member, sock, [_payload(k, k) for k in (1, 2, -1, 4, 5)])
        handled = [k for call in node.calls for k in call]
        assert handled == [1, 2, 4, 5]
        assert all(list(call) == sorted(call) for call in node.calls)
        c = member.host.counters
        assert c["in.ft/wrench.rejected"] == 1 and c["in.ft/wrench.dropped"] == 0
    finally:
        for s in member.sockets():
            s.close(linger=0)
        pub.close(linger=0)


def test_process_executor_backlog_beyond_depth_keeps_the_newest_in_one_wake_up(tmp_path):
    """One drain of a backlog deeper than ``depth``: one call with the newest ``depth``
    frames, the older ones dropped undecoded and no sequence gap."""
    ctx = zmq.Context.instance()
    pub, node, member, sock = _subscribed_member(ctx, tmp_path)
    try:
        sent = 3 * DEPTH
        for k in range(sent):
            pub.send_multipart([b"ft/wrench", _payload(k, k)])
        deadline = time.monotonic() + 20
        while not sock.poll(100):
            assert time.monotonic() < deadline, "nothing arrived"
        time.sleep(0.5)  # let ZeroMQ move the rest in (the outcome holds for however many arrived)
        member.drain("wrench", sock)
        c = member.host.counters
        got = c["in.ft/wrench.received"]
        assert node.calls == [tuple(range(max(got - DEPTH, 0), got))]
        assert c["in.ft/wrench.dropped"] == max(got - DEPTH, 0)
        assert c["in.ft/wrench.lost"] == 0  # overflow dropped on purpose is no sequence gap
    finally:
        for s in member.sockets():
            s.close(linger=0)
        pub.close(linger=0)


# -- process executor, in-container hand-over --------------------------------------------
def _container(tmp_path, sink: Node | None = None):
    device, sink = _Device(), sink or _Gatherer()
    executor = ProcessExecutor([
        (device, RunSpec(name="device", pub=f"ipc://{tmp_path}/device.pub")),
        (sink, RunSpec(name="gatherer", local={"ft/wrench": ["device"]})),
    ])
    return executor, device, sink


def _read(executor, device, read: tuple[int, ...]) -> None:
    device.read = read
    member = executor.members[0]
    member.host.call("on_readable", device.on_readable, None, member.host)
    executor._run_handovers()


def test_container_hands_one_device_read_over_as_one_tuple(tmp_path):
    executor, device, sink = _container(tmp_path)
    try:
        _read(executor, device, (1, 2, -1, 4))
        _read(executor, device, (5,))
        assert sink.calls == [(1, 2, 4), (5,)]
        host = executor.members[1].host
        assert host.counters["in.ft/wrench.received"] == 5 and host.counters["in.ft/wrench.rejected"] == 1
        assert "NaN" in host.last_error
    finally:
        for sock in executor._sockets():
            sock.close(linger=0)


def test_container_batch_beyond_depth_keeps_the_newest(tmp_path):
    executor, device, sink = _container(tmp_path)
    try:
        _read(executor, device, tuple(range(DEPTH + 3)))
        assert sink.calls == [tuple(range(3, DEPTH + 3))]
        c = executor.members[1].host.counters
        assert c["in.ft/wrench.dropped"] == 3 and c["in.ft/wrench.received"] == DEPTH + 3
    finally:
        for sock in executor._sockets():
            sock.close(linger=0)


# -- in-process (lock-step) executor -----------------------------------------------------
def test_inprocess_executor_gathers_one_instants_messages_for_a_batch_input():
    sink = _Gatherer()
    ex = InProcessExecutor([sink])
    ex.feed([(1_000, "ft/wrench", _payload(1, 0)), (1_000, "ft/wrench", _payload(-1, 1)),
             (1_000, "ft/wrench", _payload(3, 2)), (2_000, "ft/wrench", _payload(4, 3))])
    ex.run()
    assert sink.calls == [(1, 3), (4,)]
    c = ex.host("gatherer").counters
    assert c["in.ft/wrench.rejected"] == 1 and c["in.ft/wrench.received"] == 4


def test_inprocess_executor_hands_a_published_read_over_as_one_tuple_bounded_by_depth():
    device, sink = _Device(), _Gatherer()
    ex = InProcessExecutor([device, sink], keep_published=False)
    ex.run(0)
    device.read = tuple(range(DEPTH + 2)) + (-1,)
    ex.hosts[0].call("on_readable", device.on_readable, None, ex.hosts[0])
    ex.run()
    assert sink.calls == [tuple(range(3, DEPTH + 2))]
    c = ex.host("gatherer").counters
    assert c["in.ft/wrench.dropped"] == 3 and c["in.ft/wrench.rejected"] == 1
    assert c["in.ft/wrench.received"] == DEPTH + 3


# -- a handler that raises on a batch, in each executor ----------------------------------
class _Fragile(_Gatherer):
    """Raises on a batch that holds device_seq 2 (after remembering it), handles the rest."""

    def on_wrench(self, msgs: tuple[Wrench, ...], ctx) -> None:
        super().on_wrench(msgs, ctx)
        if any(m.device_seq == 2 for m in msgs):
            raise RuntimeError("a bug in the handler")


def test_a_handler_that_raises_on_a_batch_is_counted_and_the_next_batch_is_handled(tmp_path):
    ex = InProcessExecutor([_Fragile()])
    ex.feed([(1_000, "ft/wrench", _payload(k, k)) for k in (1, 2, 3)] + [(2_000, "ft/wrench", _payload(4, 3))])
    ex.run()
    assert ex.host("gatherer").node.calls == [(1, 2, 3), (4,)]
    assert ex.host("gatherer").counters["handler_errors"] == 1

    executor, device, sink = _container(tmp_path, _Fragile())
    try:
        _read(executor, device, (1, 2, 3))
        _read(executor, device, (4,))
        assert sink.calls == [(1, 2, 3), (4,)]
        assert executor.members[1].host.counters["handler_errors"] == 1
    finally:
        for sock in executor._sockets():
            sock.close(linger=0)

    pub, node, member, sock = _subscribed_member(zmq.Context.instance(), tmp_path, _Fragile())
    try:
        _send_and_drain(pub, member, sock, [_payload(k, k) for k in (1, 2, 3)])
        _send_and_drain(pub, member, sock, [_payload(4, 3)])
        assert [k for call in node.calls for k in call] == [1, 2, 3, 4]  # however the wake-ups cut them
        assert member.host.counters["handler_errors"] == 1
    finally:
        for s in member.sockets():
            s.close(linger=0)
        pub.close(linger=0)
