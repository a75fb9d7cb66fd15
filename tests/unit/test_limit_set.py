"""Exact limit set: analytic values (docs/math.md §4.3), special cases (§4.4), brute-force cross-check."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import config as numba_config
from scipy.optimize import minimize

from slipstack.lib.limit_set import load_factor, torsional_coefficient
from slipstack.lib.pad import PadGeometry
from slipstack.lib.status import SlipCase, SolverStatus

MU = 0.5


def brute_force_gamma(phi, positions, f_t, tau, mu, n_dir=1500):
    """γ = max_ξ w·ξ/D(ξ) by dense sampling of twist directions + Nelder–Mead refinement.

    Independent of the solver: it never uses the COR parametrisation. ξ = (v_x, v_y, ω·L)
    with L the pad's RMS taxel radius so that the three components are commensurate.
    """
    P = np.asarray(positions, dtype=float)
    phi = np.asarray(phi, dtype=float)
    L = math.sqrt(float(np.mean(np.sum(P**2, axis=1))))
    w = np.array([f_t[0], f_t[1], tau / L])
    perp = np.stack([-P[:, 1], P[:, 0]], axis=1) / L  # perp(p)/L, (m, 2)

    def ratios(X):
        U = X[:, None, :2] + X[:, None, 2:3] * perp[None]
        return (X @ w) / (mu * np.hypot(U[..., 0], U[..., 1]) @ phi)

    k = np.arange(n_dir) + 0.5
    z = 1 - 2 * k / n_dir
    th = math.pi * (1 + 5**0.5) * k
    X = np.stack([np.sqrt(1 - z * z) * np.cos(th), np.sqrt(1 - z * z) * np.sin(th), z], axis=1)
    vals = ratios(X)
    best = X[int(np.argmax(vals))]
    res = minimize(lambda x: -ratios((x / np.linalg.norm(x))[None])[0], best, method="Nelder-Mead",
                   options={"xatol": 1e-11, "fatol": 1e-15, "maxiter": 5000})
    return max(-float(res.fun), float(vals.max()))


def _disc_pad():
    pad = PadGeometry(128, 128, 0.1e-3)
    x, y = pad.positions.T
    return pad.positions, np.hypot(x, y)


@pytest.mark.parametrize(
    "profile, coefficient",
    [
        (lambda r, R: (r < R).astype(float), 2.0 / 3.0),
        (lambda r, R: np.sqrt(np.clip(1 - r**2 / R**2, 0, None)), 3 * math.pi / 16),
    ],
    ids=["uniform", "hertz"],
)
def test_pure_torque_capacity_of_a_disc_matches_the_analytic_value(profile, coefficient):
    P, r = _disc_pad()
    R, f_n = 5e-3, 3.0
    phi = profile(r, R)
    phi *= f_n / phi.sum()
    expected = coefficient * MU * f_n * R
    beta = torsional_coefficient(phi, P, MU)
    assert beta.beta_m * f_n == pytest.approx(expected, rel=0.01)
    tau = 0.8 * expected
    res = load_factor(phi, P, (0.0, 0.0), tau, MU)
    assert res.status is SolverStatus.CONVERGED
    assert res.gamma == pytest.approx(0.8, rel=0.01)
    assert np.hypot(*res.p_c) < 1e-9  # symmetric: the median is the centre


def test_geometric_median_example_of_math_md():
    """12×12 contact, pressure ∝ distance from the contact's left edge (x = −7.5 mm)."""
    pad = PadGeometry()
    x, y = pad.positions.T
    inside = (np.abs(x) < 7.5e-3) & (np.abs(y) < 7.5e-3)
    phi = np.where(inside, x + 7.5e-3, 0.0)
    assert inside.sum() == 144
    assert phi @ x / phi.sum() == pytest.approx(2.4826e-3, abs=1e-7)  # 143/72·h
    tor = torsional_coefficient(phi, pad.positions, MU)
    assert tor.status is SolverStatus.CONVERGED
    assert tor.median[0] == pytest.approx(2.8562e-3, abs=1e-7)
    assert abs(tor.median[1]) < 1e-12
    res = load_factor(phi, pad.positions, (0.0, 0.0), 1e-3, MU)
    assert res.p_c == pytest.approx(tor.median, abs=1e-10)


