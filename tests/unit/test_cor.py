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


def test_coincident_points_pool_weights_that_only_together_hold_the_median():
    # 0.6 + 0.6 at the origin against a pull of |(0.5, 0.5)| = 0.71: together (1.2) they
    # hold the median there, either alone (0.6) would not. Without pooling the solver
    # would leave the origin towards the other two points.
    pts = np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    res = geometric_median(pts, [0.6, 0.6, 0.5, 0.5])
    assert res.status is SolverStatus.ON_TAXEL and res.taxel in (0, 1)
    assert res.c == (0.0, 0.0)
    assert res.value == pytest.approx(1.0)
    ref = _reference_minimiser(pts, np.array([0.6, 0.6, 0.5, 0.5]), np.zeros(2))
    assert np.hypot(*ref) < 1e-6


def _objective(pts, a, b):
    return lambda c: float(a @ np.hypot(*(pts - c).T) - b @ c)


def _reference_minimiser(pts, a, b):
    """argmin Σ a_i|p_i − c| − b·c by Nelder–Mead from the best point and the centroid
    (independent of the Newton/Kuhn solver; exact enough to 1e-7 of the spread)."""
    from scipy.optimize import minimize

    F = _objective(pts, a, b)
    starts = [min(pts, key=F), a @ pts / a.sum()]  # the best point and the centroid
    best = min((minimize(F, s, method="Nelder-Mead", options={"xatol": 1e-12, "fatol": 1e-15, "maxiter": 20000})
                for s in starts), key=lambda r: r.fun)
    return best.x


def _weber_cases():
    rng = np.random.default_rng(17)
    for k in range(24):
        m = int(rng.integers(3, 12))
        pts = rng.normal(size=(m, 2)) * 10.0 ** rng.integers(-3, 1)
        a = rng.random(m) + 0.05
        if k % 3 == 0:
            a[rng.integers(m)] += a.sum()  # a dominant weight: the minimiser on a point
        b = rng.normal(size=2)
        b *= rng.random() * 0.9 * a.sum() / np.hypot(*b)  # |b| < Σa: bounded
        if k % 4 == 1:
            b[:] = 0.0  # the plain geometric median
        yield pts, a, b


@pytest.mark.parametrize("warm", [False, True])
def test_weber_solver_matches_an_independent_minimisation(warm):
    for pts, a, b in _weber_cases():
        ref = _reference_minimiser(pts, a, b)
        F = _objective(pts, a, b)
        spread = np.sqrt(a @ np.sum((pts - a @ pts / a.sum()) ** 2, axis=1) / a.sum())
        c0 = ref + spread * np.array([0.3, -0.2]) if warm else None
        res = solve_weber(pts, a, b, c0)
        assert res.converged and res.status in (SolverStatus.CONVERGED, SolverStatus.ON_TAXEL), res
        assert np.hypot(*(np.array(res.c) - ref)) < 1e-6 * spread, (res, ref)
        assert res.value == pytest.approx(F(np.array(res.c)), rel=1e-12, abs=1e-12 * spread * a.sum())
        assert res.value <= F(ref) + 1e-12 * spread * a.sum()  # at least as low as the reference
        assert 0.0 <= res.residual <= 1e-3
        if res.status is SolverStatus.ON_TAXEL:
            assert res.c == tuple(pts[res.taxel])
            # Kuhn: the pull of the others and b is no stronger than the weight on the point
            d = pts[res.taxel] - np.delete(pts, res.taxel, axis=0)
            pull = (np.delete(a, res.taxel)[:, None] * d / np.hypot(*d.T)[:, None]).sum(axis=0) - b
            assert np.hypot(*pull) <= a[res.taxel] * (1 + 1e-12)
        else:
            assert res.taxel == -1 and res.iterations >= 1
            assert np.hypot(*(np.array(res.c)[None] - pts).T).min() > 1e-9 * spread


