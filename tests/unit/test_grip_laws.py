"""Grip laws (docs/math.md §5): hand-checked values, bounds, rate limit, fail-safe."""

from __future__ import annotations

import dataclasses

import math

import numpy as np
import pytest

from slipstack.lib.errors import ConfigError
from slipstack.lib.grip_laws import (
    FingerReport,
    LAWS,
    ConeMarginLaw,
    ExactLaw,
    Ft13Law,
    Ft13SigmaLaw,
    GripGovernor,
    GripInput,
    GripReason,
    LinearLaw,
    RateLimiter,
    Tactile14Law,
    make_law,
    tactile14_increment,
)

MS = 1_000_000  # ns per ms
NAN = float("nan")


# ---------------------------------------------------------------- the laws, by hand


def test_linear_law_hand_value() -> None:
    # |f_t| = |(3, 4)| = 5 N; f_n = 5 / (σ μ) = 5 / (0.5 · 0.5) = 20 N, inside [1, 30].
    law = LinearLaw(mu=0.5, sigma=0.5, f_nom_n=1.0, f_max_n=30.0)
    d = law.decide(GripInput(f_t=(3.0, 4.0)))
    assert d.f_n_desired == pytest.approx(20.0)
    assert d.raw == pytest.approx(20.0)
    assert d.reason is GripReason.SLIP and d.reason == "slip"
    assert d.law == "linear"
    pair = GripInput(f_t=np.array([3.0, 4.0]))  # type: ignore[arg-type]  # numpy works too
    assert law.decide(pair).f_n_desired == pytest.approx(20.0)


def test_linear_law_paper_parameters() -> None:
    # Paper σ = 0.5, μ = 0.45: |f_t| = 0.9 N -> 0.9 / 0.225 = 4 N.
    d = LinearLaw(f_nom_n=1.0, f_max_n=30.0).decide(GripInput(f_t=(0.9, 0.0)))
    assert d.f_n_desired == pytest.approx(4.0)


def test_cone_margin_law_hand_value() -> None:
    # μ = 0.75, so √(1 + μ²) = 1.25; |f_t| = |(3, 4)| = 5 N, d = 2 N: f_n = (5 + 1.25·2) / 0.75 = 10 N.
    law = ConeMarginLaw(mu=0.75, cone_margin_n=2.0, f_nom_n=1.0, f_max_n=30.0)
    d = law.decide(GripInput(f_t=(3.0, 4.0)))
    assert (d.f_n_desired, d.reason, d.law) == (pytest.approx(10.0), GripReason.SLIP, "cone_margin")
    # the force (5 N, 10 N) lies d = (μ f_n − |f_t|)/√(1+μ²) = (7.5 − 5)/1.25 = 2 N inside the cone
    assert (0.75 * d.f_n_desired - 5.0) / 1.25 == pytest.approx(2.0)
    # no load: (0 + 2.5)/0.75 = 3.33 N; below f_nom = 4 N it is f_nom, nominal
    assert law.decide(GripInput(f_t=(0.0, 0.0))).f_n_desired == pytest.approx(10.0 / 3.0)
    low = ConeMarginLaw(mu=0.75, cone_margin_n=2.0, f_nom_n=4.0, f_max_n=30.0).decide(GripInput(f_t=(0.0, 0.0)))
    assert (low.f_n_desired, low.reason) == (4.0, GripReason.NOMINAL)
    # a non-finite f_t: fail-safe at f_max, as every law
    bad = law.decide(GripInput(f_t=(NAN, 1.0)))
    assert (bad.f_n_desired, bad.reason) == (30.0, GripReason.FAIL_SAFE) and "f_t" in bad.detail


def test_cone_margin_law_minimises_distance_to_nominal_plus_barrier() -> None:
    """The strategy of the paper's ref. [9] by brute force: over a fine grid of f_n the
    least d_f + w/d_s (w = d²√(1+μ²)/μ) is where the law puts f_n, for loads on both sides
    of the point where the margin reaches f_nom."""
    mu, margin, f_nom = 0.45, 1.0, 2.0
    w = margin ** 2 * math.sqrt(1 + mu ** 2) / mu
    law = ConeMarginLaw(mu=mu, cone_margin_n=margin, f_nom_n=f_nom, f_max_n=1e3)
    for f_t in (0.0, 0.5, 1.0, 3.0, 8.0):
        grid = np.linspace(f_t / mu + 1e-6, f_t / mu + 40.0, 400_001)
        d_s = (mu * grid - f_t) / math.sqrt(1 + mu ** 2)
        best = grid[np.argmin(np.abs(grid - f_nom) + w / d_s)]
        assert law.decide(GripInput(f_t=(f_t, 0.0))).f_n_desired == pytest.approx(best, abs=2e-4), f_t