def test_point_contact_has_no_torsional_capacity():
    pad = PadGeometry(8, 8, 1.25e-3)
    phi = np.zeros(64)
    phi[27] = 2.0
    p = pad.positions[27]
    res = load_factor(phi, pad.positions, (0.0, 0.0), 1e-9, MU)
    assert res.status is SolverStatus.POINT_CONTACT and res.gamma == math.inf and res.p_c == tuple(p)
    # a force through the taxel with no torque about it: a translation, γ = |f_t|/(μ f_n)
    f_t = np.array([0.3, 0.4])
    tau = -(f_t[0] * p[1] - f_t[1] * p[0])
    res = load_factor(phi, pad.positions, f_t, tau, MU)
    assert res.status is SolverStatus.TRANSLATION and res.gamma == pytest.approx(0.5)
    assert torsional_coefficient(phi, pad.positions, MU).beta_m == 0.0


def test_no_load_no_contact_and_invalid_input_are_explicit():
    pad = PadGeometry(4, 4, 1e-3)
    phi = np.ones(16)
    nl = load_factor(phi, pad.positions, (0.0, 0.0), 0.0, MU)
    assert nl.status is SolverStatus.NO_LOAD and nl.gamma == 0.0 and nl.margin == 1.0
    nc = load_factor(np.zeros(16), pad.positions, (1.0, 0.0), 0.0, MU)
    assert nc.status is SolverStatus.NO_CONTACT and nc.case is SlipCase.NONE
    bad = phi.copy()
    bad[3] = np.nan
    assert load_factor(bad, pad.positions, (1.0, 0.0), 0.0, MU).status is SolverStatus.INVALID_INPUT
    assert load_factor(phi, pad.positions, (np.inf, 0.0), 0.0, MU).status is SolverStatus.INVALID_INPUT
    assert load_factor(phi, pad.positions, (1.0, 0.0), 0.0, -1.0).status is SolverStatus.INVALID_INPUT


def test_force_through_the_centre_of_pressure_is_a_translation():
    pad = PadGeometry(8, 8, 1.25e-3)
    rng = np.random.default_rng(3)
    phi = rng.random(64)
    cop = phi @ pad.positions / phi.sum()
    f_t = np.array([0.7, -0.2])
    tau = -(f_t[0] * cop[1] - f_t[1] * cop[0])  # n(cop) = 0
    res = load_factor(phi, pad.positions, f_t, tau, MU)
    assert res.case is SlipCase.TRANSLATION and res.p_c is None
    assert res.gamma == pytest.approx(np.hypot(*f_t) / (MU * phi.sum()), rel=1e-12)


def test_near_translation_is_continuous_across_the_asymptotic_switch():
    pad = PadGeometry(8, 8, 1.25e-3)
    rng = np.random.default_rng(4)
    phi = rng.random(64)
    cop = phi @ pad.positions / phi.sum()
    f_t = np.array([0.7, -0.2])
    tau0 = -(f_t[0] * cop[1] - f_t[1] * cop[0])
    gammas = []
    for lever in (1e-9, 3e-8, 1e-7, 1e-6):  # metres of lever arm about the centre of pressure
        res = load_factor(phi, pad.positions, f_t, tau0 + lever * np.hypot(*f_t), MU)
        assert math.isfinite(res.gamma) and res.status.usable
        gammas.append(res.gamma)
        if res.p_c is not None:
            assert np.all(np.isfinite(res.p_c))
    gt = np.hypot(*f_t) / (MU * phi.sum())
    assert all(g >= gt * (1 - 1e-14) for g in gammas)
    assert gammas == sorted(gammas)
    assert gammas[-1] / gt - 1 < 1e-6


def test_cor_on_a_taxel_is_certified():
    pad = PadGeometry(8, 8, 1.25e-3)
    phi = np.ones(64)
    phi[18] = 80.0  # geometric median pinned on taxel 18
    res = load_factor(phi, pad.positions, (0.0, 0.0), 2e-3, MU)
    assert res.case is SlipCase.ON_TAXEL and res.taxel == 18
    res = load_factor(phi, pad.positions, (0.05, 0.0), 2e-3, MU)
    assert res.status is SolverStatus.ON_TAXEL and res.taxel == 18
    assert res.gamma == pytest.approx(brute_force_gamma(phi, pad.positions, (0.05, 0.0), 2e-3, MU), rel=1e-6)