def test_weber_solver_bounds_and_degenerate_inputs():
    pts = np.array([[0.0, 0.0], [2.0, 0.0], [0.0, 2.0]])
    a = np.array([1.0, 2.0, 1.0])
    # |b| >= Σa: unbounded along b
    for b in ((4.0, 0.0), (0.0, -4.0), (3.0, 3.0)):
        res = solve_weber(pts, a, b)
        assert res.status is SolverStatus.TRANSLATION and res.c is None and res.value == -np.inf
        assert res.converged  # an unbounded problem is a certified answer too
    near = solve_weber(pts, a, (3.99, 0.0))
    assert near.status.usable and near.c is not None and np.isfinite(near.value)
    # one point, or all points coincident: that point, F = −b·p
    one = solve_weber(pts[1:2], [3.0], (1.0, 0.5))
    assert one.status is SolverStatus.ON_TAXEL and one.c == (2.0, 0.0) and one.taxel == 0
    assert one.value == pytest.approx(-2.0)
    same = solve_weber(np.array([[1.0, 3.0], [1.0, 3.0]]), [1.0, 1.0], (0.5, -0.25))
    assert same.status is SolverStatus.ON_TAXEL and same.c == (1.0, 3.0) and same.value == pytest.approx(0.25)
    # zero-weight points do not count, and the taxel index refers to the given points
    zero = solve_weber(np.vstack([pts, [[50.0, 50.0]]]), [1.0, 10.0, 1.0, 0.0])
    assert zero.status is SolverStatus.ON_TAXEL and zero.taxel == 1 and zero.c == (2.0, 0.0)
    # bad input: explicit status, never an exception
    bad = [
        solve_weber(pts, [1.0, -1.0, 1.0]),
        solve_weber(pts, [1.0, np.inf, 1.0]),
        solve_weber(np.array([[0.0, 0.0], [np.nan, 0.0], [1.0, 1.0]]), a),
        solve_weber(pts, a, (np.nan, 0.0)),
        solve_weber(pts, a, (0.0, np.inf)),
        solve_weber(pts, a[:2]),
        solve_weber(pts[:, :1], a),
        solve_weber(pts, a, (1.0, 2.0, 3.0)),
    ]
    for res in bad:
        assert res.status is SolverStatus.INVALID_INPUT and res.c is None and not res.converged
        assert np.isnan(res.value) and (res.taxel, res.iterations, res.residual) == (-1, 0, np.inf)
    none = solve_weber(pts, np.zeros(3))
    assert none.status is SolverStatus.NO_CONTACT and none.c is None and none.value == 0.0
    assert (none.taxel, none.iterations, none.residual) == (-1, 0, 0.0)
    unbounded = solve_weber(pts, a, (4.0, 0.0))
    assert (unbounded.taxel, unbounded.iterations, unbounded.residual) == (-1, 0, 0.0)
    assert (one.iterations, one.residual) == (0, 0.0)
    # an unusable warm start is ignored
    cold = solve_weber(pts, a, (0.5, 0.2))
    for c0 in ((np.nan, 0.0), (0.0, np.inf)):
        assert solve_weber(pts, a, (0.5, 0.2), c0).c == pytest.approx(cold.c, abs=1e-12)


def test_collinear_points_need_the_regularised_newton_step():
    # On the line through collinear points the Hessian is singular along it.
    line = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [4.0, 0.0]])
    pts = line
    a = np.ones(4)
    for flip in (False, True):  # along x, then the same points along y (b's components swapped)
        P = line[:, ::-1] if flip else line
        for b in ((0.0, 0.0), (0.0, 1.0), (0.5, 0.0), (0.3, 2.0), (-0.2, -1.5)):
            b = np.array(b[::-1] if flip else b)
            res = solve_weber(P, a, b)
            F = _objective(P, a, b)
            ref = _reference_minimiser(P, a, b)
            assert res.converged and res.status.usable, res
            assert res.value == pytest.approx(F(ref), rel=1e-9, abs=1e-12)
            if b[0 if flip else 1] != 0.0:  # pulled off the line: a unique smooth minimiser
                assert np.array(res.c) == pytest.approx(ref, abs=1e-6)
    # b = 0: any point between the middle two is a median; the solver returns one of them
    c = solve_weber(pts, a, (0.0, 0.0)).c
    assert 1.0 <= c[0] <= 2.0 and c[1] == 0.0


@pytest.mark.parametrize("centre", [(0.0, 0.0), (2e-3, -1e-3)])
def test_newton_converges_in_a_few_steps_on_smooth_contacts(centre):
    # The solvers are Newton methods (quadratic convergence): a handful of steps from a
    # cold start on a smooth pressure. A slower (e.g. linearly convergent) variant would
    # still find the answer, but not at sensor rate.
    x, y = PAD.positions.T
    phi = np.sqrt(np.clip(1 - ((x - centre[0]) ** 2 + (y - centre[1]) ** 2) / 5e-3**2, 0, None))
    med = geometric_median(PAD.positions, phi)
    assert med.status is SolverStatus.CONVERGED and med.iterations <= 4 and med.residual < 1e-8
    for f_t, tau in (((0.2, 0.1), 1e-3), ((0.0, 0.3), -2e-3), ((0.5, 0.0), 1e-4), ((0.05, 0.02), 3e-3)):
        res = load_factor(phi, PAD.positions, f_t, tau, MU)
        assert res.status is SolverStatus.CONVERGED and res.iterations <= 6 and res.residual < 1e-8, res


def test_weber_solver_out_of_steps_says_so():
    # A smooth minimiser far from the start: one Newton step cannot reach it.
    x, y = PAD.positions.T
    phi = _hertz()
    full = solve_weber(PAD.positions, phi, (0.2 * phi.sum(), 0.1 * phi.sum()))
    assert full.status is SolverStatus.CONVERGED
    short = solve_weber(PAD.positions, phi, (0.2 * phi.sum(), 0.1 * phi.sum()), c0=(-9e-3, 9e-3), max_iter=1)
    assert short.status is SolverStatus.MAX_ITER and not short.converged
    assert short.c is not None and short.iterations == 1 and 1e-3 < short.residual < np.inf  # |grad F| there


