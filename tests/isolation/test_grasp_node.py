"""The grasp node on crafted verdicts of two fingers: the least squeeze for the measured split,
one verdict, and the fail-safe contract (docs/safety.md): either finger missing, stale or not
``ok`` holds the squeeze, blind and loaded it rises; it never lowers on data it cannot trust."""

from __future__ import annotations

import numpy as np
import pytest

from slipstack.messages import Contact, GraspGoal, Header, Slip
from slipstack.nodes.grasp import Grasp, GraspParams
from slipstack.nodes.runtime.inprocess import InProcessExecutor

MS = 1_000_000
MU = 0.45


def _slip(k: int, f_y: float, *, f_n: float = 10.0, status: str = "ok", stamp_ns: int | None = None,
          state: str = "stick") -> Slip:
    """Finger verdict received at ``k`` ms: a load ``f_y`` (N) along y at ``f_n``; γ = |f_y|/(μ f_n)."""
    stamp = k * MS if stamp_ns is None else stamp_ns
    gamma = abs(f_y) / (MU * f_n)
    return Slip(state=state, margin=1 - gamma, method="exact", gamma=gamma, status=status, f_n=f_n,
                f_t=np.array([0.0, f_y]), tau=0.0, p_c=np.zeros(2), header=Header(stamp, k, stamp, {}))


def _run(events, until_ms: int, **params):
    node = Grasp(GraspParams(mu=MU, mu_d=0.36, sigma=0.8, f_nom_n=5.0, f_max_n=60.0, max_rate_n_per_s=1e6,
                             **params))
    ex = InProcessExecutor([node])
    ex.feed(events)
    ex.run(until_ns=until_ms * MS)
    return ex.published["grip/command"], ex.published["slip"]


def _both(k: int, f0: float, f1: float, **kw):
    return [(k * MS, "finger0/slip", _slip(k, f0, **kw)), (k * MS, "finger1/slip", _slip(k, f1, **kw))]


def test_the_squeeze_holds_the_finger_that_carries_more_not_half_the_total():
    # finger 0 carries 3 N, finger 1 1 N, at 10 N each: least squeeze 3/0.45 = 6.67 N, over σ = 0.8
    events = [e for k in range(1, 40) for e in _both(k, -3.0, -1.0)]
    cmds, verdicts = _run(events, until_ms=40)
    assert cmds[-1].reason == "slip" and cmds[-1].f_n_desired == pytest.approx(3.0 / MU / 0.8)
    assert cmds[-1].f_n_desired > 2.0 / MU / 0.8  # an even split (2 N each) would squeeze less
    v = verdicts[-1]
    assert v.method == "grasp" and v.gamma == pytest.approx(3.0 / 4.5) and v.f_t[1] == pytest.approx(-4.0)
    assert set(v.verdicts) == {"finger0", "finger1"} and v.state == "stick"


def test_either_finger_missing_holds_and_then_raises_the_squeeze():
    events = [e for k in range(1, 21) for e in _both(k, -3.0, -1.0)]
    events += [(k * MS, "finger0/slip", _slip(k, -3.0)) for k in range(21, 200)]  # finger 1 goes silent
    cmds, _ = _run(events, until_ms=200)
    # the start contract (docs/safety.md): finger 0's first verdict alone is not trusted, so no command
    # until finger 1's comes; then the least squeeze
    assert cmds[0].reason != "fail-safe" and cmds[0].header.sources.get("slip1") == 1 * MS
    live = [c for c in cmds if c.header.stamp_ns <= 20 * MS and c.reason != "fail-safe"]
    held = [c for c in cmds if c.reason == "fail-safe" and c.header.stamp_ns > 20 * MS]
    assert held and held[0].f_n_desired == pytest.approx(live[-1].f_n_desired)
    assert all(b.f_n_desired >= a.f_n_desired for a, b in zip(held, held[1:]))  # never lower
    assert held[-1].f_n_desired > live[-1].f_n_desired  # blind with a load past the grace: raised


@pytest.mark.parametrize("status", ["stale", "implausible", "disconnected"])
def test_a_finger_not_ok_never_lowers_the_squeeze(status):
    events = [e for k in range(1, 11) for e in _both(k, -3.0, -1.0)]
    events += [(k * MS, "finger0/slip", _slip(k, 0.0)) for k in range(11, 30)]  # "no load" from finger 0 ...
    events += [(k * MS, "finger1/slip", _slip(k, 0.0, status=status)) for k in range(11, 30)]  # ... finger 1 untrusted
    cmds, verdicts = _run(events, until_ms=30)
    held = [(a, b) for a, b in zip(cmds, cmds[1:]) if b.reason == "fail-safe"]
    assert len(held) >= 18 and all(b.f_n_desired >= a.f_n_desired for a, b in held)
    assert cmds[-1].f_n_desired >= 3.0 / MU / 0.8 - 0.5  # at most the hold's fall over the one valid step
    assert verdicts[-1].status == status