def test_warm_start_gives_the_same_answer_in_fewer_iterations():
    pad = PadGeometry()
    x, y = pad.positions.T
    phi = np.clip(1 - (x**2 + y**2) / 7e-3**2, 0, None)
    cold = load_factor(phi, pad.positions, (0.2, 0.1), 1e-3, MU)
    warm = load_factor(phi, pad.positions, (0.2, 0.1), 1e-3, MU, c0=cold.p_c)
    assert warm.gamma == pytest.approx(cold.gamma, rel=1e-13)
    assert warm.p_c == pytest.approx(cold.p_c, abs=1e-12)
    assert warm.iterations < cold.iterations
    garbage = load_factor(phi, pad.positions, (0.2, 0.1), 1e-3, MU, c0=(np.nan, 1.0))
    assert garbage.gamma == pytest.approx(cold.gamma, rel=1e-13)


def _random_case(rng, pad):
    kind = rng.integers(4)
    m = pad.n_taxels
    if kind == 0:
        phi = rng.random(m)
    elif kind == 1:
        phi = rng.random(m) * (rng.random(m) < 0.3)
        phi[rng.integers(m)] += 1.0
    elif kind == 2:
        phi = np.zeros(m)
        phi[rng.choice(m, 2, replace=False)] = rng.random(2) + 0.1  # two taxels
    else:
        phi = np.exp(3 * rng.normal(size=m))  # very uneven
    f_t = rng.normal(size=2) * rng.choice([0.0, 1e-3, 1.0], p=[0.1, 0.2, 0.7])
    tau = rng.normal() * 2e-3 * rng.choice([0.0, 1.0], p=[0.1, 0.9])
    if f_t[0] == 0 and tau == 0:
        tau = 1e-3
    return phi, f_t, tau


def test_gamma_matches_brute_force_on_200_random_fields_including_the_boundary():
    pad = PadGeometry(6, 6, 2.5e-3)
    rng = np.random.default_rng(2000)
    worst = 0.0
    for k in range(200):
        phi, f_t, tau = _random_case(rng, pad)
        res = load_factor(phi, pad.positions, f_t, tau, MU)
        if k % 4 == 1:  # scale the load onto the boundary or just off it
            s = [1.0, 1 - 1e-3, 1 + 1e-3][k % 3] / res.gamma
            f_t, tau = f_t * s, tau * s
            res = load_factor(phi, pad.positions, f_t, tau, MU)
        ref = brute_force_gamma(phi, pad.positions, f_t, tau, MU)
        assert res.status.usable, res
        err = abs(res.gamma - ref) / ref
        worst = max(worst, err)
        assert err < 1e-6, (k, res, ref)
    assert worst < 1e-6


def test_a_force_below_rounding_beside_the_torque_gets_the_unique_pure_torque_cor():
    # Found by hypothesis: two equal taxels under a torque and f_t = 1e-70 N. s·n/T is
    # flat along the segment between them, so the COR was wherever the iteration
    # stopped, and moved when the field was translated by one taxel.
    pts = np.array([[0.0, 0.0], [2.5e-3, 1.25e-3]])
    for f_y in (0.0, 1.28e-70):
        r = load_factor(np.ones(2), pts, (0.0, f_y), 3.9e-3, 0.5)
        assert r.status is SolverStatus.CONVERGED
        assert r.p_c == pytest.approx((1.25e-3, 0.625e-3), abs=1e-15)  # the midpoint
        assert r.gamma == pytest.approx(3.9e-3 / (0.5 * np.hypot(2.5e-3, 1.25e-3)), rel=1e-12)


