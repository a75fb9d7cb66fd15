"""COR of (12) and test (11): the paper's iteration vs the robust Weber solver."""

from __future__ import annotations

import numpy as np
import pytest

from slipstack.lib.cor import cor_equations, paper_cor, robust_cor
from slipstack.lib.limit_set import load_factor
from slipstack.lib.pad import PadGeometry
from slipstack.lib.status import SlipCase, SolverStatus
from slipstack.lib.weber import geometric_median, solve_weber

MU = 0.5
PAD = PadGeometry()


def _hertz(radius=7e-3):
    x, y = PAD.positions.T
    return np.sqrt(np.clip(1 - (x**2 + y**2) / radius**2, 0, None))


def test_paper_and_robust_solvers_agree_on_a_smooth_cor():
    phi = _hertz()
    paper = paper_cor(phi, PAD.positions, (0.2, 0.1), 1e-3, MU)
    robust = robust_cor(phi, PAD.positions, (0.2, 0.1), 1e-3, MU)
    assert paper.status is SolverStatus.CONVERGED and robust.status is SolverStatus.CONVERGED
    assert paper.p_c == pytest.approx(robust.p_c, abs=1e-9)
    F, _ = cor_equations(np.array(robust.p_c), phi[phi > 0], PAD.positions[phi > 0], np.array([0.2, 0.1]), MU)
    assert np.hypot(*F) < 1e-9 * MU * phi.sum()
    assert paper.ratio == pytest.approx(robust.ratio, rel=1e-6)  # paper stops at 1e-7 L
    assert paper.iterations > robust.iterations


def test_robust_solver_takes_the_binding_sense_the_paper_omits():
    phi = _hertz()
    robust = robust_cor(phi, PAD.positions, (0.0, 0.3), -2e-3, MU)
    paper = paper_cor(phi, PAD.positions, (0.0, 0.3), -2e-3, MU)
    assert robust.sense == -1 and paper.sense == 1
    assert robust.ratio > paper.ratio


def test_cor_on_a_taxel_robust_certifies_it_and_paper_reports_failure():
    pad = PadGeometry(8, 8, 1.25e-3)
    phi = np.ones(64)
    phi[18] = 80.0
    robust = robust_cor(phi, pad.positions, (0.05, 0.0), 2e-3, MU)
    assert robust.status is SolverStatus.ON_TAXEL and robust.p_c == tuple(pad.positions[18])
    paper = paper_cor(phi, pad.positions, (0.05, 0.0), 2e-3, MU)
    assert paper.status in (SolverStatus.MAX_ITER, SolverStatus.SINGULAR, SolverStatus.DIVERGED)
    assert not paper.status.usable


def test_translation_when_the_force_exceeds_coulomb():
    phi = _hertz()
    f = 1.01 * MU * phi.sum()
    for solver in (paper_cor, robust_cor):
        res = solver(phi, PAD.positions, (f, 0.0), 0.0, MU)
        assert res.case is SlipCase.TRANSLATION and res.ratio == pytest.approx(1.01) and not res.stick


@pytest.mark.parametrize("scale", [0.9, 1.1])
def test_test_11_at_the_robust_cor_is_the_exact_test(scale):
    rng = np.random.default_rng(11)
    pad = PadGeometry(8, 8, 1.25e-3)
    for _ in range(30):
        phi = rng.random(64) * (rng.random(64) < 0.7)
        f_t, tau = rng.normal(size=2) * 0.2, rng.normal() * 1e-3
        g = load_factor(phi, pad.positions, f_t, tau, MU).gamma
        res = robust_cor(phi, pad.positions, f_t * scale / g, tau * scale / g, MU)
        assert res.stick is (scale < 1)


def test_weber_solver_basics():
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    # equal weights: the Fermat point of the triangle (angles < 120°)
    res = geometric_median(pts, np.ones(3))
    d = pts - np.array(res.c)
    u = d / np.linalg.norm(d, axis=1)[:, None]
    assert np.linalg.norm(u.sum(axis=0)) < 1e-9  # unit vectors sum to zero
    # a dominant weight pins the median on its point (Kuhn)
    assert solve_weber(pts, [5.0, 1.0, 1.0]).status is SolverStatus.ON_TAXEL
    assert solve_weber(pts, [1.0, 1.0, 1.0], (3.0, 0.0)).status is SolverStatus.TRANSLATION
    assert solve_weber(pts, [0.0, 0.0, 0.0]).status is SolverStatus.NO_CONTACT
    assert solve_weber(pts, [np.nan, 1.0, 1.0]).status is SolverStatus.INVALID_INPUT
    # scale invariance: metres vs micrometres, newtons vs kilonewtons
    a = solve_weber(pts, [1.0, 2.0, 3.0], (0.5, 0.2))
    b = solve_weber(pts * 1e-6, [1e3, 2e3, 3e3], (0.5e3, 0.2e3))
    assert np.array(b.c) == pytest.approx(np.array(a.c) * 1e-6, rel=1e-9)


def test_coincident_points_pool_their_weight_in_the_kuhn_test():
    # Two taxels at the origin carry 2 of the 3 units of weight: the pull of the other
    # two (|(1,0)·0.5 + (0,1)·0.5| ≈ 0.71) cannot move the median off the origin.
    pts = np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    res = geometric_median(pts, [1.0, 1.0, 0.5, 0.5])
    assert res.status is SolverStatus.ON_TAXEL
    assert res.taxel in (0, 1)
    assert res.c == (0.0, 0.0)
    assert res.value == pytest.approx(1.0)
