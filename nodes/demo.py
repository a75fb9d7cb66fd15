"""The demo graph: a synthetic 1 kHz wrench source, a relay and a sink.

It exercises the whole runtime (timers, latest/queue inputs, diagnostics) with no
device and no physics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from slipstack.messages import Wrench
from slipstack.nodes.runtime.node import Context, Input, Node, Output

__all__ = ["WrenchSource", "Relay", "Sink"]


@dataclass(frozen=True)
class SourceParams:
    rate_hz: float = field(default=1000.0, metadata={"help": "publish rate (Hz)"})
    amplitude_n: float = field(default=2.0, metadata={"help": "tangential force amplitude (N)"})
    f_n: float = field(default=10.0, metadata={"help": "normal force (N)"})


class WrenchSource(Node):
    """Publishes a synthetic wrench: f_z = f_n, f_x a 1 Hz sine, on ``ft/wrench``."""

    name = "wrench_source"
    outputs = {"wrench": Output("ft/wrench", Wrench)}
    Params = SourceParams
    precise_timers = True

    def __init__(self, params: SourceParams | None = None) -> None:
        super().__init__(params)
        self.timers = {"tick": 1.0 / self.params.rate_hz}
        self._n = 0

    def on_timer_tick(self, ctx: Context) -> None:
        t = ctx.now_ns()
        fx = self.params.amplitude_n * math.sin(2 * math.pi * t * 1e-9)
        msg = Wrench(force=np.array([fx, 0.0, self.params.f_n]), torque=np.zeros(3), device_seq=self._n)
        self._n += 1
        ctx.publish("wrench", msg, stamp_ns=t)


class Relay(Node):
    """Republishes every wrench unchanged (keeps the sample stamp)."""

    name = "relay"
    inputs = {"wrench": Input("ft/wrench", Wrench, policy="queue")}
    outputs = {"out": Output("ft/relayed", Wrench)}

    def on_wrench(self, msg: Wrench, ctx: Context) -> None:
        ctx.publish("out", msg, stamp_ns=msg.header.stamp_ns, sources={"wrench": msg.header.stamp_ns})


class Sink(Node):
    """Consumes relayed wrenches and counts them and their latency (counters on diagnostics)."""

    name = "sink"
    inputs = {"wrench": Input("ft/relayed", Wrench, policy="queue")}

    def on_wrench(self, msg: Wrench, ctx: Context) -> None:
        ctx.count("sink.received")
        ctx.count("sink.latency_ns_sum", ctx.now_ns() - msg.header.stamp_ns)