def test_bounds_nominal_and_saturated() -> None:
    # |f_t| = 0.5 N -> raw 0.5 / 0.25 = 2 N < f_nom = 5 N -> 5 N, nominal.
    low = LinearLaw(mu=0.5, sigma=0.5, f_nom_n=5.0, f_max_n=15.0).decide(GripInput(f_t=(0.3, 0.4)))
    assert (low.f_n_desired, low.reason, low.raw) == (5.0, GripReason.NOMINAL, pytest.approx(2.0))
    # |f_t| = 5 N -> raw 20 N > f_max = 15 N -> 15 N, saturated, raw kept.
    high = LinearLaw(mu=0.5, sigma=0.5, f_nom_n=5.0, f_max_n=15.0).decide(GripInput(f_t=(3.0, 4.0)))
    assert (high.f_n_desired, high.reason, high.raw) == (15.0, GripReason.SATURATED, pytest.approx(20.0))


def test_ft13_hand_value() -> None:
    # |f_t|/μ = 5 / 0.5 = 10 N; |τ|/β = 0.02 N·m / 0.01 m = 2 N; + k = 2 N -> 14 N.
    law = Ft13Law(mu=0.5, beta_m=0.01, k_n=2.0, f_nom_n=1.0, f_max_n=30.0)
    d = law.decide(GripInput(f_t=(3.0, 4.0), tau=-0.02))
    assert d.f_n_desired == pytest.approx(14.0)
    # No load: raw = k = 2 N, above f_nom = 1 N.
    assert law.decide(GripInput(f_t=(0.0, 0.0), tau=0.0)).raw == pytest.approx(2.0)


def test_ft13_sigma_hand_value() -> None:
    # (|f_t|/μ + |τ|/β)/σ = (10 + 2) / 0.5 = 24 N.
    law = Ft13SigmaLaw(mu=0.5, beta_m=0.01, sigma=0.5, f_nom_n=1.0, f_max_n=30.0)
    assert law.decide(GripInput(f_t=(3.0, 4.0), tau=0.02)).f_n_desired == pytest.approx(24.0)


def test_exact_law_hand_value() -> None:
    # γ f_n / σ = 0.8 · 10 N / 0.5 = 16 N.
    law = ExactLaw(sigma=0.5, f_nom_n=1.0, f_max_n=30.0)
    assert law.decide(GripInput(gamma=0.8, f_n=10.0)).f_n_desired == pytest.approx(16.0)


# Test (11) fails: |n| = 0.05 N·m > T = 0.03 N·m, excess 0.02 N·m; σ = μ = 0.5, Σ|p_i − p_c| = 0.08 m:
# δφ = 0.02 / (0.5 · 0.5 · 0.08) = 0.02 / 0.02 = 1 N per taxel; N_A = 10 -> δf_n = 10 N.
FAILING = GripInput(f_n=5.0, n_c=0.05, t_c=0.03, sum_dist_m=0.08, n_contact=10)


def test_tactile14_increment_total_and_per_taxel() -> None:
    assert tactile14_increment(0.05, 0.03, 0.08, 10, 0.5, 0.5) == pytest.approx(10.0)
    assert tactile14_increment(0.05, 0.03, 0.08, 10, 0.5, 0.5, "per_taxel") == pytest.approx(1.0)
    # Opposite sense of rotation counts the same (|n|).
    assert tactile14_increment(-0.05, 0.03, 0.08, 10, 0.5, 0.5) == pytest.approx(10.0)
    # Test holds (|n| = 0.02 <= 0.03): no increment.
    assert tactile14_increment(0.02, 0.03, 0.08, 10, 0.5, 0.5) == 0.0
    # Fails with no lever arm (point contact): unbounded.
    assert tactile14_increment(0.05, 0.03, 0.0, 1, 0.5, 0.5) == math.inf