def test_weber_warm_start_at_the_answer_off_centre_takes_one_step():
    x, y = PAD.positions.T
    phi = np.sqrt(np.clip(1 - ((x - 2e-3) ** 2 + (y + 3e-3) ** 2) / 5e-3**2, 0, None))
    b = (0.2 * phi.sum(), 0.1 * phi.sum())
    cold = solve_weber(PAD.positions, phi, b)
    warm = solve_weber(PAD.positions, phi, b, c0=cold.c)
    assert cold.status is warm.status is SolverStatus.CONVERGED
    assert warm.iterations == 1 < cold.iterations
    assert warm.c == pytest.approx(cold.c, abs=1e-12)


def test_stop_rule_by_hand():
    # Converged when the step is below xtol·(1 + |c|), or below 1e-3 with the predicted
    # next step (quadratic convergence) step³/prev² below that bound.
    from slipstack.lib.weber import step_converged

    assert step_converged(5e-8, 1e-30, 3.0, 4.0, 1e-8)          # 5e-8 <= 1e-8·(1 + 5)
    assert not step_converged(7e-8, 1e-30, 3.0, 4.0, 1e-8)      # above it, no usable prediction
    assert step_converged(1e-4, 0.5, 0.0, 0.0, 1e-8)            # predicted 4e-12
    assert step_converged(4.6e-5, 0.01, 0.0, 0.0, 1e-8)         # predicted 9.7e-10 (prev² not prev³)
    assert not step_converged(1e-4, 1e-4, 0.0, 0.0, 1e-8)       # predicted 1e-4: not yet
    assert not step_converged(2e-3, 1.0, 0.0, 0.0, 1e-8)        # predicted 8e-9, but the step is > 1e-3
    assert not step_converged(1e-4, 0.0, 0.0, 0.0, 1e-8)        # no previous step
    assert step_converged(1e-3, 1e3, 0.0, 0.0, 1e-8)            # exactly 1e-3 counts


def test_solve_weber_without_b_is_the_geometric_median():
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    assert solve_weber(pts, np.ones(3)).c == pytest.approx(geometric_median(pts, np.ones(3)).c, abs=1e-12)
    assert solve_weber(pts, np.ones(3)).c[0] == pytest.approx(0.2113248654, abs=1e-9)  # Fermat point: (3 − √3)/6


def test_far_warm_starts_are_pulled_in_by_the_line_search_within_a_few_steps():
    # From 100-1000 contact radii away the Newton step overshoots; the backtracking line
    # search must keep each step a descent so the iteration is back within a few steps.
    x, y = PAD.positions.T
    phi = np.sqrt(np.clip(1 - ((x - 2e-3) ** 2 + (y + 3e-3) ** 2) / 5e-3**2, 0, None))
    for b in ((0.0, 0.0), (0.2 * phi.sum(), 0.1 * phi.sum()), (-0.5 * phi.sum(), 0.3 * phi.sum())):
        cold = solve_weber(PAD.positions, phi, b)
        for c0 in ((1.0, 0.0), (-3e-2, 5e-2), (0.3, -0.4)):
            res = solve_weber(PAD.positions, phi, b, c0=c0)
            assert res.status is SolverStatus.CONVERGED and res.iterations <= 7, (b, c0, res)
            assert res.c == pytest.approx(cold.c, abs=1e-10)  # xtol 1e-9 of the 3 mm contact radius


_DENORMAL_PAD = np.zeros(PAD.n_taxels)
_DENORMAL_PAD[[r * PAD.cols + c for r in range(5, 11) for c in range(5, 11)]] = 5e-324  # 36 taxels, subnormal


@pytest.mark.parametrize("solve", [paper_cor, robust_cor])
@pytest.mark.parametrize("phi, f_t, tau", [
    (_DENORMAL_PAD, (0.0, 0.0), 1e-3),  # the paper's iteration said SINGULAR, ratio +inf: "slipping"
    (_DENORMAL_PAD, (0.2, 0.0), 1e-3),  # both said TRANSLATION, ratio +inf
    (_DENORMAL_PAD, (0.0, 0.0), 1e-320),  # a load as small: a ratio of numbers with a digit or two
    (np.where(_DENORMAL_PAD > 0, 1e307, 0.0), (0.2, 0.0), 1e-3),  # Σφ overflows: robust said stick at γ 2e-309
])
def test_a_pad_without_a_measurable_force_or_beyond_float_range_is_refused_as_invalid(solve, phi, f_t, tau):
    """Pressures whose friction capacity μΣφ is subnormal (no force a sensor measures; the ratio
    is rounding noise or overflows to +inf, a "slip" verdict) or overflows (every ratio 0, a
    "stick" one) are refused as bad input, as the slip tests refuse a μ f_n that underflows."""
    res = solve(phi, PAD.positions, f_t, tau, MU)
    assert res.status is SolverStatus.INVALID_INPUT and res.case is SlipCase.NONE and res.p_c is None
    assert res.ratio == 0.0