def test_a_stale_verdict_of_one_finger_holds():
    events = [e for k in range(1, 31) for e in _both(k, -3.0, -1.0)]
    events += [(k * MS, "finger1/slip", _slip(k, 0.0, stamp_ns=(k - 25) * MS)) for k in range(31, 60)]  # 25 ms old
    events += [(k * MS, "finger0/slip", _slip(k, 0.0)) for k in range(31, 60)]  # and finger 0 says "no load"
    cmds, _ = _run(events, until_ms=60)
    after = [c for c in cmds if c.header.pub_ns >= 31 * MS]
    assert after and all(c.reason == "fail-safe" and c.f_n_desired >= 3.0 / MU / 0.8 - 1e-9 for c in after)


def test_every_new_verdict_gets_a_command_and_one_instant_gets_one():
    # lock-step: both fingers' verdicts of an instant share a stamp → one command per instant, no error
    node = Grasp(GraspParams(mu=MU, mu_d=0.36, sigma=0.8))
    ex = InProcessExecutor([node])
    ex.feed([e for k in range(1, 11) for e in _both(k, -3.0, -1.0)])
    ex.run(until_ns=11 * MS)
    assert len(ex.published["grip/command"]) == 10 and len(ex.published["slip"]) == 19  # the first pair: one verdict
    assert not ex.logs  # no handler failed
    # real time: each sensor stamps its own samples; finger 1's verdict on a sample older than finger 0's
    # newest is still a new sample: it gets its command at once, not with finger 0's next one
    events = []
    for k in range(1, 11):
        events += [(k * MS, "finger0/slip", _slip(k, -3.0, stamp_ns=k * MS + 300_000)),
                   (k * MS + 100_000, "finger1/slip", _slip(k, -1.0, stamp_ns=k * MS + 200_000))]
    node = Grasp(GraspParams(mu=MU, mu_d=0.36, sigma=0.8))
    ex = InProcessExecutor([node])
    ex.feed(events)
    ex.run(until_ns=11 * MS)
    cmds = ex.published["grip/command"]
    assert not ex.logs
    assert len(cmds) == 19  # finger 0's first verdict alone starts nothing (the start contract)
    first = {}
    for c in cmds:
        first.setdefault(c.header.sources.get("slip1"), c.header.pub_ns)
    assert [first[k * MS + 200_000] for k in range(1, 11)] == [k * MS + 100_000 for k in range(1, 11)]


@pytest.mark.parametrize("pads", [
    ((4, 4, 0.0), (4, 4, 1.25e-3)),        # a pitch of 0 (the decoder admits it for F/T-only contacts)
    ((16, 16, 1.25e-3), (4, 4, 1.25e-3)),  # unlike pads
    ((4, 4, 1.25e-3), (4, 4, 2.5e-3)),     # unlike pitches: finger 1's taxels taken at finger 0's positions
])
def test_pressure_frames_of_no_common_pad_geometry_hold_and_refuse_a_pivot_without_error(pads):
    # Both fingers' contacts with pressure frames each ms, then a pivot goal. The pads' joint
    # view of the object needs one geometry: else no view (no error), a goal refused saying why.
    # (The first two raised in on_contact on every frame pair; the third judged silently wrong.)
    def contact(k: int, rows: int, cols: int, pitch: float) -> Contact:
        phi = np.zeros(rows * cols)
        phi[: rows * cols // 4] = 1.0
        return Contact(rows=rows, cols=cols, pitch_m=pitch, phi=phi, f_n=10.0, f_t=np.array([0.0, -3.0]),
                       mask=phi > 0, header=Header(k * MS, k, k * MS, {"tactile": k * MS}))

    events = []
    for k in range(1, 30):
        events += [(k * MS, "finger0/contact", contact(k, *pads[0])), (k * MS, "finger1/contact", contact(k, *pads[1])),
                   *_both(k, -3.0, -1.0)]
        if k == 15:
            events.append((k * MS, "grasp/goal", GraspGoal(mode="pivot", angle_rad=0.5, rate_rad_s=0.5,
                                                           header=Header(k * MS, 1, k * MS, {}))))
    node = Grasp(GraspParams(mu=MU, mu_d=0.36, sigma=0.8))
    ex = InProcessExecutor([node])
    ex.feed(events)
    ex.run(until_ns=30 * MS)
    host = ex.hosts[0]
    assert host.counters.get("handler_errors", 0) == 0, host.last_error
    assert len(ex.published["grip/command"]) == 29
    assert "pivot goal refused" in host.last_error and "one pad geometry" in host.last_error, host.last_error