def test_every_reported_field_agrees_with_sums_computed_at_the_reported_cor():
    # Beside γ (brute force above): the COR, capacity, load torque, sense, centre of
    # pressure and contact radius recomputed here with numpy from their definitions.
    pad = PadGeometry(6, 6, 2.5e-3)
    P = pad.positions
    rng = np.random.default_rng(77)
    seen = set()
    for k in range(60):
        phi, f_t, tau = _random_case(rng, pad)
        warm = None if k % 2 else P[int(np.argmax(phi))] + 1e-4
        res = load_factor(phi, P, f_t, tau, MU, c0=warm)
        f_n = phi.sum()
        cop = phi @ P / f_n
        assert res.cop == pytest.approx(tuple(cop), abs=1e-15)
        radius = math.sqrt(phi @ np.sum((P - cop) ** 2, axis=1) / f_n)
        assert res.contact_radius_m == pytest.approx(radius, rel=1e-12) or np.count_nonzero(phi) == 1
        assert res.margin == 1.0 - res.gamma
        seen.add(res.status)
        if res.p_c is None:
            assert res.status in (SolverStatus.TRANSLATION, SolverStatus.NO_LOAD)
            assert res.gamma == pytest.approx(np.hypot(*f_t) / (MU * f_n), rel=1e-9)
            assert res.sense == 0 and res.taxel == -1
            continue
        assert res.converged and res.status.usable, res
        c = np.array(res.p_c)
        T = MU * phi @ np.hypot(*(P - c).T)
        n = tau + f_t[0] * c[1] - f_t[1] * c[0]
        assert res.torque_capacity == pytest.approx(T, rel=1e-12)
        assert res.load_torque == pytest.approx(n, rel=1e-9, abs=1e-12 * abs(tau) + 1e-18)
        assert res.sense == (1 if n > 0 else -1)
        if res.status is SolverStatus.POINT_CONTACT:
            assert res.gamma == math.inf
            continue
        assert res.gamma == pytest.approx(max(abs(n) / T, np.hypot(*f_t) / (MU * f_n)), rel=1e-12)
        if res.case is SlipCase.ON_TAXEL:
            assert res.p_c == pytest.approx(tuple(P[res.taxel]), abs=1e-15) and phi[res.taxel] > 0
        else:
            assert res.taxel == -1 and res.case is SlipCase.ROTATION and res.iterations >= 1
        assert 0.0 <= res.residual <= 1e-3
    assert {SolverStatus.CONVERGED, SolverStatus.ON_TAXEL} <= seen


def test_gamma_is_the_same_for_a_load_and_its_opposite_and_grows_linearly_with_it():
    # The limit set is centrally symmetric (the friction cone is): −w has the same γ and
    # the opposite sense; γ is homogeneous of degree 1 in the load, 0 in the pressure scale.
    pad = PadGeometry(6, 6, 2.5e-3)
    rng = np.random.default_rng(5)
    for _ in range(20):
        phi, f_t, tau = _random_case(rng, pad)
        a = load_factor(phi, pad.positions, f_t, tau, MU)
        b = load_factor(phi, pad.positions, -f_t, -tau, MU)
        c = load_factor(3.0 * phi, pad.positions, 2.0 * f_t, 2.0 * tau, MU)
        assert b.gamma == pytest.approx(a.gamma, rel=1e-9) and b.sense == -a.sense
        assert c.gamma == pytest.approx(2.0 / 3.0 * a.gamma, rel=1e-9)


def test_bad_shapes_and_friction_are_invalid_input_not_exceptions():
    pad = PadGeometry(4, 4, 1e-3)
    phi = np.ones(16)
    bad = [
        load_factor(phi.reshape(4, 4), pad.positions, (1.0, 0.0), 0.0, MU),      # phi not 1-D
        load_factor(phi[:15], pad.positions, (1.0, 0.0), 0.0, MU),               # one taxel short
        load_factor(phi, pad.positions[:, :1], (1.0, 0.0), 0.0, MU),             # positions not (N, 2)
        load_factor(phi, pad.positions, (1.0, 0.0, 0.0), 0.0, MU),               # f_t not (2,)
        load_factor(phi, pad.positions, (1.0, 0.0), np.nan, MU),
        load_factor(phi, pad.positions, (1.0, 0.0), 0.0, 0.0),                  # mu must be > 0
        load_factor(phi, pad.positions, (1.0, 0.0), 0.0, np.inf),
    ]
    for res in bad:
        assert res.status is SolverStatus.INVALID_INPUT and res.case is SlipCase.NONE
        # the "nothing to say" result: every field at its neutral value
        assert (res.gamma, res.p_c, res.torque_capacity, res.load_torque, res.sense) == (0.0, None, 0.0, 0.0, 0)
        assert (res.iterations, res.residual, res.taxel, res.cop, res.contact_radius_m) == (0, 0.0, -1, (0.0, 0.0), 0.0)
        assert not res.converged and res.margin == 1.0
    assert load_factor(phi, pad.positions, (1.0, 0.0), 0.0, MU).converged


