"""In a container, a ``latest`` input handed several messages at once (a driver member
publishing one device read's batch) handles the newest only and counts the rest as
skipped, as its bus socket would; a ``queue`` input still handles every one."""

from __future__ import annotations

import numpy as np

from slipstack.messages import Wrench
from slipstack.nodes.runtime.node import Input, Node, Output
from slipstack.nodes.runtime.process import ProcessExecutor, RunSpec


class _Batch(Node):
    name = "batch"
    outputs = {"out": Output("ft/wrench", Wrench)}

    def on_readable(self, source, ctx) -> None:  # one device read: five samples
        for k in range(5):
            ctx.publish("out", Wrench(force=np.zeros(3), torque=np.zeros(3), device_seq=k), stamp_ns=k + 1)


class _Sink(Node):
    name = "sink"
    inputs = {"latest": Input("ft/wrench", Wrench), "every": Input("ft/wrench", Wrench, policy="queue")}

    def __init__(self) -> None:
        super().__init__()
        self.seen: dict[str, list[int]] = {"latest": [], "every": []}

    def on_latest(self, msg: Wrench, ctx) -> None:
        self.seen["latest"].append(msg.device_seq)

    def on_every(self, msg: Wrench, ctx) -> None:
        self.seen["every"].append(msg.device_seq)


def test_a_batch_handed_over_reaches_a_latest_input_newest_only(tmp_path):
    sink = _Sink()
    executor = ProcessExecutor([
        (_Batch(), RunSpec(name="batch", pub=f"ipc://{tmp_path}/batch.pub")),
        (sink, RunSpec(name="sink", local={"ft/wrench": ["batch"]})),
    ])
    try:
        batch = executor.members[0]
        for _ in range(2):
            batch.host.call("on_readable", batch.node.on_readable, None, batch.host)
            executor._run_handovers()
        assert sink.seen["latest"] == [4, 4]
        assert sink.seen["every"] == [0, 1, 2, 3, 4] * 2
        c = executor.members[1].host.counters
        assert c["in.ft/wrench.dropped"] == 8 and c["in.ft/wrench.received"] == 20
    finally:
        for sock in executor._sockets():
            sock.close(linger=0)


class _NanBatch(_Batch):
    """Publishes a wrench with a NaN force between two good ones: a member's bug."""

    def on_readable(self, source, ctx) -> None:
        for k, fx in enumerate((0.0, float("nan"), 0.0)):
            ctx.publish("out", Wrench(force=np.array([fx, 0.0, 0.0]), torque=np.zeros(3), device_seq=k), stamp_ns=k + 1)


def test_a_message_that_fails_the_decoders_checks_is_rejected_by_a_member_as_on_the_bus(tmp_path):
    """The in-process hand-over checks what it hands over, as the lock-step executor does:
    a container's member never handles what a separate process would refuse."""
    sink = _Sink()
    executor = ProcessExecutor([
        (_NanBatch(), RunSpec(name="batch", pub=f"ipc://{tmp_path}/batch.pub")),
        (sink, RunSpec(name="sink", local={"ft/wrench": ["batch"]})),
    ])
    try:
        batch = executor.members[0]
        batch.host.call("on_readable", batch.node.on_readable, None, batch.host)
        executor._run_handovers()
        assert sink.seen["every"] == [0, 2]
        host = executor.members[1].host
        assert host.counters["in.ft/wrench.rejected"] == 1 and "NaN" in host.last_error
    finally:
        for sock in executor._sockets():
            sock.close(linger=0)
