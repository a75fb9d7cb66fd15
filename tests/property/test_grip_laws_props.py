"""Properties of the grip laws and the governor (docs/math.md §5)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from slipstack.lib.grip_laws import (
    ConeMarginLaw,
    ExactLaw,
    FingerReport,
    Ft13Law,
    Ft13SigmaLaw,
    GripGovernor,
    GripInput,
    GripLaw,
    GripReason,
    LinearLaw,
    Tactile14Law,
    tactile14_increment,
)
from slipstack.lib.pad import PadGeometry

F_NOM, F_MAX = 2.0, 40.0
LAWS: list[GripLaw] = [
    LinearLaw(f_nom_n=F_NOM, f_max_n=F_MAX),
    Ft13Law(beta_m=0.008, f_nom_n=F_NOM, f_max_n=F_MAX),
    Ft13SigmaLaw(beta_m=0.008, f_nom_n=F_NOM, f_max_n=F_MAX),
    Tactile14Law(decay_n_per_s=5.0, f_nom_n=F_NOM, f_max_n=F_MAX),
    Tactile14Law(increment="per_taxel", f_nom_n=F_NOM, f_max_n=F_MAX),
    ExactLaw(f_nom_n=F_NOM, f_max_n=F_MAX),
    ConeMarginLaw(f_nom_n=F_NOM, f_max_n=F_MAX),
]

anything = st.floats(allow_nan=True, allow_infinity=True)
sane = st.floats(min_value=-1e4, max_value=1e4, allow_nan=False)
magnitude = st.floats(min_value=0.0, max_value=1e3, allow_nan=False)


@st.composite
def inputs(draw: st.DrawFn, value: st.SearchStrategy[float] = anything) -> GripInput:
    return GripInput(f_t=(draw(value), draw(value)), tau=draw(value), f_n=draw(value),
                     gamma=draw(value), n_c=draw(value), t_c=draw(value),
                     sum_dist_m=draw(value), n_contact=draw(st.integers(0, 256)))


@given(law=st.sampled_from(LAWS), inp=inputs(), dt=anything)
def test_output_always_finite_and_bounded(law: GripLaw, inp: GripInput, dt: float) -> None:
    d = law.decide(inp, dt)
    assert math.isfinite(d.f_n_desired)
    assert F_NOM <= d.f_n_desired <= F_MAX
    assert not math.isnan(d.raw)


STATIC = [law for law in LAWS if isinstance(law, (LinearLaw, Ft13Law, Ft13SigmaLaw, ConeMarginLaw))]


@given(law=st.sampled_from(STATIC), fx=sane, fy=sane, tau=sane, scale=st.floats(1.0, 10.0))
def test_static_laws_monotone_in_load(law: GripLaw, fx: float, fy: float, tau: float, scale: float) -> None:
    small = law.decide(GripInput(f_t=(fx, fy), tau=tau))
    large = law.decide(GripInput(f_t=(fx * scale, fy * scale), tau=tau * scale))
    assert large.raw >= small.raw - 1e-9 * abs(small.raw)
    assert large.f_n_desired >= small.f_n_desired


@given(fx=sane, fy=sane, tau=sane, scale=st.floats(0.01, 100.0))
def test_scaling_of_load(fx: float, fy: float, tau: float, scale: float) -> None:
    """linear and ft13_sigma are homogeneous of degree 1 in (f_t, τ); ft13 and cone_margin
    are, once their demand at zero load (the offset) is taken away."""
    lin, ft13, ft13s, _ = STATIC
    base = GripInput(f_t=(fx, fy), tau=tau)
    scaled = GripInput(f_t=(fx * scale, fy * scale), tau=tau * scale)
    assert lin.decide(scaled).raw == pytest.approx(scale * lin.decide(base).raw, rel=1e-9, abs=1e-9)
    assert ft13s.decide(scaled).raw == pytest.approx(scale * ft13s.decide(base).raw, rel=1e-9, abs=1e-9)
    for offset_law in STATIC[1::2]:  # ft13 and cone_margin: an offset at zero load
        offset = offset_law.decide(GripInput(f_t=(0.0, 0.0), tau=0.0)).raw
        expected = scale * (offset_law.decide(base).raw - offset)
        assert offset_law.decide(scaled).raw - offset == pytest.approx(expected, rel=1e-9, abs=1e-9)


@given(law=st.sampled_from(STATIC), fx=sane, fy=sane, tau=sane)
def test_static_laws_ignore_the_sense_of_the_load(law: GripLaw, fx: float, fy: float, tau: float) -> None:
    """Reversing the tangential force or the torque (either sense of slip) needs the same grip."""
    ref = law.decide(GripInput(f_t=(fx, fy), tau=tau)).raw
    assert law.decide(GripInput(f_t=(-fx, -fy), tau=tau)).raw == pytest.approx(ref, rel=1e-12)
    assert law.decide(GripInput(f_t=(fy, -fx), tau=-tau)).raw == pytest.approx(ref, rel=1e-12)


def test_static_laws_hand_checked_values() -> None:
    """|f_t| = 0.5 N, |τ| = 4 mN·m, μ = 0.45, β = 8 mm, σ = 0.5, k = 2 N, worked by hand."""
    lin, ft13, ft13s, _ = STATIC
    inp = GripInput(f_t=(0.3, -0.4), tau=-0.004)
    assert lin.decide(inp).raw == pytest.approx(0.5 / 0.225, rel=1e-12)  # 2.222 N
    assert ft13.decide(inp).raw == pytest.approx(1.1111111111111112 + 0.5 + 2.0, rel=1e-12)  # 3.611 N
    assert ft13s.decide(inp).raw == pytest.approx((1.1111111111111112 + 0.5) * 2.0, rel=1e-12)  # 3.222 N
    assert ft13.decide(GripInput(f_t=(0.0, 0.0), tau=0.0)).raw == pytest.approx(2.0)  # the paper's 2 N offset


@given(n_c=sane, t_c=magnitude, dist=st.floats(1e-4, 1.0), n_a=st.integers(1, 256),
       scale=st.floats(0.01, 100.0))
# |n| one ulp above T: the scaled difference rounds 14 % away from 7 x the unscaled one
# (failed the test's former tolerance rel 1e-9, abs 1e-12; 883205e)
@example(n_c=7.151030083563861, t_c=7.15103008356386, dist=1e-4, n_a=256, scale=7.0)
def test_tactile14_increment_scales_with_torque_and_counts_taxels(
    n_c: float, t_c: float, dist: float, n_a: int, scale: float
) -> None:
    total = tactile14_increment(n_c, t_c, dist, n_a, 0.45, 0.5)
    per = tactile14_increment(n_c, t_c, dist, n_a, 0.45, 0.5, "per_taxel")
    assert total == pytest.approx(n_a * per, rel=1e-12)
    # |n| − T cancels: scaling both moves the rounding of the difference by up to 2 ulps of |n|
    rounding = 4 * math.ulp(abs(n_c) * max(scale, 1.0)) / (0.5 * 0.45 * dist) * n_a
    assert tactile14_increment(n_c * scale, t_c * scale, dist, n_a, 0.45, 0.5) == pytest.approx(
        scale * total, rel=1e-9, abs=1e-12 + rounding)
    assert tactile14_increment(-n_c, t_c, dist, n_a, 0.45, 0.5) == total  # both senses of rotation
    assert (total > 0) == (abs(n_c) > t_c)  # raise only while test (11) fails


PAD4 = PadGeometry(4, 4, 1.25e-3)


@given(phi=arrays(float, 16, elements=st.one_of(st.just(0.0), st.floats(0.01, 2.0))).filter(lambda a: a.any()),
       c=st.tuples(st.floats(-3e-3, 3e-3), st.floats(-3e-3, 3e-3)), excess=st.floats(1e-6, 1e-2),
       sense=st.sampled_from([-1.0, 1.0]), sigma=st.floats(0.1, 1.0))
def test_tactile14_increment_restores_test_11_with_margin(phi, c, excess, sense, sigma) -> None:
    """Raise every taxel in contact by the per-taxel increment and recompute the torsional
    capacity T(p_c) = μ Σ φ_i |p_i − p_c| from the taxels: test (11) |n(p_c)| ≤ T holds
    again, exactly at the limit for σ = 1 and with the excess to spare over the limit
    scaled by 1/σ otherwise."""
    mu = 0.45
    dist = np.hypot(*(PAD4.positions - np.asarray(c)).T)
    contact = phi > 0
    t_before = mu * float(np.sum(phi * dist))
    n_c = sense * (t_before + excess)
    per = tactile14_increment(n_c, t_before, float(dist[contact].sum()), int(contact.sum()), mu, sigma, "per_taxel")
    t_after = mu * float(np.sum((phi + per * contact) * dist))
    assert abs(n_c) <= t_after * (1 + 1e-12)
    assert t_after - t_before == pytest.approx(excess / sigma, rel=1e-9)


steps = st.lists(
    st.tuples(inputs(st.one_of(sane, anything)), st.integers(0, 30_000_000), st.integers(0, 120_000_000),
              st.booleans()),
    min_size=1, max_size=30,
)


@given(law=st.sampled_from(LAWS), seq=steps)
def test_governor_finite_bounded_rate_limited_and_holds(
    law: GripLaw, seq: list[tuple[GripInput, int, int, bool]]
) -> None:
    rate = 300.0
    gov = GripGovernor(law, timeout_ns=50_000_000, max_rate_n_per_s=rate, initial_n=F_NOM, blind_grace_ns=-1)
    now, last = 0, gov.last_n
    for inp, advance, age, ok in seq:
        now += advance
        d = gov.step(inp, now_ns=now, stamps_ns=[now - age], status_ok=ok)
        assert math.isfinite(d.f_n_desired) and not math.isnan(d.raw)
        assert F_NOM <= d.f_n_desired <= F_MAX
        assert abs(d.f_n_desired - last) <= rate * advance * 1e-9 + 1e-9
        if d.reason is GripReason.FAIL_SAFE:
            assert d.f_n_desired == last  # held: never below (nor above) the last command
        last = d.f_n_desired


finger_reports = st.one_of(st.none(), st.builds(FingerReport, anything, st.booleans()))


@given(law=st.sampled_from(LAWS), seq=steps, finger=finger_reports,
       f_hold=st.one_of(st.none(), st.floats(0.0, 2 * F_MAX)), grace=st.integers(-1, 60_000_000))
def test_governor_start_contract(law: GripLaw, seq: list[tuple[GripInput, int, int, bool]],
                                 finger: FingerReport | None, f_hold: float | None, grace: int) -> None:
    """docs/safety.md, clause 4, for every law: the first command is never below the force
    measured when the step is trusted, nor below the finger's report; with neither, nothing
    until the wait for the report is over, then f_hold; all within the bounds. Until a valid
    step, the grip is held, and raised only for a finger a controller commanded before."""
    gov = GripGovernor(law, timeout_ns=50_000_000, max_rate_n_per_s=300.0, f_hold_n=f_hold,
                       finger_wait_ns=100_000_000, blind_grace_ns=grace)
    now, first, last, asked = 0, None, None, None
    for inp, advance, age, ok in seq:
        now += advance
        asked = now if asked is None else asked
        d = gov.step(inp, now_ns=now, stamps_ns=[now - age], status_ok=ok, finger=finger)
        trusted = ok and age <= 50_000_000 and math.isfinite(inp.f_n)
        if first is None:
            floors = ([inp.f_n] if trusted else []) + (
                [finger.f_n_command] if finger and math.isfinite(finger.f_n_command) else [])
            if not floors and f_hold is not None and now - asked >= 100_000_000:
                floors = [f_hold]
            if not floors:
                assert d is None
                continue
            first = min(max(max(floors), F_NOM), F_MAX)
            assert d.f_n_desired == first  # valid or not: the first step moves nowhere (dt 0)
        else:
            assert d is not None
        if d.reason is not GripReason.FAIL_SAFE:
            return  # a valid step: the law takes over (the other properties hold from here)
        if last is not None:
            squeezes = finger is not None and finger.commanded and math.isfinite(finger.f_n_command)
            assert d.f_n_desired == last or (squeezes and d.f_n_desired > last)
        assert F_NOM <= d.f_n_desired <= F_MAX
        last = d.f_n_desired