def test_contact_subset_keeps_the_positive_taxels_and_rejects_bad_input():
    from slipstack.lib.limit_set import contact_subset

    pad = PadGeometry(2, 2, 1e-3)
    idx, phi, pos = contact_subset(np.array([0.0, 2.0, 0.0, 1.0]), pad.positions)
    assert idx.tolist() == [1, 3] and phi.tolist() == [2.0, 1.0]
    assert np.array_equal(pos, pad.positions[[1, 3]])
    assert contact_subset(np.ones((2, 2)), pad.positions) is None                  # not 1-D
    assert contact_subset(np.ones(4), pad.positions[:3]) is None                   # count mismatch
    assert contact_subset(np.ones(4), pad.positions[:, :1]) is None
    assert contact_subset(np.array([1.0, np.nan, 1.0, 1.0]), pad.positions) is None
    assert contact_subset(np.array([1.0, -1e-9, 1.0, 1.0]), pad.positions) is None


def test_coincident_taxels_are_a_point_contact_and_loads_beyond_float_range_invalid():
    # Two taxels at one place (e.g. after pooling): no torsional capacity about that place.
    pts = np.array([[1e-3, 2e-3], [1e-3, 2e-3]])
    res = load_factor(np.array([1.0, 2.0]), pts, (0.0, 0.0), 1e-4, MU)
    assert res.status is SolverStatus.POINT_CONTACT and res.gamma == math.inf and res.sense == 1
    assert res.p_c == (1e-3, 2e-3)
    res = load_factor(np.array([1.0, 2.0]), pts, (0.3, 0.0), -0.3 * 2e-3, MU)  # line of action through it
    assert res.status is SolverStatus.TRANSLATION and res.gamma == pytest.approx(0.3 / (MU * 3.0))
    # |f_t|/(μ f_n) beyond the float range: said, not computed as inf or NaN
    pad = PadGeometry(4, 4, 1e-3)
    huge = load_factor(np.full(16, 1e-300), pad.positions, (1e300, 1e300), 1e-3, MU)
    assert huge.status is SolverStatus.INVALID_INPUT
    # |f_t|/(μ f_n) overflows while the torque about the (exactly central) centre of pressure does not
    square = PadGeometry(2, 2, 1e-3).positions
    assert load_factor(np.full(4, 1e-300), square, (1e300, 0.0), 1e-3, MU).status is SolverStatus.INVALID_INPUT


@pytest.mark.parametrize("along", ["y", "x", "oblique"])
def test_near_translation_switch_sits_at_1e_5_of_the_spread_along_the_force(along):
    # A contact elongated along x, pushed along y with the line of action a lever arm
    # a = k·1e-5·σ off the centre of pressure (σ: RMS spread along f_t, computed here).
    # Below the switch (k < 1): TRANSLATION by the expansion γ = γ_t (1 + a²/(2σ²));
    # above: the Dinkelbach iteration, whose COR lies about σ²/a away. Both sides must
    # agree with the expansion to rounding, so the switch is continuous.
    pad = PadGeometry(8, 8, 1.25e-3)
    turn = {"y": 0.0, "x": math.pi / 2, "oblique": math.pi / 6}[along]  # the same contact turned
    R = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]])
    P = pad.positions @ R.T
    x, y = pad.positions.T
    phi = np.where(np.abs(y) < 2e-3, 1.0 + 0.3 * (x > 0), 0.0)
    f_n = phi.sum()
    cop = phi @ P / f_n
    f_t = 0.02 * np.array([-math.sin(turn + (0.4 if along == "oblique" else 0.0)),
                           math.cos(turn + (0.4 if along == "oblique" else 0.0))])
    sigma = math.sqrt(phi @ ((P - cop) @ (f_t / 0.02)) ** 2 / f_n)
    gamma_t = 0.02 / (MU * f_n)
    tau_through_cop = -(f_t[0] * cop[1] - f_t[1] * cop[0])
    for k in (0.5, 0.999, 1.001, 2.0):
        lever = k * 1e-5 * sigma
        res = load_factor(phi, P, f_t, tau_through_cop + lever * 0.02, MU)
        assert res.gamma / gamma_t - 1.0 == pytest.approx((lever / sigma) ** 2 / 2, rel=1e-4, abs=1e-15), k
        if k < 1:
            assert res.case is SlipCase.TRANSLATION and res.p_c is None, k
            assert (res.torque_capacity, res.load_torque, res.sense, res.iterations, res.residual) == (0, 0, 0, 0, 0)
            assert res.cop == pytest.approx(tuple(cop), abs=1e-15) and res.taxel == -1
        else:
            assert res.case is SlipCase.ROTATION and res.status is SolverStatus.CONVERGED, k
            assert res.iterations <= 8, res  # a start on the ray towards the far COR, then Newton
            assert np.hypot(*(np.array(res.p_c) - cop)) == pytest.approx(sigma**2 / lever, rel=1e-2)


