"""The grip controller on recorded-style input: it holds the grip when its inputs stop
or go stale, and never lowers it in fail-safe."""

from __future__ import annotations

import numpy as np

from slipstack.messages import Header, Slip
from slipstack.nodes.grip_controller import GripController, GripControllerParams
from slipstack.nodes.runtime.inprocess import InProcessExecutor

MS = 1_000_000


def _slip(k: int, f_t: float, status: str = "ok") -> Slip:
    # exact law: gamma = |f_t| / (mu f_n) for a pure force; f_n = 4 N, mu = 0.45
    gamma = f_t / (0.45 * 4.0)
    return Slip(state="stick", margin=1 - gamma, method="exact", gamma=gamma, status=status, f_n=4.0,
                f_t=np.array([f_t, 0.0]), tau=0.0, p_c=np.zeros(2), header=Header(k * MS, k, k * MS, {}))


def _run(events, until_ms: int):
    node = GripController(GripControllerParams(law="exact", timeout_ms=20.0, max_rate_n_per_s=1e6))
    ex = InProcessExecutor([node])
    ex.feed(events)
    ex.run(until_ns=until_ms * MS)
    return ex.published["grip/command"]


def test_inputs_that_stop_hold_the_last_grip_and_say_so():
    # f_t = 1.8 N -> gamma = 1 -> exact law: gamma f_n / sigma = 1 * 4 / 0.5 = 8 N
    cmds = _run([(k * MS, "slip", _slip(k, 1.8)) for k in range(1, 11)], until_ms=100)
    live = [c for c in cmds if c.header.stamp_ns <= 10 * MS and c.reason != "fail-safe"]
    assert live and abs(live[-1].f_n_desired - 8.0) < 1e-9
    held = [c for c in cmds if c.reason == "fail-safe"]
    assert len(held) >= 3  # the watchdog keeps saying it, every timeout
    assert held[0].f_n_desired == live[-1].f_n_desired  # held first ...
    assert all(b.f_n_desired >= a.f_n_desired >= live[-1].f_n_desired for a, b in zip(held, held[1:]))
    assert held[-1].f_n_desired > live[-1].f_n_desired  # ... then raised: blind with a load past the grace


def test_a_stale_input_never_lowers_the_grip():
    # the governor's first step only sets its clock (dt = 0 holds f_nom); the second reaches 8 N
    events = [(k * MS, "slip", _slip(k, 1.8)) for k in (1, 2)]
    events += [(k * MS, "slip", _slip(k, 0.0, status="stale")) for k in (3, 4)]
    cmds = _run(events, until_ms=5)
    assert [c.reason for c in cmds[:4]] == ["slip", "slip", "fail-safe", "fail-safe"]
    assert [c.f_n_desired for c in cmds[1:4]] == [8.0, 8.0, 8.0]  # a stale "no load" does not release
