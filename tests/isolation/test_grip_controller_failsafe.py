"""The grip controller on recorded-style input: it holds the grip when its inputs stop
or go stale, and never lowers it in fail-safe."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from slipstack.lib.defaults import F_MAX_N
from slipstack.messages import GripState, Header, Slip, decode
from slipstack.nodes.grip_controller import GripController, GripControllerParams
from slipstack.nodes.runtime.inprocess import InProcessExecutor

MS = 1_000_000


def _slip(k: int, f_t: float, status: str = "ok", *, f_n: float = 4.0, tau: float = 0.0,
          stamp_ns: int | None = None, state: str = "stick") -> Slip:
    """The verdict received at ``k`` ms on a force ``f_t`` (N, along x) with ``f_n`` (N) and
    ``tau`` (N·m), stamped at ``stamp_ns`` (default: ``k`` ms). Its gamma is the pure-force
    one, |f_t| / (mu f_n) with mu = 0.45, as the exact law reads it."""
    gamma = f_t / (0.45 * f_n)
    stamp = k * MS if stamp_ns is None else stamp_ns
    return Slip(state=state, margin=1 - gamma, method="exact", gamma=gamma, status=status, f_n=f_n,
                f_t=np.array([f_t, 0.0]), tau=tau, p_c=np.zeros(2), header=Header(stamp, k, stamp, {}))


def _run(events, until_ms: int, params: GripControllerParams | None = None):
    node = GripController(params or GripControllerParams(law="exact", timeout_ms=20.0, max_rate_n_per_s=1e6))
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


DEFAULTS = GripControllerParams(mu=0.45)  # law exact, sigma 0.5; the documented bounds, rates and times


def test_the_default_command_stays_within_f_nom_and_f_max():
    # gamma 10 asks for 10 * 4 / 0.5 = 80 N: from the measured 4 N up at 200 N/s to f_max
    # (lib/defaults.py F_MAX_N, 20 N: the launch files' value)
    cmds = _run([(k * MS, "slip", _slip(k, 18.0)) for k in range(1, 300)], until_ms=300, params=DEFAULTS)
    assert cmds[0].f_n_desired == 4.0
    assert max(c.f_n_desired for c in cmds) == F_MAX_N == 20.0 and cmds[-1].f_n_desired == F_MAX_N
    # no load on a light touch (1 N measured): the law asks for f_nom, 2 N, and gets it
    cmds = _run([(k * MS, "slip", _slip(k, 0.0, f_n=1.0)) for k in range(1, 100)], until_ms=100, params=DEFAULTS)
    assert cmds[0].f_n_desired == 2.0 and cmds[-1].f_n_desired == 2.0
    assert all(c.reason != "fail-safe" for c in cmds)


def test_the_default_timeout_accepts_a_verdict_20_ms_old_and_holds_on_an_older_one():
    events = [(k * MS, "slip", _slip(k, 0.9)) for k in range(1, 31)]
    events += [(31 * MS, "slip", _slip(31, 0.9, stamp_ns=11 * MS)),  # exactly 20 ms old: accepted
               (32 * MS, "slip", _slip(32, 0.9, stamp_ns=12 * MS - 1))]  # 1 ns older: held
    cmds = _run(events, until_ms=32, params=DEFAULTS)
    assert [c.reason for c in cmds[-3:]] == ["slip", "slip", "fail-safe"]


def test_by_default_a_blind_loaded_grip_rises_10_n_per_s_after_50_ms():
    # stale verdicts every ms (each 30 ms old) after a valid phase: fail-safe from the first,
    # held for the 50 ms grace, then 10 N/s = 0.01 N per 1 ms step
    events = [(k * MS, "slip", _slip(k, 0.9)) for k in range(31, 41)]
    events += [(k * MS, "slip", _slip(k, 0.9, stamp_ns=(k - 30) * MS)) for k in range(41, 130)]
    cmds = _run(events, until_ms=130, params=DEFAULTS)
    held = [c for c in cmds if c.reason == "fail-safe"]
    start = held[0].header.pub_ns
    assert start == 41 * MS
    hold = held[0].f_n_desired
    grace = [c for c in held if c.header.pub_ns - start < 50 * MS]
    rising = [c for c in held if c.header.pub_ns - start >= 50 * MS]
    assert len(grace) == 50 and all(c.f_n_desired == hold for c in grace)
    assert rising and rising[0].header.pub_ns - start == 50 * MS
    rises = np.diff([hold] + [c.f_n_desired for c in rising])
    assert np.allclose(rises, 0.01, rtol=1e-9)


def test_a_blind_controller_holds_without_raising_when_the_last_verdicts_saw_no_contact():
    # nothing in the finger (valid "no-contact" verdicts), then the verdicts stop: hold, say
    # fail-safe, but do not squeeze harder: there is no load that could be growing unseen
    events = [(k * MS, "slip", _slip(k, 0.0, f_n=0.01, state="no-contact")) for k in range(1, 41)]
    cmds = _run(events, until_ms=400, params=DEFAULTS)
    held = [c for c in cmds if c.reason == "fail-safe"]
    assert len(held) >= 10  # the watchdog, every 20 ms for 340 ms
    assert {c.f_n_desired for c in held} == {cmds[39].f_n_desired}


def test_law_13_adds_its_default_2_n_offset():
    # |f_t| / mu + |tau| / beta + k = 0.5 / 0.45 + 0.004 / 0.008 + 2 N = 3.611 N (paper (13))
    params = GripControllerParams(law="ft13", mu=0.45, beta_m=0.008)
    cmds = _run([(k * MS, "slip", _slip(k, 0.5, f_n=3.0, tau=-0.004)) for k in range(1, 50)], until_ms=50,
                params=params)
    assert cmds[-1].f_n_desired == pytest.approx(0.5 / 0.45 + 0.5 + 2.0, rel=1e-12)


def test_the_cone_margin_law_keeps_its_default_1_n_from_the_cone_and_holds_on_stale_input():
    # the paper's ref. [9]: (|f_t| + sqrt(1 + mu^2) * 1 N) / mu = (1.8 + 1.0966) / 0.45 = 6.437 N
    params = GripControllerParams(law="cone_margin", mu=0.45, max_rate_n_per_s=1e6)
    events = [(k * MS, "slip", _slip(k, 1.8)) for k in range(1, 30)]
    events += [(k * MS, "slip", _slip(k, 0.0, status="stale")) for k in range(30, 35)]
    cmds = _run(events, until_ms=35, params=params)
    live = [c for c in cmds if c.reason == "slip"]
    assert live[-1].f_n_desired == pytest.approx((1.8 + (1 + 0.45 ** 2) ** 0.5) / 0.45, rel=1e-12)
    assert live[-1].law == "cone_margin"
    held = [c for c in cmds if c.reason == "fail-safe"]
    assert held and all(c.f_n_desired == live[-1].f_n_desired for c in held)  # a stale "no load" does not release


def test_diagnostics_say_fail_safe_and_why_while_the_grip_is_held_and_ok_once_valid_again():
    events = [(k * MS, "slip", _slip(k, 0.9)) for k in range(1, 11)]
    events += [(k * MS, "slip", _slip(k, 0.9, status="tactile_stale")) for k in range(11, 16)]
    events += [(k * MS, "slip", _slip(k, 0.9)) for k in range(16, 21)]
    ex = InProcessExecutor([GripController(DEFAULTS)], diagnostics_period_s=0.001)
    ex.feed(events)
    ex.run(until_ns=20 * MS + MS // 2)
    reports = {d.header.stamp_ns: d for d in ex.published["diagnostics"]}
    assert reports[10 * MS].status == "ok"  # after the 10 ms verdict (frames run before the report)
    held = reports[15 * MS]
    assert held.status.startswith("fail-safe: ") and "status not ok" in held.status
    assert held.counters["grip.fail_safe_steps"] == 5
    recovered = reports[20 * MS]
    assert recovered.status == "ok" and recovered.counters["grip.fail_safe_steps"] == 5


def _finger(k: int, f_n: float, mode: str = "following") -> tuple[int, str, GripState]:
    """The finger's report at ``k`` ms: it holds to ``f_n`` N, in ``mode``."""
    return k * MS, "grip/state", GripState(f_n_command=f_n, mode=mode, header=Header(k * MS, k, k * MS, {}))


