"""A handler that raises on every call is logged once and counted every time."""

from __future__ import annotations

from slipstack.nodes.runtime.host import NodeHost
from slipstack.nodes.runtime.node import Node


class _Broken(Node):
    name = "broken"
    timers = {"tick": 0.001}

    def on_timer_tick(self, ctx) -> None:
        raise RuntimeError("no publish endpoint")


def test_a_repeating_handler_error_is_logged_once_and_counted_every_time():
    lines: list[str] = []
    host = NodeHost(_Broken(), clock=lambda: 0, send=lambda topic, payload: None, log=lines.append)
    for _ in range(1000):
        host.fire_timer("tick")
    assert host.counters["handler_errors"] == 1000
    assert len(lines) == 1 and "Traceback" in lines[0] and "no publish endpoint" in lines[0]
    assert host.status == "error" and "no publish endpoint" in host.last_error
