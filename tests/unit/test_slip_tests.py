"""Slip tests of the paper behind one interface (docs/math.md §3)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pytest

from slipstack.lib.errors import ConfigError
from slipstack.lib.fusion import fuse
from slipstack.lib.limit_set import load_factor
from slipstack.lib.pad import PadGeometry
from slipstack.lib.slip_tests import FT_TESTS, SLIP_TESTS, SlipParams, ft_stick_margins, get_slip_test
from slipstack.lib.status import SolverStatus

PAD = PadGeometry(8, 8, 1.25e-3)


@dataclass(frozen=True)
class Contact:
    f_n: float
    f_t: np.ndarray
    tau: float
    phi: np.ndarray
    positions: np.ndarray = field(default_factory=lambda: PAD.positions)


def _uniform(f_n=2.0, f_t=(0.0, 0.0), tau=0.0):
    return Contact(f_n, np.array(f_t, dtype=float), tau, np.full(64, f_n / 64))


def test_registry_names_and_unknown_name():
    assert set(SLIP_TESTS) == {
        "coulomb", "decoupled", "linear_ls", "elliptic_ls", "tactile_cor", "tactile_cor_robust", "exact"
    }
    assert get_slip_test("exact") is SLIP_TESTS["exact"]
    with pytest.raises(ConfigError, match="coulomb"):
        get_slip_test("nope")


def test_force_torque_tests_by_hand():
    # a_t = |f_t|/(μ f_n) = 0.6 and a_r = |τ|/(β f_n) = 0.3
    c = _uniform(2.0, (0.36, 0.48), 3e-3)
    p = SlipParams(mu=0.5, beta_m=5e-3)
    assert SLIP_TESTS["coulomb"](c, p).gamma == pytest.approx(0.6)
    assert SLIP_TESTS["decoupled"](c, p).gamma == pytest.approx(0.6)
    lin = SLIP_TESTS["linear_ls"](c, p)
    assert lin.gamma == pytest.approx(0.9) and lin.margin == pytest.approx(0.1) and lin.stick
    assert SLIP_TESTS["elliptic_ls"](c, p).gamma == pytest.approx(math.sqrt(0.45))
    slip = SLIP_TESTS["linear_ls"](c, SlipParams(mu=0.5, beta_m=5e-3, delta=0.2))
    assert not slip.stick and slip.kind == "combined"  # ρ = 0.3/0.9 = 1/3


def test_kind_follows_the_rotation_share():
    p = SlipParams(mu=0.5, beta_m=5e-3)
    assert SLIP_TESTS["linear_ls"](_uniform(2.0, (2.0, 0.0)), p).kind == "translation"
    assert SLIP_TESTS["linear_ls"](_uniform(2.0, (0.0, 0.0), 0.02), p).kind == "rotation"
    exact = SLIP_TESTS["exact"]
    assert exact(_uniform(2.0, (2.0, 0.0)), p).kind == "translation"
    spin = exact(_uniform(2.0, (0.0, 0.0), 0.02), p)
    assert spin.kind == "rotation" and np.hypot(*spin.p_c) < 1e-12


def test_tactile_tests_without_beta_use_the_tactile_torsional_coefficient():
    c = _uniform(2.0, (0.0, 0.0), 1e-3)
    v = SLIP_TESTS["elliptic_ls"](c, SlipParams(mu=0.5))
    ref = load_factor(c.phi, c.positions, c.f_t, c.tau, 0.5).gamma
    assert v.status is SolverStatus.OK and v.gamma == pytest.approx(ref, rel=1e-9)  # pure torque: exact


def test_no_load_no_contact_and_bad_input_for_every_test():
    p = SlipParams(mu=0.5, beta_m=5e-3)
    for name, test in SLIP_TESTS.items():
        nl = test(_uniform(), p)
        assert nl.stick and nl.margin == 1.0 and nl.kind == "stick", name
        nc = test(Contact(0.0, np.zeros(2), 0.0, np.zeros(64)), p)
        assert not nc.stick and nc.kind == "no-contact", name
        bad = test(Contact(1.0, np.array([np.nan, 0.0]), 0.0, np.full(64, 1 / 64)), p)
        assert bad.status is SolverStatus.INVALID_INPUT and not math.isnan(bad.margin), name


def test_tactile_tests_agree_with_exact_away_from_the_boundary():
    rng = np.random.default_rng(5)
    p = SlipParams(mu=0.5)
    for _ in range(40):
        phi = rng.random(64) * (rng.random(64) < 0.8)
        f_t, tau = rng.normal(size=2) * 0.1, rng.normal() * 1e-3
        g = load_factor(phi, PAD.positions, f_t, tau, 0.5).gamma
        s = rng.choice([0.8, 1.25]) / g
        c = Contact(phi.sum(), f_t * s, tau * s, phi)
        ex = SLIP_TESTS["exact"](c, p)
        assert ex.stick is bool(s * g < 1) and ex.gamma == pytest.approx(s * g, rel=1e-9)
        assert SLIP_TESTS["tactile_cor_robust"](c, p).stick is ex.stick
        paper = SLIP_TESTS["tactile_cor"](c, p)
        if paper.status.usable and not paper.stick:
            assert not ex.stick  # the paper's ratio is a lower bound on γ


def test_fusion_result_is_a_contact_and_warm_start_round_trips():
    pressure = np.zeros(64)
    pressure[[9, 10, 17, 18, 27]] = [1, 2, 3, 4, 5]
    fr = fuse(pressure, [0.3, 0.1, -2.0], [0, 0, 2e-3], PAD)
    p = SlipParams(mu=0.5)
    first = SLIP_TESTS["exact"](fr, p)
    again = SLIP_TESTS["exact"](fr, p, first.p_c)
    assert again.gamma == pytest.approx(first.gamma, rel=1e-12) and again.method == "exact"


def test_params_validation():
    for kw in ({"mu": 0.0}, {"beta_m": -1.0}, {"delta": 1.0}, {"paper_gain": 2.0}):
        with pytest.raises(ConfigError):
            SlipParams(**kw)


def _point(f_n=2.0, f_t=(0.0, 0.0), tau=0.0):
    """All the normal force on one taxel: β_s = 0."""
    phi = np.zeros(64)
    phi[27] = f_n
    return Contact(f_n, np.array(f_t, dtype=float), tau, phi)


@pytest.mark.parametrize("contact", [
    _uniform(f_t=(0.3, -0.4), tau=2e-3),                 # both ratios
    _uniform(f_t=(2.0, 0.0), tau=-9e-3),                 # slips
    _uniform(),                                          # no load
    _uniform(f_t=(0.0, 0.0), tau=1e-320),                # a torque whose ratio underflows
    _uniform(f_n=0.0, f_t=(0.1, 0.0)),                   # no contact
    _uniform(f_t=(math.nan, 0.0)),                       # bad input
    _point(f_t=(0.5, 0.0)),                              # point contact, no torque
    _point(f_t=(0.5, 0.0), tau=1e-4),                    # point contact under a torque
    Contact(2.0, np.array([0.3, 0.0]), 1e-3, np.zeros(0), np.zeros((0, 2))),  # no β at all
], ids=["load", "slip", "no-load", "underflow", "no-contact", "nan", "point", "point-torque", "no-beta"])
@pytest.mark.parametrize("beta_m", [None, 2e-3])
def test_the_ft_tests_judged_together_agree_with_each_test_alone(contact, beta_m):
    params = SlipParams(mu=0.5, beta_m=beta_m, delta=0.1)
    for names in (FT_TESTS, FT_TESTS[::-1], ("elliptic_ls",), ("coulomb",)):
        together = ft_stick_margins(contact, params, names)
        alone = [SLIP_TESTS[name](contact, params) for name in names]
        assert together == [(v.stick, v.margin) for v in alone]
    assert FT_TESTS == ("coulomb", "decoupled", "linear_ls", "elliptic_ls")
