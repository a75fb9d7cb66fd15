"""A publication nobody outside the process subscribes to is not encoded nor sent, but
still counted, numbered and handed over in-process; a subscriber that joins gets the
next one at once, and one that leaves stops the sending again (real ZeroMQ sockets)."""

from __future__ import annotations

import time

import numpy as np
import zmq

from slipstack.messages import Wrench, decode
from slipstack.nodes.runtime.node import Node, Output
from slipstack.nodes.runtime.process import RunSpec, _Member


class _Source(Node):
    name = "source"
    outputs = {"out": Output("ft/wrench", Wrench)}


def _until(cond, what: str, timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not cond():
        assert time.monotonic() < deadline, what
        time.sleep(0.005)


def test_sending_follows_the_subscribers_present(tmp_path):
    ctx = zmq.Context.instance()
    member = _Member(_Source(), RunSpec(name="source", pub=f"ipc://{tmp_path}/source.pub"), ctx)
    handed_over: list[int] = []
    member.host.on_publish = lambda topic, msg, header: handed_over.append(header.seq)
    sent: list[bytes] = []
    real_send = member.host._send
    member.host._send = lambda topic, payload: (sent.append(payload), real_send(topic, payload))
    wrench = Wrench(force=np.ones(3), torque=np.zeros(3))
    subs = [ctx.socket(zmq.SUB) for _ in range(2)]
    try:
        member.host.publish("out", wrench, stamp_ns=1)  # nobody listens
        assert sent == [] and handed_over == [0]

        for sub in subs:
            sub.setsockopt(zmq.LINGER, 0)
            sub.setsockopt(zmq.SUBSCRIBE, b"ft/")
            sub.connect(f"ipc://{tmp_path}/source.pub")
        _until(lambda: member.pub.poll(10) and (member.read_subscriptions() or member.subscribers_of("ft/wrench") == 2),
               "the subscriptions never arrived")
        assert member.listened("ft/wrench")
        member.host.publish("out", wrench, stamp_ns=2)
        for sub in subs:
            assert sub.poll(10_000), "a subscriber got nothing"
            topic, payload = sub.recv_multipart()
            assert topic == b"ft/wrench" and decode(payload).header.seq == 1

        for sub in subs:  # both leave: a plain verbose XPUB reports only the last one's departure
            sub.close(linger=0)
        _until(lambda: member.pub.poll(10) and (member.read_subscriptions() or not member.listened("ft/wrench")),
               "the departures were never seen", timeout_s=5.0)
        member.host.publish("out", wrench, stamp_ns=3)
        assert len(sent) == 1 and handed_over == [0, 1, 2]
        assert member.host.counters["out.ft/wrench.published"] == 3
    finally:
        for sub in subs:
            sub.close(linger=0)
        for sock in member.sockets():
            sock.close(linger=0)