def test_tactile14_law_raises_by_total_or_per_taxel() -> None:
    total = Tactile14Law(mu=0.5, sigma=0.5, f_nom_n=1.0, f_max_n=30.0)
    per = Tactile14Law(mu=0.5, sigma=0.5, increment="per_taxel", f_nom_n=1.0, f_max_n=30.0)
    assert total.decide(FAILING).f_n_desired == pytest.approx(15.0)  # 5 + 10
    assert per.decide(FAILING).f_n_desired == pytest.approx(6.0)  # 5 + 1
    assert total.decide(FAILING).reason is GripReason.SLIP


def test_tactile14_raises_for_clockwise_and_counter_clockwise_slip_alike() -> None:
    # The limit set is centrally symmetric: a load torque of -n about the COR fails test (11)
    # exactly as +n does, and asks for the same increment.
    law = Tactile14Law(mu=0.5, sigma=0.5, f_nom_n=1.0, f_max_n=30.0)
    clockwise = dataclasses.replace(FAILING, n_c=-FAILING.n_c)
    assert law.decide(clockwise).f_n_desired == pytest.approx(law.decide(FAILING).f_n_desired)
    assert law.decide(clockwise).reason is GripReason.SLIP
    holding = dataclasses.replace(FAILING, n_c=-0.5 * FAILING.t_c)  # |n| < T: (11) holds
    assert law.decide(holding).f_n_desired == pytest.approx(FAILING.f_n)


def test_tactile14_holds_or_decays_when_test_passes() -> None:
    passing = GripInput(f_n=8.0, n_c=0.02, t_c=0.03, sum_dist_m=0.08, n_contact=10)
    hold = Tactile14Law(mu=0.5, sigma=0.5, f_nom_n=1.0, f_max_n=30.0)
    assert hold.decide(passing, dt_s=0.5).f_n_desired == pytest.approx(8.0)
    # Decay 2 N/s for 0.5 s: 8 − 1 = 7 N; never below f_nom (1 N) even after 100 s.
    decay = Tactile14Law(mu=0.5, sigma=0.5, decay_n_per_s=2.0, f_nom_n=1.0, f_max_n=30.0)
    assert decay.decide(passing, dt_s=0.5).f_n_desired == pytest.approx(7.0)
    far = decay.decide(passing, dt_s=100.0)
    assert (far.f_n_desired, far.reason) == (1.0, GripReason.NOMINAL)


def test_tactile14_point_contact_saturates() -> None:
    law = Tactile14Law(f_nom_n=1.0, f_max_n=30.0)
    d = law.decide(GripInput(f_n=5.0, n_c=0.01, t_c=0.0, sum_dist_m=0.0, n_contact=1))
    assert (d.f_n_desired, d.reason, d.raw) == (30.0, GripReason.SATURATED, math.inf)


@pytest.mark.parametrize("bad", [NAN, math.inf, -math.inf])
def test_law_non_finite_input_is_fail_safe_not_nan(bad: float) -> None:
    law = LinearLaw(f_nom_n=1.0, f_max_n=30.0)
    d = law.decide(GripInput(f_t=(bad, 1.0)))
    assert (d.f_n_desired, d.reason) == (30.0, GripReason.FAIL_SAFE)
    assert math.isfinite(d.raw) and "f_t" in d.detail


# ---------------------------------------------------------------- registry and config


def test_registry_names() -> None:
    assert set(LAWS) == {"linear", "ft13", "ft13_sigma", "tactile14", "exact", "cone_margin"}
    law = make_law("ft13", beta_m=0.01, f_nom_n=1.0, f_max_n=30.0)
    assert isinstance(law, Ft13Law) and law.k_n == 2.0 and law.mu == 0.45


@pytest.mark.parametrize(
    ("name", "params", "words"),
    [
        ("nope", {}, "unknown grip law"),
        ("ft13", {"f_nom_n": 1.0, "f_max_n": 30.0}, "beta_m"),
        ("linear", {"f_nom_n": 1.0, "f_max_n": 30.0, "sigma": 1.5}, "sigma"),
        ("linear", {"f_nom_n": 40.0, "f_max_n": 30.0}, "f_nom_n"),
        ("linear", {"f_nom_n": 1.0, "f_max_n": 30.0, "mu": 0.0}, "mu"),
        ("linear", {"f_nom_n": 1.0, "f_max_n": 30.0, "colour": 1}, "colour"),
        ("tactile14", {"f_nom_n": 1.0, "f_max_n": 30.0, "increment": "each"}, "increment"),
        ("cone_margin", {"f_nom_n": 1.0, "f_max_n": 30.0, "cone_margin_n": 0.0}, "cone_margin_n"),
    ],
)
def test_config_errors_say_what_to_fix(name: str, params: dict, words: str) -> None:
    with pytest.raises(ConfigError, match=words):
        make_law(name, **params)


