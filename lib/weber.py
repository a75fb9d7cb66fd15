"""Weighted Fermat–Weber problem with a linear term (MATH.md §4.2).

Minimise over ``c ∈ R²``::

    F(c) = Σ_i a_i |p_i − c| − b·c,        a_i ≥ 0,

the sub-problem behind the paper's COR equations (12): with ``a_i = μ φ_i`` and
``b = s·perp(f_t)`` it is ``max_c g_s(c) = s·n(c) − T(c)`` up to the constant
``s·τ``; with ``b = 0`` its minimiser is the weighted geometric median.

``F`` is convex. It has a finite minimiser iff ``|b| < Σ a_i`` (for ``|b| ≥ Σ a``
it decreases without bound along ``b``: the contact translates).

Method: damped Newton with Armijo backtracking on ``F`` (globally convergent on a
convex function, quadratic near a smooth minimiser), plus the kink handling of
Kuhn (1973) / Vardi & Zhang (2000): at a point ``p_j`` the minimiser is ``p_j``
iff ``|R_j| ≤ a_j`` with ``R_j = Σ_{i≠j} a_i (p_j − p_i)/|p_j − p_i| − b``;
otherwise the steepest-descent step ``−R_j/|R_j| · (|R_j| − a_j)/Σ_{i≠j} a_i/|p_j − p_i|``
leaves the point. The Kuhn test is run whenever an iterate gets closer to a
point than the length of its last step: a minimiser on a taxel (the paper's
special case) is then found exactly instead of being approached forever, and
when the point is not optimal the Vardi–Zhang step off it is taken if it lowers
``F`` more than the Newton step (Newton alone crawls near a kink, where the
curvature grows like 1/r).

All work is done in normalised coordinates (points centred on their weighted
centroid and divided by their RMS radius, weights divided by their sum), so the
tolerances are relative: results are invariant to the units of ``a`` and ``b``
and to the length scale of ``p``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from slipstack.lib.status import SolverStatus

__all__ = ["WeberResult", "solve_weber", "geometric_median", "WeberStep", "weber_step", "step_converged"]

_KINK = 1e-13
"""Normalised distance below which an iterate is taken to sit on a point."""
_ARMIJO = 1e-4
_MAX_HALVINGS = 50


@dataclass(frozen=True)
class WeberResult:
    """Minimiser of ``Σ a_i|p_i − c| − b·c``.

    Attributes:
        c: the minimiser, same length unit as the points; ``None`` when unbounded.
        value: ``F(c)`` (units of ``a`` × length); ``-inf`` when unbounded.
        taxel: index (into the given points) of the point the minimiser sits on,
            ``-1`` when it is not on a point.
        iterations: Newton / Vardi–Zhang steps taken.
        residual: ``|∇F(c)| / Σa`` at a smooth minimiser; ``max(0, |R_j| − a_j)/Σa``
            at a point (dimensionless).
        status: CONVERGED, ON_TAXEL, TRANSLATION (unbounded), NO_CONTACT (all
            weights zero), MAX_ITER, or INVALID_INPUT.
    """

    c: tuple[float, float] | None
    value: float
    taxel: int
    iterations: int
    residual: float
    status: SolverStatus

    @property
    def converged(self) -> bool:
        """True when ``c`` is a certified minimiser (or the problem is unbounded)."""
        return self.status in (SolverStatus.CONVERGED, SolverStatus.ON_TAXEL, SolverStatus.TRANSLATION)


@dataclass(frozen=True)
class WeberStep:
    """One step of :func:`weber_step` in normalised coordinates.

    Attributes:
        c: the new iterate (2,).
        D: ``c − P`` for every point, shape (2, m), reusable by the next step.
        r: ``|c − P_i|``, shape (m,).
        step: length of the move that was made.
        taxel: index of the point ``c`` was certified optimal at (Kuhn test), or -1.
        kink_residual: ``max(0, |R_j| − a_j)`` of the last Kuhn test run (0 if none).
        stalled: the line search could not decrease ``F`` (machine precision reached).
        dist_sum: ``Σ a_i r_i`` at the new iterate.
    """

    c: np.ndarray
    D: np.ndarray
    r: np.ndarray
    step: float
    taxel: int
    kink_residual: float
    stalled: bool
    dist_sum: float


def _distances(PT: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    D = c[:, None] - PT
    return D, np.hypot(D[0], D[1])


def _kuhn(PT: np.ndarray, a: np.ndarray, b: np.ndarray, j: int) -> tuple[np.ndarray, np.ndarray]:
    """``R_j = Σ_{i≠j} a_i (p_j − p_i)/|p_j − p_i| − b`` (2,) and the distances from p_j (r_jj = inf)."""
    Dj = PT[:, j : j + 1] - PT
    rj = np.hypot(Dj[0], Dj[1])
    rj[j] = np.inf
    return Dj @ (a / rj) - b, rj


def _leave_point(PT: np.ndarray, a: np.ndarray, R: np.ndarray, rj: np.ndarray, j: int) -> np.ndarray:
    """Vardi–Zhang step off point ``j`` along ``−R_j`` (requires ``|R_j| > a_j``)."""
    norm_r = math.hypot(R[0], R[1])
    length = (norm_r - a[j]) / float(np.sum(a / rj))
    return PT[:, j] - R * (length / norm_r)


def weber_step(
    PT: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray, D: np.ndarray, r: np.ndarray
) -> WeberStep:
    """One safeguarded Newton step on ``F(c) = Σ a_i|P_i − c| − b·c`` (normalised).

    Args:
        PT: points, shape (2, m), normalised (centroid 0, RMS radius 1).
        a: weights (m,), summing to 1.
        b: linear term (2,), ``|b| < 1`` for a bounded problem.
        c: current iterate (2,); ``D, r``: its ``c − P`` (2, m) and distances (m,).

    Returns:
        A :class:`WeberStep`. ``taxel >= 0`` means ``c`` is certified optimal at
        that point; ``stalled`` means no decrease is possible in floating point.
    """
    j = int(r.argmin())
    if r[j] <= _KINK:
        return _at_point(PT, a, b, c, j, float(r[j]))
    bx, by = float(b[0]), float(b[1])
    w = a / r
    s = float(w.sum())
    g = D @ w
    gx, gy = float(g[0]) - bx, float(g[1]) - by
    H = (D * (w / (r * r))) @ D.T
    hxx, hyy, hxy = s - float(H[0, 0]), s - float(H[1, 1]), -float(H[0, 1])
    det = hxx * hyy - hxy * hxy
    if det <= 1e-14 * (hxx + hyy) ** 2:  # collinear points through c: regularise
        lam = 1e-7 * (hxx + hyy) + 1e-300
        hxx += lam
        hyy += lam
        det = hxx * hyy - hxy * hxy
    dx = -(hyy * gx - hxy * gy) / det
    dy = -(hxx * gy - hxy * gx) / det
    cx, cy = float(c[0]), float(c[1])
    f0 = float(a @ r) - bx * cx - by * cy
    slope = gx * dx + gy * dy
    t = 1.0
    for _ in range(_MAX_HALVINGS):
        cn = np.array([cx + t * dx, cy + t * dy])
        Dn = cn[:, None] - PT
        rn = np.hypot(Dn[0], Dn[1])
        dist = float(a @ rn)
        if dist - bx * cn[0] - by * cn[1] <= f0 + _ARMIJO * t * slope:
            break
        t *= 0.5
    else:
        return _stalled(PT, a, b, c, D, r)
    step = t * math.hypot(dx, dy)
    jn = int(rn.argmin())
    if rn[jn] <= step:
        # Near a kink Newton crawls (the 1/r curvature); certify the point or jump off it.
        R, rj = _kuhn(PT, a, b, jn)
        excess = math.hypot(R[0], R[1]) - a[jn]
        if excess <= 1e-14:
            return _snap(PT, a, jn, step, excess)
        cv = _leave_point(PT, a, R, rj, jn)
        Dv, rv = _distances(PT, cv)
        dist_v = float(a @ rv)
        if dist_v - bx * cv[0] - by * cv[1] < dist - bx * cn[0] - by * cn[1]:
            return WeberStep(cv, Dv, rv, math.hypot(cv[0] - cx, cv[1] - cy), -1, 0.0, False, dist_v)
    return WeberStep(cn, Dn, rn, step, -1, 0.0, False, dist)


def _snap(PT, a, j, step, excess) -> WeberStep:
    cj = PT[:, j].copy()
    Dj, rj = _distances(PT, cj)
    return WeberStep(cj, Dj, rj, step, j, max(excess, 0.0), False, float(a @ rj))


def _at_point(PT, a, b, c, j, rj) -> WeberStep:
    """The iterate sits on point ``j``: certify it or take the Vardi–Zhang step off it."""
    R, dist_j = _kuhn(PT, a, b, j)
    excess = math.hypot(R[0], R[1]) - a[j]
    if excess <= 1e-14:
        return _snap(PT, a, j, rj, excess)
    cn = _leave_point(PT, a, R, dist_j, j)
    Dn, rn = _distances(PT, cn)
    return WeberStep(cn, Dn, rn, math.hypot(*(cn - c)), -1, 0.0, False, float(a @ rn))


def _stalled(PT, a, b, c, D, r) -> WeberStep:
    """No decrease possible in floating point: certify the nearest point or report a stall."""
    j = int(r.argmin())
    R, _ = _kuhn(PT, a, b, j)
    excess = math.hypot(R[0], R[1]) - a[j]
    if excess <= 1e-14:
        return _snap(PT, a, j, 0.0, excess)
    return WeberStep(c, D, r, 0.0, -1, 0.0, True, float(a @ r))


def step_converged(step: float, prev_step: float, c: np.ndarray, xtol: float) -> bool:
    """Stop test shared by the Newton-type solvers (normalised coordinates).

    Converged when the last step is below ``xtol·(1 + |c|)``, or when it is below
    1e-3 and the quadratic-convergence prediction of the next step,
    ``step³/prev_step²``, is (the error left is then about that prediction).
    """
    bound = xtol * (1.0 + math.hypot(c[0], c[1]))
    if step <= bound:
        return True
    return step <= 1e-3 and prev_step > 0 and step**3 <= bound * prev_step**2


def _gradient_norm(D: np.ndarray, r: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    safe = np.where(r > _KINK, r, np.inf)
    g = D @ (a / safe) - b
    return math.hypot(g[0], g[1])


def solve_weber(
    points: np.ndarray,
    weights: np.ndarray,
    b: np.ndarray | tuple[float, float] = (0.0, 0.0),
    c0: np.ndarray | tuple[float, float] | None = None,
    *,
    xtol: float = 1e-9,
    max_iter: int = 100,
) -> WeberResult:
    """Minimise ``Σ a_i|p_i − c| − b·c`` (see module docstring).

    Args:
        points: (m, 2) point positions, any length unit (m in slipstack).
        weights: (m,) non-negative weights ``a_i`` (N for forces, or N·dimensionless).
        b: (2,) linear term, units of ``a``.
        c0: warm start (e.g. the previous frame's minimiser); centroid if ``None``.
        xtol: stop when a Newton step is below ``xtol`` × RMS radius of the points.
        max_iter: step limit.

    Returns:
        :class:`WeberResult`. Never raises on bad numbers (INVALID_INPUT instead).
    """
    P = np.asarray(points, dtype=float)
    a_all = np.asarray(weights, dtype=float)
    bv = np.asarray(b, dtype=float).reshape(-1)
    if P.ndim != 2 or P.shape[1] != 2 or a_all.shape != (P.shape[0],) or bv.shape != (2,):
        return WeberResult(None, math.nan, -1, 0, math.inf, SolverStatus.INVALID_INPUT)
    if not (np.all(np.isfinite(P)) and np.all(np.isfinite(a_all)) and np.all(np.isfinite(bv))):
        return WeberResult(None, math.nan, -1, 0, math.inf, SolverStatus.INVALID_INPUT)
    if np.any(a_all < 0):
        return WeberResult(None, math.nan, -1, 0, math.inf, SolverStatus.INVALID_INPUT)
    idx = np.flatnonzero(a_all > 0)
    if idx.size == 0:
        return WeberResult(None, 0.0, -1, 0, 0.0, SolverStatus.NO_CONTACT)
    total = float(a_all[idx].sum())
    a = a_all[idx] / total
    Pc = P[idx]
    centre = a @ Pc
    scale = math.sqrt(float(a @ np.sum((Pc - centre) ** 2, axis=1)))
    bn = bv / total
    if math.hypot(bn[0], bn[1]) >= 1.0:
        return WeberResult(None, -math.inf, -1, 0, 0.0, SolverStatus.TRANSLATION)
    if scale == 0.0 or idx.size == 1:  # one point (or coincident points): it is optimal
        c = tuple(float(v) for v in Pc[0])
        value = total * 0.0 - float(bv @ Pc[0])
        return WeberResult(c, value, int(idx[0]), 0, 0.0, SolverStatus.ON_TAXEL)
    PT = np.ascontiguousarray(((Pc - centre) / scale).T)
    if c0 is not None and np.all(np.isfinite(np.asarray(c0, dtype=float))):
        c = (np.asarray(c0, dtype=float).reshape(2) - centre) / scale
    else:
        c = np.zeros(2)
    D, r = _distances(PT, c)
    status = SolverStatus.MAX_ITER
    taxel = -1
    residual = math.inf
    it = 0
    prev = math.inf
    for it in range(1, max_iter + 1):
        st = weber_step(PT, a, bn, c, D, r)
        c, D, r = st.c, st.D, st.r
        if st.taxel >= 0:
            status, taxel, residual = SolverStatus.ON_TAXEL, st.taxel, st.kink_residual
            break
        if st.stalled or step_converged(st.step, prev, c, xtol):
            residual = _gradient_norm(D, r, a, bn)
            status = SolverStatus.CONVERGED if residual <= 1e-3 else SolverStatus.MAX_ITER
            break
        prev = st.step
    else:
        residual = _gradient_norm(D, r, a, bn)
    c_out = centre + scale * c
    value = float(a_all[idx] @ np.hypot(*(Pc - c_out).T)) - float(bv @ c_out)
    return WeberResult(
        (float(c_out[0]), float(c_out[1])),
        value,
        int(idx[taxel]) if taxel >= 0 else -1,
        it,
        float(residual),
        status,
    )


def geometric_median(
    points: np.ndarray, weights: np.ndarray, c0: np.ndarray | tuple[float, float] | None = None
) -> WeberResult:
    """Weighted geometric median ``argmin_c Σ a_i |p_i − c|`` (``b = 0``)."""
    return solve_weber(points, weights, (0.0, 0.0), c0)