def test_cor_on_the_first_taxel_in_contact_reports_index_0_and_odd_warm_starts_are_ignored():
    pad = PadGeometry(8, 8, 1.25e-3)
    phi = np.ones(64)
    phi[0] = 80.0  # the corner taxel pins the COR (Kuhn: the others pull with at most 63)
    for f_t in ((0.05, 0.0), (0.0, 0.0)):  # Dinkelbach, and the pure-torque median
        res = load_factor(phi, pad.positions, f_t, 2e-3, MU)
        assert res.case is SlipCase.ON_TAXEL and res.taxel == 0, res
        assert res.p_c == pytest.approx(tuple(pad.positions[0]), abs=1e-15)
    cold = load_factor(phi, pad.positions, (0.05, 0.02), 2e-3, MU)
    for c0 in ((1e-3, 2e-3, 3e-3), (np.nan, 0.0), (1e9, 0.0), ()):
        res = load_factor(phi, pad.positions, (0.05, 0.02), 2e-3, MU, c0=c0)
        assert res.gamma == pytest.approx(cold.gamma, rel=1e-12) and res.taxel == cold.taxel


def test_warm_start_at_the_answer_off_centre_takes_one_update_and_bad_ones_change_nothing():
    # An off-centre contact (the warm start is moved into the centred frame and back).
    pad = PadGeometry()
    x, y = pad.positions.T
    phi = np.sqrt(np.clip(1 - ((x - 2e-3) ** 2 + (y + 3e-3) ** 2) / 5e-3**2, 0, None))
    cold = load_factor(phi, pad.positions, (0.2, 0.1), 1e-3, MU)
    warm = load_factor(phi, pad.positions, (0.2, 0.1), 1e-3, MU, c0=cold.p_c)
    assert warm.iterations == 1 < cold.iterations
    assert warm.p_c == pytest.approx(cold.p_c, abs=1e-12)
    cop, p_c = np.array(cold.cop), np.array(cold.p_c)
    # the mirror image of the COR, the centre of pressure, far along and far against it:
    # starts whose ratio does not qualify, or barely, still end at the same γ
    for c0 in (2 * cop - p_c, cop, cop + 1e3 * (p_c - cop), cop - 1e3 * (p_c - cop)):
        res = load_factor(phi, pad.positions, (0.2, 0.1), 1e-3, MU, c0=c0)
        assert res.gamma == pytest.approx(cold.gamma, rel=1e-12)
        assert res.p_c == pytest.approx(cold.p_c, abs=1e-9)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_point_contact_in_both_senses_and_a_force_through_it(sign):
    pad = PadGeometry(8, 8, 1.25e-3)
    for taxel in (10, 29, 53):  # off the diagonals: x != ±y
        phi = np.zeros(64)
        phi[taxel] = 2.0
        p = pad.positions[taxel]
        f_t = sign * np.array([0.3, -0.7])
        through = -(f_t[0] * p[1] - f_t[1] * p[0])  # τ of a force whose line passes through p
        res = load_factor(phi, pad.positions, f_t, through, MU)
        assert res.status is SolverStatus.TRANSLATION and res.p_c is None, (taxel, res)
        assert res.gamma == pytest.approx(np.hypot(*f_t) / (MU * 2.0))
        assert (res.torque_capacity, res.load_torque, res.sense, res.iterations, res.residual) == (0, 0, 0, 0, 0)
        assert res.taxel == -1 and res.cop == tuple(p)
        twisted = load_factor(phi, pad.positions, f_t, through + sign * 1e-4, MU)
        assert twisted.status is SolverStatus.POINT_CONTACT and twisted.gamma == math.inf
        assert twisted.sense == (1 if sign > 0 else -1) and twisted.load_torque == pytest.approx(sign * 1e-4)
        assert twisted.taxel == taxel and twisted.torque_capacity == 0.0 and twisted.iterations == 0
        assert twisted.residual == 0.0 and twisted.cop == tuple(p)
    # a single taxel at the pad origin under a pure force: a translation, not a point contact
    res = load_factor(np.array([1.0, 0.0]), np.array([[0.0, 0.0], [1e-3, 0.0]]), (0.2, 0.1), 0.0, MU)
    assert res.status is SolverStatus.TRANSLATION and res.gamma == pytest.approx(np.hypot(0.2, 0.1) / MU)


