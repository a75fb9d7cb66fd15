"""Oracle grip force (lib/oracle.py): hand-checked values on uniform and Hertzian pads."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slipstack.lib.limit_set import load_factor
from slipstack.lib.oracle import least_holding_force, oracle_normal_force
from slipstack.lib.pad import PadGeometry
from slipstack.lib.status import SolverStatus

MU = 0.5
PAD = PadGeometry()  # 16 x 16, pitch 1.25 mm
P = PAD.positions


def uniform(f_n: float) -> np.ndarray:
    return np.full(PAD.n_taxels, f_n / PAD.n_taxels)


@pytest.mark.parametrize("f_n", [0.5, 4.0, 60.0])
def test_pure_force_on_uniform_pad_needs_ft_over_mu(f_n):
    # |f_t| = 5 N, μ = 0.5: the least holding force is 10 N whatever the force now.
    r = oracle_normal_force(uniform(f_n), P, (3.0, 4.0), 0.0, MU)
    assert r.status is SolverStatus.TRANSLATION
    assert r.f_n_min == pytest.approx(10.0, rel=1e-12)
    assert r.gamma == pytest.approx(10.0 / f_n, rel=1e-12)


def test_pure_torque_on_uniform_pad_needs_tau_over_mu_mean_radius():
    # Symmetric pad: the COR is the centre, capacity μ f_n · mean |p_i|.
    mean_r = float(np.mean(np.hypot(P[:, 0], P[:, 1])))  # ≈ 7.65 mm for a 2 cm square
    assert mean_r == pytest.approx(7.65e-3, rel=2e-3)
    r = oracle_normal_force(uniform(3.0), P, (0.0, 0.0), 0.02, MU)
    assert r.usable
    assert r.f_n_min == pytest.approx(0.02 / (MU * mean_r), rel=1e-6)


def test_special_cases():
    no_load = oracle_normal_force(uniform(3.0), P, (0.0, 0.0), 0.0, MU)
    assert (no_load.f_n_min, no_load.status) == (0.0, SolverStatus.NO_LOAD)
    point = np.zeros(PAD.n_taxels)
    point[0] = 2.0
    spun = oracle_normal_force(point, P, (0.0, 0.0), 1e-3, MU)
    assert spun.usable and spun.f_n_min == math.inf
    none = oracle_normal_force(np.zeros(PAD.n_taxels), P, (1.0, 0.0), 0.0, MU)
    assert not none.usable and math.isnan(none.f_n_min)
    bad = least_holding_force(uniform, P, (1.0, 0.0), 0.0, MU, f_start=0.0)
    assert bad.status is SolverStatus.INVALID_INPUT and math.isnan(bad.f_n_min)


def test_fixed_point_of_a_scaling_shape_is_gamma_times_f():
    r = least_holding_force(uniform, P, (0.3, -0.4), 4e-3, MU, f_start=7.0)
    direct = oracle_normal_force(uniform(7.0), P, (0.3, -0.4), 4e-3, MU)
    assert r.iterations <= 2
    assert r.f_n_min == pytest.approx(direct.f_n_min, rel=1e-9)


def test_hertzian_fingertip_pure_torque_matches_analytic_law():
    # Hertz: radius a = a_ref (f/f_ref)^(1/3), τ_max = (3π/16) μ f a  =>
    # f* = (τ f_ref^(1/3) / ((3π/16) μ a_ref))^(3/4).  Fine pad so sampling error is small.
    fine = PadGeometry(rows=80, cols=80, pitch_m=0.25e-3)
    a_ref, f_ref, tau = 5e-3, 5.0, 0.01
    r2 = np.sum(fine.positions**2, axis=1)

    def hertz(f: float) -> np.ndarray:
        a = a_ref * (f / f_ref) ** (1.0 / 3.0)
        w = np.sqrt(np.clip(1.0 - r2 / (a * a), 0.0, None))
        return f * w / w.sum()

    c = 3.0 * math.pi / 16.0
    expected = (tau * f_ref ** (1.0 / 3.0) / (c * MU * a_ref)) ** 0.75  # ≈ 9.5 N
    r = least_holding_force(hertz, fine.positions, (0.0, 0.0), tau, MU, f_start=2.0, rtol=1e-9)
    assert r.usable and r.iterations < 30
    assert r.f_n_min == pytest.approx(expected, rel=0.01)
    # γ = 1 exactly at the fixed point (independent evaluation) ...
    assert load_factor(hertz(r.f_n_min), fine.positions, (0.0, 0.0), tau, MU).gamma == pytest.approx(1.0, abs=1e-8)
    # ... while the frozen-shape estimate γ·f at twice the force under-predicts (bigger contact).
    frozen = oracle_normal_force(hertz(2 * r.f_n_min), fine.positions, (0.0, 0.0), tau, MU)
    assert frozen.f_n_min == pytest.approx(r.f_n_min * 2 ** (-1 / 3), rel=0.01)


def test_shape_that_jumps_gives_the_least_holding_force_at_the_jump():
    # Below 1 N the contact is the central 2x2 taxels, from 1 N on the central 8x8.
    # Pure torque τ: the small contact needs τ/(μ r_small) > 1 N, the large one
    # τ/(μ r_large) < 1 N, so the least holding force is the jump, 1 N; the plain
    # iteration γ·f would jump between the two shapes for ever.
    r = np.hypot(P[:, 0], P[:, 1])
    rows, cols = np.divmod(np.arange(PAD.n_taxels), PAD.cols)
    small = (abs(rows - 7.5) < 1) & (abs(cols - 7.5) < 1)
    large = (abs(rows - 7.5) < 4) & (abs(cols - 7.5) < 4)
    r_small, r_large = r[small].mean(), r[large].mean()  # 0.88 mm, 3.6 mm
    tau = MU * 2e-3  # f* would be 2.3 N with the small contact, 0.56 N with the large

    def jumping(f: float) -> np.ndarray:
        mask = large if f >= 1.0 else small
        return f * mask / mask.sum()

    assert tau / (MU * r_small) > 1.0 > tau / (MU * r_large)
    res = least_holding_force(jumping, P, (0.0, 0.0), tau, MU, f_start=0.3, rtol=1e-9)
    assert res.usable
    assert res.f_n_min == pytest.approx(1.0, rel=1e-8)
    assert res.gamma <= 1.0