# ---------------------------------------------------------------- rate limiter


def test_rate_limiter_rise_and_fall() -> None:
    lim = RateLimiter(100.0, max_fall_rate_n_per_s=10.0, initial_n=5.0)
    assert lim.step(20.0, 0.05) == pytest.approx(10.0)  # 5 + 100 · 0.05
    assert lim.step(20.0, 0.1) == pytest.approx(20.0)  # 10 + 10 would pass 20: reaches target
    assert lim.step(0.0, 0.1) == pytest.approx(19.0)  # 20 − 10 · 0.1
    assert lim.step(0.0, -1.0) == pytest.approx(19.0)  # time going back: hold
    assert lim.step(0.0, NAN) == pytest.approx(19.0)


def test_rate_limiter_first_step_passes_through() -> None:
    lim = RateLimiter(1.0)
    assert lim.value is None
    assert lim.step(7.0, 0.0) == 7.0
    lim.reset(3.0)  # e.g. to the measured actuator force
    assert lim.step(10.0, 0.5) == pytest.approx(3.5)  # 3 + 1 N/s · 0.5 s


def test_rate_limiter_rejects_bad_rate() -> None:
    with pytest.raises(ConfigError, match="max_rate_n_per_s"):
        RateLimiter(0.0)


# ---------------------------------------------------------------- governor: fail-safe


def _governor(**kw: object) -> GripGovernor:
    # Linear law μ = σ = 0.5, bounds [2, 30] N, 200 N/s actuator, 50 ms timeout, starting at 2 N.
    law = LinearLaw(mu=0.5, sigma=0.5, f_nom_n=2.0, f_max_n=30.0)
    return GripGovernor(law, timeout_ns=50 * MS, max_rate_n_per_s=200.0, **{"initial_n": 2.0, **kw})


LOAD = GripInput(f_t=(3.0, 4.0))  # law demand 20 N


def test_governor_rate_limits_from_initial() -> None:
    gov = _governor()
    first = gov.step(LOAD, now_ns=0, stamps_ns=[0])
    assert first.f_n_desired == 2.0 and first.raw == pytest.approx(20.0)  # dt = 0: initial f_nom
    # 10 ms at 200 N/s = 2 N per step: 4, 6, ..., 20 at 90 ms, then held at 20.
    out = [gov.step(LOAD, now_ns=k * 10 * MS, stamps_ns=[k * 10 * MS]).f_n_desired for k in range(1, 12)]
    assert out[:3] == pytest.approx([4.0, 6.0, 8.0])
    assert out[8:] == pytest.approx([20.0, 20.0, 20.0])


def _raised() -> GripGovernor:
    gov = _governor()
    for k in range(11):
        gov.step(LOAD, now_ns=k * 10 * MS, stamps_ns=[k * 10 * MS])
    assert gov.last_n == pytest.approx(20.0)
    return gov


def test_stale_input_holds_never_releases() -> None:
    gov = _raised()
    # Newest stamp 100 ms, now 200 ms: age 100 ms > 50 ms. The (stale) load is zero,
    # which would release to f_nom: the governor holds 20 N instead.
    d = gov.step(GripInput(f_t=(0.0, 0.0)), now_ns=200 * MS, stamps_ns=[100 * MS, 190 * MS])
    assert (d.f_n_desired, d.reason) == (pytest.approx(20.0), GripReason.FAIL_SAFE)
    assert "age 100.000 ms > timeout 50.000 ms" in d.detail
    assert gov.in_fail_safe


