"""Per-stage CPU accounting (benchmarks only): CPU lands in the stage that spent it."""

from __future__ import annotations

import time

import numpy as np

from slipstack.messages import Header, Wrench, decode, encode
from slipstack.nodes.runtime.host import NodeHost
from slipstack.nodes.runtime.node import Input, Node, Output
from slipstack.nodes.runtime.stage_cpu import STAGE_CPU_ENV, StageCpu, stage_cpu_from_env


def _burn(seconds: float) -> None:
    end = time.thread_time() + seconds
    while time.thread_time() < end:
        pass


class _Relay(Node):
    name = "relay"
    inputs = {"wrench": Input("ft/wrench", Wrench)}
    outputs = {"out": Output("ft/relayed", Wrench)}

    def on_wrench(self, msg: Wrench, ctx) -> None:
        _burn(0.02)
        ctx.publish("out", msg, stamp_ns=msg.header.stamp_ns)


def test_handler_encode_and_send_are_charged_to_their_own_stages():
    stage = StageCpu("relay")
    sent: list[bytes] = []

    def slow_send(topic: str, payload: bytes) -> None:
        _burn(0.01)
        sent.append(payload)

    host = NodeHost(_Relay(), clock=lambda: 5, send=slow_send, stage_cpu=stage)
    frame = Wrench(force=np.ones(3), torque=np.zeros(3))
    host.dispatch("wrench", host.receive("wrench", encode(frame, Header(1, 0, 2, {}))))
    counters = decode(host.diagnostics()).counters
    assert counters["cpu.handler_us"] >= 15_000  # the handler's 20 ms, not the send's 10 ms inside it
    assert 8_000 <= counters["cpu.send_us"] < 15_000
    assert counters["cpu.handler_us"] < 30_000
    assert "cpu.decode_us" in counters and "cpu.encode_us" in counters
    assert decode(sent[-1]).header.stamp_ns == 1


def test_off_unless_the_environment_asks(monkeypatch):
    monkeypatch.delenv(STAGE_CPU_ENV, raising=False)
    assert stage_cpu_from_env("x") is None
    monkeypatch.setenv(STAGE_CPU_ENV, "1")
    assert isinstance(stage_cpu_from_env("x"), StageCpu)
    host = NodeHost(_Relay(), clock=lambda: 0, send=lambda t, p: None)
    assert not any(k.startswith("cpu.") for k in decode(host.diagnostics()).counters)
