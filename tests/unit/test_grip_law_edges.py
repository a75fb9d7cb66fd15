"""The grip laws and the governor at their edges: the boundaries of every setting, the
classification at the bounds, the exotic NaN, and the documented defaults.

Each test pins a behaviour a plausible one-character bug would change (the mutation
run over lib/grip_laws.py: tests/mutation/).
"""

from __future__ import annotations

import math

import pytest

from slipstack.lib.errors import ConfigError
from slipstack.lib.grip_laws import (
    Ft13Law,
    GripGovernor,
    GripInput,
    GripReason,
    LinearLaw,
    Tactile14Law,
    bound_demand,
)

MS = 1_000_000


def test_a_demand_exactly_at_a_bound_is_classified_by_the_bound_it_does_not_exceed():
    assert bound_demand(20.0, 2.0, 20.0, "x").reason is GripReason.SLIP  # not above f_max: not saturated
    assert bound_demand(20.0 + 1e-12, 2.0, 20.0, "x").reason is GripReason.SATURATED
    assert bound_demand(2.0, 2.0, 20.0, "x").reason is GripReason.NOMINAL  # not above f_nom: nominal
    assert bound_demand(2.0 + 1e-12, 2.0, 20.0, "x").reason is GripReason.SLIP


@pytest.mark.parametrize(("f_nom", "f_max", "ok"), [
    (0.0, 5.0, True),  # a zero least force is allowed
    (5.0, 5.0, True),  # a fixed grip: f_nom = f_max
    (0.0, 0.0, False),  # f_max must be > 0
    (-0.1, 5.0, False),
    (6.0, 5.0, False),
    (0.5, 1.0, True),  # f_max below 1 N is a valid (small) gripper
])
def test_bounds_accepted_and_refused(f_nom, f_max, ok):
    if ok:
        LinearLaw(f_nom_n=f_nom, f_max_n=f_max)
    else:
        with pytest.raises(ConfigError, match="f_nom_n"):
            LinearLaw(f_nom_n=f_nom, f_max_n=f_max)


def test_sigma_one_is_allowed_and_zero_is_not():
    LinearLaw(f_nom_n=1.0, f_max_n=10.0, sigma=1.0)  # no margin, but legal
    with pytest.raises(ConfigError, match="sigma"):
        LinearLaw(f_nom_n=1.0, f_max_n=10.0, sigma=0.0)


@pytest.mark.parametrize(("k", "ok"), [(0.0, True), (2.0, True), (-1.0, False), (math.nan, False), (math.inf, False)])
def test_the_offset_of_law_13_is_a_finite_force_of_zero_or_more(k, ok):
    if ok:
        assert Ft13Law(f_nom_n=0.0, f_max_n=50.0, beta_m=0.002, k_n=k).k_n == k
    else:
        with pytest.raises(ConfigError, match="k_n"):
            Ft13Law(f_nom_n=0.0, f_max_n=50.0, beta_m=0.002, k_n=k)


@pytest.mark.parametrize("decay", [-1.0, math.nan, math.inf])
def test_law_14_refuses_a_decay_that_is_not_a_finite_rate(decay):
    with pytest.raises(ConfigError, match="decay"):
        Tactile14Law(f_nom_n=1.0, f_max_n=30.0, decay_n_per_s=decay)


def test_law_14_defaults_are_the_papers():
    law = Tactile14Law(f_nom_n=1.0, f_max_n=30.0)
    assert (law.mu, law.sigma, law.increment, law.decay_n_per_s) == (0.45, 0.5, "total", 0.0)


def test_law_14_holds_over_a_step_of_unknown_length():
    law = Tactile14Law(f_nom_n=1.0, f_max_n=30.0, decay_n_per_s=100.0)
    holding = GripInput(f_n=10.0, n_c=0.0, t_c=1.0, sum_dist_m=0.1, n_contact=10)
    assert law.decide(holding, dt_s=math.nan).f_n_desired == 10.0  # no time known: no decay
    assert law.decide(holding, dt_s=math.inf).f_n_desired == 10.0  # nor an infinite step
    assert law.decide(holding).f_n_desired == 10.0  # a step given no length holds
    assert law.decide(holding, dt_s=0.01).f_n_desired == pytest.approx(9.0)