def test_nan_and_bad_status_hold() -> None:
    gov = _raised()
    nan = gov.step(GripInput(f_t=(NAN, 0.0)), now_ns=110 * MS, stamps_ns=[110 * MS])
    status = gov.step(GripInput(f_t=(0.0, 0.0)), now_ns=120 * MS, stamps_ns=[120 * MS], status_ok=False)
    none = gov.step(GripInput(f_t=(0.0, 0.0)), now_ns=130 * MS, stamps_ns=[])
    for d in (nan, status, none):
        assert d.reason is GripReason.FAIL_SAFE
        assert d.f_n_desired == pytest.approx(20.0) and math.isfinite(d.raw)
    assert "status" in status.detail and "stamps" in none.detail


def test_recovery_is_rate_limited() -> None:
    gov = _raised()
    gov.step(GripInput(f_t=(0.0, 0.0)), now_ns=300 * MS, stamps_ns=[0])  # stale: hold 20
    # Fresh zero load 10 ms later: falls by 200 N/s · 10 ms = 2 N, not straight to f_nom.
    d = gov.step(GripInput(f_t=(0.0, 0.0)), now_ns=310 * MS, stamps_ns=[310 * MS])
    assert (d.f_n_desired, d.reason) == (pytest.approx(18.0), GripReason.NOMINAL)
    assert not gov.in_fail_safe


def test_governor_fail_safe_before_any_input_holds_initial() -> None:
    gov = _governor()
    d = gov.step(LOAD, now_ns=0, stamps_ns=[-(100 * MS)])
    assert (d.f_n_desired, d.reason) == (2.0, GripReason.FAIL_SAFE)


def test_a_started_governor_begins_from_the_trusted_measured_force_not_f_nom() -> None:
    # A respawned controller while the finger squeezes 12.9 N on valid data: its first command is
    # 12.9 N, and the law then moves it at the slew limit (200 N/s: 2 N per 10 ms).
    measured = GripInput(f_t=(0.3, 0.4), f_n=12.9)  # law demand 2 N (f_nom)
    fresh = _governor(initial_n=None)
    first = fresh.step(measured, now_ns=0, stamps_ns=[0])
    assert first.f_n_desired == pytest.approx(12.9)
    assert fresh.step(measured, now_ns=10 * MS, stamps_ns=[10 * MS]).f_n_desired == pytest.approx(10.9)


def test_an_untrusted_measurement_is_no_start_the_finger_report_is() -> None:
    # One RDT BIAS datagram zeroes the F/T: the verdict is implausible, its f_n ~0 N. The old
    # governor started there (f_nom, 2 N) although the finger held 14 N.
    biased = GripInput(f_t=(0.0, 0.0), f_n=0.01)
    gov = _governor(initial_n=None)
    assert gov.step(biased, now_ns=0, stamps_ns=[0], status_ok=False) is None  # nothing known: no command
    held = gov.step(biased, now_ns=MS, stamps_ns=[MS], status_ok=False, finger=FingerReport(14.0, True))
    assert (held.f_n_desired, held.reason) == (14.0, GripReason.FAIL_SAFE)
    stale = _governor(initial_n=None).step(GripInput(f_n=25.0), now_ns=0, stamps_ns=[-(100 * MS)],
                                           finger=FingerReport(14.0, True))
    assert stale.f_n_desired == 14.0  # a stale measurement is not trusted either, however high


def test_the_start_is_the_highest_of_what_is_known_within_the_bounds() -> None:
    lower_finger = _governor(initial_n=None).step(GripInput(f_n=12.9), now_ns=0, stamps_ns=[0],
                                                  finger=FingerReport(11.0, True))
    higher_finger = _governor(initial_n=None).step(GripInput(f_n=12.9), now_ns=0, stamps_ns=[0],
                                                   finger=FingerReport(13.5, True))
    above_f_max = _governor(initial_n=None).step(GripInput(f_n=1.0), now_ns=0, stamps_ns=[0],
                                                 finger=FingerReport(45.0, True))
    below_f_nom = _governor(initial_n=None).step(GripInput(f_n=0.5), now_ns=0, stamps_ns=[0],
                                                 finger=FingerReport(1.0, False))
    assert [d.f_n_desired for d in (lower_finger, higher_finger, above_f_max, below_f_nom)] == [12.9, 13.5, 30.0, 2.0]