def test_pure_torque_sense_and_torsional_coefficient_edge_cases():
    pad = PadGeometry(8, 8, 1.25e-3)
    phi = np.ones(64)
    for tau in (2e-3, -2e-3):
        res = load_factor(phi, pad.positions, (0.0, 0.0), tau, MU)
        assert res.sense == (1 if tau > 0 else -1) and res.load_torque == tau
        assert res.gamma == pytest.approx(abs(tau) / res.torque_capacity)
    for mu in (0.0, -0.5, np.nan, np.inf):
        bad = torsional_coefficient(phi, pad.positions, mu)
        assert bad.status is SolverStatus.INVALID_INPUT and bad.beta_m == 0.0 and bad.median is None
    empty = torsional_coefficient(np.zeros(64), pad.positions, MU)
    assert empty.status is SolverStatus.NO_CONTACT and empty.beta_m == 0.0 and empty.median is None


def test_a_force_through_a_point_contact_perpendicular_to_its_position_is_a_translation():
    # f ⟂ p with f × p > 0: τ = −(f × p) = −|f||p| exactly cancels the lever term, so the
    # tolerance for "through the taxel" must use |τ|; n(p̄) is then rounding only.
    pad = PadGeometry(8, 8, 1.25e-3)
    for taxel in range(64):
        phi = np.zeros(64)
        phi[taxel] = 1.5
        px, py = pad.positions[taxel]
        for k in (0.3, 1.1, 2.3):
            f_t = (k * py, -k * px)
            res = load_factor(phi, pad.positions, f_t, -(f_t[0] * py - f_t[1] * px), MU)
            assert res.status is SolverStatus.TRANSLATION, (taxel, k, res)


def test_a_line_contact_pushed_across_through_its_centre_is_a_plain_translation():
    # Taxels on the x axis have no spread along y: a force along y through the centre of
    # pressure has γ = |f_t|/(μ f_n) exactly (no correction term, no division by zero).
    pts = np.array([[-1e-3, 0.0], [0.0, 0.0], [2e-3, 0.0]])
    phi = np.array([1.0, 2.0, 1.0])
    cop_x = phi @ pts[:, 0] / phi.sum()
    res = load_factor(phi, pts, (0.0, 0.1), 0.1 * cop_x, MU)  # τ = −(f × p̄) = f_y·p̄_x
    assert res.status is SolverStatus.TRANSLATION and res.gamma == 0.1 / (MU * 4.0)


def test_a_capacity_that_underflows_is_refused_not_divided_by():
    """Pressures at the bottom of float range: μ f_n L underflows to 0 (ZeroDivisionError before)."""
    square = np.array([[0.0, 0.0], [1e-3, 0.0], [0.0, 1e-3], [1e-3, 1e-3]])
    res = load_factor(np.full(4, 5e-324), square, (0.0, 0.0), 5e-324, 0.5)
    assert res.status is SolverStatus.INVALID_INPUT


@pytest.mark.skipif(numba_config.DISABLE_JIT, reason="specialisations are compiled code: none with the JIT off")
def test_the_solvers_kernels_have_one_specialisation_whatever_arrays_they_are_given():
    """A read-only array is a numba type of its own; the kernels take every array read-only
    (``kernel_input``), so a node passing writable pooled taxels loads no second specialisation."""
    from slipstack.lib import limit_set, weber

    square = np.array([[0.0, 0.0], [1e-3, 0.0], [0.0, 1e-3], [1e-3, 1e-3]])
    weights = np.array([1.0, 2.0, 3.0, 4.0])
    frozen_square, frozen_weights = square.copy(), weights.copy()
    frozen_square.setflags(write=False)
    frozen_weights.setflags(write=False)
    for positions in (square, frozen_square, square[::-1]):
        for phi in (weights, frozen_weights, weights.astype(np.float32)):
            assert limit_set.load_factor(phi, positions, (0.1, 0.2), 1e-4, 0.5).gamma > 0
            assert limit_set.torsional_coefficient(phi, positions, 0.5).beta_m > 0
    assert len(limit_set._solve.signatures) == 1, limit_set._solve.signatures
    assert len(weber._solve_kernel.signatures) == 1, weber._solve_kernel.signatures
    assert square.flags.writeable and weights.flags.writeable  # the callers' arrays are left as they were