def test_an_overflowing_increment_over_no_taxels_is_a_nan_demand_and_fails_safe():
    # excess / lever overflows to inf, and inf * N_A = inf * 0 = NaN: the law must not pass it on
    law = Tactile14Law(f_nom_n=1.0, f_max_n=30.0)
    exotic = GripInput(f_n=5.0, n_c=1e300, t_c=0.0, sum_dist_m=1e-300, n_contact=0)
    d = law.decide(exotic)
    assert (d.f_n_desired, d.reason) == (30.0, GripReason.FAIL_SAFE) and "NaN" in d.detail


def test_an_input_that_is_not_a_number_is_a_fail_safe_decision_not_an_exception():
    d = LinearLaw(f_nom_n=1.0, f_max_n=30.0).decide(GripInput(f_t=("a", 1.0)))  # type: ignore[arg-type]
    assert (d.f_n_desired, d.reason) == (30.0, GripReason.FAIL_SAFE)


def _governor(**kw) -> GripGovernor:
    law = LinearLaw(mu=0.5, sigma=0.5, f_nom_n=2.0, f_max_n=30.0)
    return GripGovernor(law, timeout_ns=50 * MS, max_rate_n_per_s=200.0, **{"initial_n": 2.0, **kw})


LOAD = GripInput(f_t=(3.0, 4.0))  # demand 20 N


def test_the_governor_defaults_are_the_documented_policy():
    gov = GripGovernor(LinearLaw(f_nom_n=2.0, f_max_n=30.0), timeout_ns=MS, max_rate_n_per_s=100.0)
    assert (gov.blind_grace_ns, gov.blind_rise_n_per_s, gov.blind_limit_n) == (50 * MS, 10.0, 30.0)  # docs/safety.md


def test_an_input_exactly_one_timeout_old_or_ahead_is_still_fresh():
    gov = _governor()
    assert gov.step(LOAD, now_ns=100 * MS, stamps_ns=[50 * MS]).reason is not GripReason.FAIL_SAFE
    assert gov.step(LOAD, now_ns=110 * MS, stamps_ns=[160 * MS]).reason is not GripReason.FAIL_SAFE
    assert gov.step(LOAD, now_ns=120 * MS, stamps_ns=[69 * MS]).reason is GripReason.FAIL_SAFE


def test_one_input_from_the_future_among_fresh_ones_is_enough_to_distrust_the_step():
    gov = _governor()
    d = gov.step(LOAD, now_ns=100 * MS, stamps_ns=[100 * MS, 200 * MS])
    assert d.reason is GripReason.FAIL_SAFE and "future" in d.detail


def test_a_governor_that_starts_blind_holds_until_a_valid_step_sees_a_load():
    gov = _governor(blind_grace_ns=0)  # holding is not squeezing (issue 29, item 10)
    first = gov.step(LOAD, now_ns=0, stamps_ns=[-100 * MS])
    later = gov.step(LOAD, now_ns=100 * MS, stamps_ns=[-100 * MS])
    assert first.f_n_desired == 2.0 and later.f_n_desired == 2.0


def test_a_zero_grace_escalates_from_the_first_blind_step_after_a_valid_one():
    gov = _governor(blind_grace_ns=0)
    gov.step(LOAD, now_ns=0, stamps_ns=[0])  # valid: 2 N (dt 0), loaded
    d = gov.step(LOAD, now_ns=10 * MS, stamps_ns=[0], status_ok=False)
    assert d.reason is GripReason.FAIL_SAFE and d.f_n_desired == pytest.approx(2.1)


@pytest.mark.parametrize(("kw", "ok"), [
    ({"initial_n": 30.0}, True),  # start at f_max
    ({"blind_limit_n": 2.0}, True),  # escalation capped at f_nom: holding only
    ({"blind_limit_n": math.nan}, False),
    ({"blind_limit_n": 31.0}, False),
])
def test_governor_settings_accepted_and_refused(kw, ok):
    if ok:
        _governor(**kw)
    else:
        with pytest.raises(ConfigError, match="blind_limit_n"):
            _governor(**kw)