def test_without_trusted_data_or_a_report_f_hold_comes_after_the_wait_for_the_finger() -> None:
    gov = _governor(initial_n=None, f_hold_n=9.0, finger_wait_ns=100 * MS)
    waiting = [gov.step(LOAD, now_ns=k * 10 * MS, stamps_ns=[k * 10 * MS], status_ok=False) for k in range(10)]
    assert waiting == [None] * 10  # 0..90 ms: the finger's report may be on its way
    held = gov.step(LOAD, now_ns=100 * MS, stamps_ns=[100 * MS], status_ok=False)
    assert (held.f_n_desired, held.reason) == (9.0, GripReason.FAIL_SAFE)
    nothing = _governor(initial_n=None)  # no f_hold: no command at all while nothing is known
    assert all(nothing.step(LOAD, now_ns=k * 100 * MS, stamps_ns=[0], status_ok=False) is None for k in range(50))


def test_a_launch_holds_blind_it_does_not_squeeze_a_restart_escalates() -> None:
    # The finger's power-on grip (never commanded): held while the sensors start, however long.
    launch = _governor(initial_n=None, blind_grace_ns=50 * MS)
    out = [launch.step(LOAD, now_ns=k * 10 * MS, stamps_ns=[k * 10 * MS], status_ok=False,
                       finger=FingerReport(3.0, False)).f_n_desired for k in range(100)]
    assert out == [3.0] * 100
    # A finger a controller commanded before: a load was held, so blind it rises after the grace.
    restart = _governor(initial_n=None, blind_grace_ns=50 * MS, blind_rise_n_per_s=10.0)
    out = [restart.step(LOAD, now_ns=k * 10 * MS, stamps_ns=[k * 10 * MS], status_ok=False,
                        finger=FingerReport(14.0, True)).f_n_desired for k in range(16)]
    assert out[:5] == [14.0] * 5 and out[-1] == pytest.approx(15.1)  # 10 N/s from 40 to 150 ms, after 50 ms


def test_governor_escalates_while_blind_and_loaded_then_recovers_rate_limited() -> None:
    gov = _governor(blind_grace_ns=50 * MS, blind_rise_n_per_s=10.0)
    for k in range(11):  # raise to 20 N on valid data
        gov.step(LOAD, now_ns=k * 10 * MS, stamps_ns=[k * 10 * MS])
    t0 = 100 * MS
    blind = [gov.step(LOAD, now_ns=t0 + k * 10 * MS, stamps_ns=[t0]) for k in range(6, 31)]  # stale from 160 ms
    assert all(d.reason is GripReason.FAIL_SAFE for d in blind)
    # stale once the age passes 50 ms (t = 160 ms); held through the 50 ms grace; at 210 ms the
    # first raise covers its step (200 -> 210 ms), so by 400 ms: 0.2 s at 10 N/s
    assert [d.f_n_desired for d in blind[:5]] == pytest.approx([20.0] * 5)
    assert blind[5].f_n_desired == pytest.approx(20.1)
    assert blind[-1].f_n_desired == pytest.approx(22.0)
    assert "raising the grip" in blind[-1].detail
    back = gov.step(LOAD, now_ns=410 * MS, stamps_ns=[410 * MS])  # demand 20 N: down at 200 N/s
    assert back.reason is GripReason.SLIP and back.f_n_desired == pytest.approx(20.0)


def test_governor_does_not_escalate_without_a_load() -> None:
    gov = _governor(blind_grace_ns=0)
    gov.step(GripInput(f_t=(0.0, 0.0)), now_ns=0, stamps_ns=[0], loaded=False)
    out = [gov.step(LOAD, now_ns=k * 10 * MS, stamps_ns=[0], status_ok=False).f_n_desired for k in range(1, 20)]
    assert out == pytest.approx([2.0] * 19)


def test_governor_treats_a_future_stamp_as_untrustworthy() -> None:
    gov = _governor()
    d = gov.step(LOAD, now_ns=0, stamps_ns=[51 * MS])
    assert d.reason is GripReason.FAIL_SAFE and "future" in d.detail
    assert gov.step(LOAD, now_ns=MS, stamps_ns=[2 * MS]).reason is GripReason.SLIP  # within the timeout: fine


def test_governor_config_errors() -> None:
    law = LinearLaw(f_nom_n=2.0, f_max_n=30.0)
    with pytest.raises(ConfigError, match="timeout_ns"):
        GripGovernor(law, timeout_ns=0, max_rate_n_per_s=1.0)
    with pytest.raises(ConfigError, match="initial_n"):
        GripGovernor(law, timeout_ns=1, max_rate_n_per_s=1.0, initial_n=40.0)
