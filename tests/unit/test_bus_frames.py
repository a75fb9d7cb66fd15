"""The process executor reads bus frames part by part: a frame of the wrong number of
parts is rejected and counted, and the frames around it are handled in order, on real
ZeroMQ sockets (ipc)."""

from __future__ import annotations

import time

import numpy as np
import zmq

from slipstack.messages import Header, Wrench, encode
from slipstack.nodes.runtime.node import Input, Node
from slipstack.nodes.runtime.process import RunSpec, _Member
from slipstack.nodes.runtime.transport import make_pub


class _Queued(Node):
    """Remembers the device_seq of every wrench handled, in order."""

    name = "queued_node"
    inputs = {"x": Input("grip/wrench", Wrench, policy="queue", depth=100)}

    def __init__(self) -> None:
        super().__init__()
        self.handled: list[int] = []

    def on_x(self, msg: Wrench, ctx) -> None:
        self.handled.append(msg.device_seq)


def _wrench(k: int) -> bytes:
    return encode(Wrench(force=np.zeros(3), torque=np.zeros(3), device_seq=k), Header(1, k, 1, {}))


def test_frames_of_one_or_three_parts_are_rejected_and_the_others_handled_in_order(tmp_path):
    ctx = zmq.Context.instance()
    endpoint = f"ipc://{tmp_path}/src.pub"
    pub = make_pub(ctx, endpoint)
    node = _Queued()
    member = _Member(node, RunSpec(name="q", subs={"grip/wrench": [endpoint]}), ctx)
    (sock, _), = member.sub_topic.items()
    try:
        deadline = time.monotonic() + 10
        while not pub.poll(10):
            sock.getsockopt(zmq.EVENTS)  # a socket attaches its peers when used
            assert time.monotonic() < deadline, "the member never subscribed"
        pub.recv()
        pub.send_multipart([b"grip/wrench", _wrench(0)])
        pub.send_multipart([b"grip/wrench"])
        pub.send_multipart([b"grip/wrench", _wrench(1), b"extra"])
        pub.send_multipart([b"grip/wrench", _wrench(2)])
        while not sock.poll(10):
            assert time.monotonic() < deadline, "no frame arrived"
        time.sleep(0.2)  # the rest follow the first through ZeroMQ's I/O thread
        member.drain("x", sock)
        assert node.handled == [0, 2]
        counters = member.host.counters
        assert counters["in.grip/wrench.rejected"] == 2
        assert counters["in.grip/wrench.received"] == 2
        assert "got 3 parts" in member.host.last_error
    finally:
        for s in member.sockets():
            s.close(linger=0)
        pub.close(linger=0)