STALE = [(k * MS, "slip", _slip(k, 0.9, stamp_ns=(k - 30) * MS)) for k in range(31, 131)]  # measured 4 N, 30 ms old


def test_a_controller_restarted_into_stale_data_holds_what_the_finger_reports_then_rises_blind():
    # restarted while the F/T driver hangs, the finger held 6 N for the controller before: the
    # stale 4 N is no start; a load was held, so after the 50 ms grace the grip rises at 10 N/s
    cmds = _run([_finger(30, 6.0), *STALE], until_ms=131, params=DEFAULTS)
    assert all(c.reason == "fail-safe" for c in cmds)
    assert cmds[0].f_n_desired == 6.0
    assert cmds[-1].f_n_desired == pytest.approx(6.0 + 10.0 * 0.050, rel=1e-9)  # 50 rising 1 ms steps, 81-130 ms


def test_a_launch_into_stale_data_holds_the_fingers_own_grip_and_never_squeezes():
    cmds = _run([_finger(30, 3.0, mode="initial"), *STALE], until_ms=131, params=DEFAULTS)
    assert len(cmds) == 100 and all(c.reason == "fail-safe" and c.f_n_desired == 3.0 for c in cmds)


def test_without_the_fingers_report_no_command_or_f_hold_after_the_wait():
    assert _run(STALE, until_ms=131, params=DEFAULTS) == []  # nothing known: the finger keeps its grip
    longer = [(k * MS, "slip", _slip(k, 0.9, stamp_ns=(k - 30) * MS)) for k in range(31, 141)]
    cmds = _run(longer, until_ms=141, params=dataclasses.replace(DEFAULTS, f_hold_n=12.0))
    assert cmds[0].header.pub_ns == 131 * MS and cmds[0].f_n_desired == 12.0  # 100 ms after the first verdict


def test_an_injected_verdict_is_never_trusted_not_even_before_the_first_real_one():
    ex = InProcessExecutor([GripController(DEFAULTS)])
    host = ex.host("grip_controller")
    forged = _slip(1, 0.0, f_n=0.5)  # "ok, no load": the law would release to f_nom
    host.dispatch("slip", forged, sender="topic_pub-1")
    assert ex.published["grip/command"] == [] and host.counters["handler_errors"] == 0
    ex.feed([(k * MS, "slip", _slip(k, 1.8)) for k in range(2, 21)])  # exact law: 8 N
    ex.run(until_ns=20 * MS)
    held = ex.published["grip/command"][-1].f_n_desired
    host.dispatch("slip", _slip(20, 0.0, f_n=0.5), sender="topic_pub-1")
    last = ex.published["grip/command"][-1]
    assert (last.f_n_desired, last.reason) == (held, "fail-safe") and held > 7.0  # on its way to 8 N at 200 N/s
    assert decode(host.diagnostics()).status == "fail-safe: slip verdict injected by topic_pub-1: not trusted"
    assert host.counters["grip.injected_verdicts"] == 2
