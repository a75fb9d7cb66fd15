"""Weighted Fermat–Weber problem with a linear term (docs/math.md §4.2).

Minimise over ``c ∈ R²``::

    F(c) = Σ_i a_i |p_i − c| − b·c,        a_i ≥ 0,

More in docs/modules.md, `lib/weber.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from slipstack.lib.status import SolverStatus

__all__ = [
    "CONTACT_INVALID",
    "CONTACT_NONE",
    "CONTACT_OK",
    "SOLVED_CONVERGED",
    "SOLVED_MAX_ITER",
    "SOLVED_ON_TAXEL",
    "SOLVED_STATUS",
    "STEP_MOVED",
    "STEP_ON_TAXEL",
    "STEP_STALLED",
    "WeberResult",
    "fill_distances",
    "geometric_median",
    "kernel_input",
    "newton_step",
    "normalise_contact",
    "solve_weber",
    "step_converged",
]

JIT = {"cache": True, "nogil": True, "error_model": "numpy"}
"""numba options of every slipstack kernel: cached, GIL released, IEEE division (x/0 → inf, no exception)."""


def kernel_input(a: np.ndarray) -> np.ndarray:
    """``a`` as the one array type the solvers' kernels take: C-contiguous and read-only.

    numba compiles, and loads from its cache, one specialisation per argument type, and a
    read-only array is a type of its own. Nodes pass read-only arrays (decoded message
    buffers, fusion's frozen arrays, the cached pad geometry) and sometimes writable ones
    (pooled or selected taxels): passing every one read-only (a view, no copy) keeps
    one specialisation per kernel, loaded once at start (~7 ms each) instead of one per mix.
    """
    a = np.ascontiguousarray(a)
    if a.flags.writeable:
        a = a.view()
        a.flags.writeable = False
    return a


_KINK = 1e-13
"""Normalised distance below which an iterate is taken to sit on a point."""
_ARMIJO = 1e-4
_MAX_HALVINGS = 50
_KUHN_TOL = 1e-14

STEP_MOVED, STEP_ON_TAXEL, STEP_STALLED = 0, 1, 2
"""``newton_step`` outcomes: moved; ``c`` certified optimal at a point; no decrease possible."""
CONTACT_OK, CONTACT_INVALID, CONTACT_NONE = 0, 1, 2
"""``normalise_contact`` codes: usable; a non-finite value, a negative weight or an overflowing sum; no positive weight."""
SOLVED_CONVERGED, SOLVED_ON_TAXEL, SOLVED_MAX_ITER = 0, 1, 2
"""Outcome codes of the compiled solvers (here and in :mod:`slipstack.lib.limit_set`)."""
SOLVED_STATUS = {
    SOLVED_CONVERGED: SolverStatus.CONVERGED,
    SOLVED_ON_TAXEL: SolverStatus.ON_TAXEL,
    SOLVED_MAX_ITER: SolverStatus.MAX_ITER,
}
_TRANSLATION, _SINGLE = 3, 4  # further outcomes of _solve_kernel


@dataclass(frozen=True, slots=True)
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


@njit(**JIT)
def normalise_contact(points, weights):
    """The points with positive weight, centred and scaled (compiled).

    Args:
        points: (N, 2) float64, any length unit; weights: (N,) float64, ``≥ 0``.

    Returns:
        ``(code, idx, px, py, a, centre_x, centre_y, scale, total)``: code
        :data:`CONTACT_OK`, :data:`CONTACT_INVALID` (a non-finite value, a negative
        weight, or weights whose sum overflows) or :data:`CONTACT_NONE` (no positive weight);
        ``idx`` the kept indices; ``px, py`` the kept points minus the weighted
        centroid, divided by ``scale`` (their weighted RMS radius, 0 if they all
        coincide, which leaves them unscaled); ``a`` the kept weights over their
        ``total``.
    """
    n = weights.size
    m = 0
    for i in range(n):
        w = weights[i]
        if not (math.isfinite(w) and w >= 0.0 and math.isfinite(points[i, 0]) and math.isfinite(points[i, 1])):
            return CONTACT_INVALID, np.empty(0, np.int64), np.empty(0), np.empty(0), np.empty(0), 0.0, 0.0, 0.0, 0.0
        if w > 0.0:
            m += 1
    idx = np.empty(m, np.int64)
    k = 0
    total = 0.0
    for i in range(n):
        if weights[i] > 0.0:
            idx[k] = i
            total += weights[i]
            k += 1
    if m == 0:
        return CONTACT_NONE, idx, np.empty(0), np.empty(0), np.empty(0), 0.0, 0.0, 0.0, 0.0
    if not math.isfinite(total):  # the weights overflow together: no weight is usable against their sum
        return CONTACT_INVALID, np.empty(0, np.int64), np.empty(0), np.empty(0), np.empty(0), 0.0, 0.0, 0.0, 0.0
    a = np.empty(m)
    cx = 0.0
    cy = 0.0
    for k in range(m):
        a[k] = weights[idx[k]] / total
        cx += a[k] * points[idx[k], 0]
        cy += a[k] * points[idx[k], 1]
    px = np.empty(m)
    py = np.empty(m)
    var = 0.0
    for k in range(m):
        px[k] = points[idx[k], 0] - cx
        py[k] = points[idx[k], 1] - cy
        var += a[k] * (px[k] * px[k] + py[k] * py[k])
    scale = math.sqrt(var)
    if scale > 0.0:
        for k in range(m):
            px[k] /= scale
            py[k] /= scale
    return CONTACT_OK, idx, px, py, a, cx, cy, scale, total


@njit(**JIT)
def fill_distances(px, py, a, cx, cy, r):
    """``r_i = |c − p_i|`` written into ``r``; returns ``Σ a_i r_i`` (normalised units)."""
    total = 0.0
    for i in range(px.size):
        dx = cx - px[i]
        dy = cy - py[i]
        ri = math.sqrt(dx * dx + dy * dy)  # no overflow: normalised coordinates are O(1)…O(1e7)
        r[i] = ri
        total += a[i] * ri
    return total


@njit(**JIT)
def _kuhn(px, py, a, bx, by, j):
    """Kuhn's quantities at point ``j``: ``R_j`` (x, y), ``Σ_{i≠j} a_i/|p_j − p_i|`` and
    the weight sitting at ``p_j`` (``a_j`` plus any point coinciding with it)."""
    rx = -bx
    ry = -by
    inv = 0.0
    aj = a[j]
    for i in range(px.size):
        if i == j:
            continue
        dx = px[j] - px[i]
        dy = py[j] - py[i]
        d = math.sqrt(dx * dx + dy * dy)
        if d == 0.0:
            aj += a[i]
            continue
        w = a[i] / d
        rx += w * dx
        ry += w * dy
        inv += w
    return rx, ry, inv, aj


@njit(**JIT)
def _snap(px, py, a, j, step, excess, r):
    """Certified at point ``j``: move there (``r`` refilled)."""
    dist = fill_distances(px, py, a, px[j], py[j], r)
    return px[j], py[j], step, STEP_ON_TAXEL, max(excess, 0.0), j, dist


@njit(**JIT)
def _leave_point(px, py, rx, ry, inv, aj, j):
    """Vardi–Zhang step off point ``j`` along ``−R_j`` (requires ``|R_j| > a_j``)."""
    norm_r = math.hypot(rx, ry)
    length = (norm_r - aj) / inv
    return px[j] - rx * (length / norm_r), py[j] - ry * (length / norm_r)


@njit(**JIT)
def _at_point(px, py, a, bx, by, cx, cy, j, r):
    """The iterate sits on point ``j``: certify it or take the Vardi–Zhang step off it."""
    rx, ry, inv, aj = _kuhn(px, py, a, bx, by, j)
    excess = math.hypot(rx, ry) - aj
    if excess <= _KUHN_TOL or inv == 0.0:
        return _snap(px, py, a, j, r[j], excess, r)
    nx, ny = _leave_point(px, py, rx, ry, inv, aj, j)
    dist = fill_distances(px, py, a, nx, ny, r)
    return nx, ny, math.hypot(nx - cx, ny - cy), STEP_MOVED, 0.0, -1, dist


@njit(**JIT)
def _stalled(px, py, a, bx, by, cx, cy, r, dist):
    """No decrease possible in floating point: certify the nearest point or report a stall."""
    j = np.argmin(r)
    rx, ry, _, aj = _kuhn(px, py, a, bx, by, j)
    excess = math.hypot(rx, ry) - aj
    if excess <= _KUHN_TOL:
        return _snap(px, py, a, j, 0.0, excess, r)
    return cx, cy, 0.0, STEP_STALLED, 0.0, -1, dist


@njit(**JIT)
def newton_step(px, py, a, bx, by, cx, cy, r, work):
    """One safeguarded Newton step on ``F(c) = Σ a_i|p_i − c| − b·c`` (normalised, compiled).

    Args:
        px, py: (m,) point coordinates, normalised (centroid 0, RMS radius 1).
        a: (m,) weights summing to 1; ``bx, by``: the linear term, ``|b| < 1``.
        cx, cy: the current iterate; ``r``: (m,) its distances ``|c − p_i|``,
            overwritten with the new iterate's; ``work``: (m,) scratch.

    Returns:
        ``(cx, cy, step, code, kink_residual, taxel, dist_sum)``: the new iterate,
        the length of the move, the outcome :data:`STEP_MOVED` / :data:`STEP_ON_TAXEL`
        (``c`` certified optimal at point ``taxel``, ``kink_residual = max(0, |R_j| − a_j)``)
        / :data:`STEP_STALLED` (no decrease possible in floating point), and ``Σ a_i r_i`` there.
    """
    j = np.argmin(r)
    if r[j] <= _KINK:
        return _at_point(px, py, a, bx, by, cx, cy, j, r)
    s = 0.0
    gx = -bx
    gy = -by
    qxx = 0.0
    qyy = 0.0
    qxy = 0.0
    dist0 = 0.0
    for i in range(px.size):
        ri = r[i]
        w = a[i] / ri
        dx = cx - px[i]
        dy = cy - py[i]
        s += w
        gx += w * dx
        gy += w * dy
        w3 = w / (ri * ri)
        qxx += w3 * dx * dx
        qyy += w3 * dy * dy
        qxy += w3 * dx * dy
        dist0 += a[i] * ri
    hxx = s - qxx
    hyy = s - qyy
    hxy = -qxy
    det = hxx * hyy - hxy * hxy
    if det <= 1e-14 * (hxx + hyy) ** 2:  # collinear points through c: regularise
        lam = 1e-7 * (hxx + hyy) + 1e-300
        hxx += lam
        hyy += lam
        det = hxx * hyy - hxy * hxy
    dx = -(hyy * gx - hxy * gy) / det
    dy = -(hxx * gy - hxy * gx) / det
    f0 = dist0 - bx * cx - by * cy
    slope = gx * dx + gy * dy
    t = 1.0
    nx = cx
    ny = cy
    dist = dist0
    decreased = False
    for _ in range(_MAX_HALVINGS):
        nx = cx + t * dx
        ny = cy + t * dy
        dist = fill_distances(px, py, a, nx, ny, work)
        if dist - bx * nx - by * ny <= f0 + _ARMIJO * t * slope:
            decreased = True
            break
        t *= 0.5
    if not decreased:
        return _stalled(px, py, a, bx, by, cx, cy, r, dist0)
    step = t * math.hypot(dx, dy)
    jn = np.argmin(work)
    if work[jn] <= step:
        # Near a kink Newton crawls (the 1/r curvature); certify the point or jump off it.
        rx, ry, inv, aj = _kuhn(px, py, a, bx, by, jn)
        excess = math.hypot(rx, ry) - aj
        if excess <= _KUHN_TOL:
            return _snap(px, py, a, jn, step, excess, r)
        vx, vy = _leave_point(px, py, rx, ry, inv, aj, jn)
        dist_v = fill_distances(px, py, a, vx, vy, r)
        if dist_v - bx * vx - by * vy < dist - bx * nx - by * ny:
            return vx, vy, math.hypot(vx - cx, vy - cy), STEP_MOVED, 0.0, -1, dist_v
    r[:] = work
    return nx, ny, step, STEP_MOVED, 0.0, -1, dist


@njit(**JIT)
def step_converged(step, prev_step, cx, cy, xtol):
    """Stop test shared by the Newton-type solvers (normalised coordinates).

    Converged when the last step is below ``xtol·(1 + |c|)``, or when it is below
    1e-3 and the quadratic-convergence prediction of the next step,
    ``step³/prev_step²``, is (the error left is then about that prediction).
    """
    bound = xtol * (1.0 + math.hypot(cx, cy))
    if step <= bound:
        return True
    return step <= 1e-3 and prev_step > 0.0 and step**3 <= bound * prev_step**2


@njit(**JIT)
def _gradient_norm(px, py, a, bx, by, cx, cy, r):
    """``|∇F(c)|`` in normalised units, points closer than the kink tolerance left out."""
    gx = -bx
    gy = -by
    for i in range(px.size):
        if r[i] > _KINK:
            w = a[i] / r[i]
            gx += w * (cx - px[i])
            gy += w * (cy - py[i])
    return math.hypot(gx, gy)


@njit(**JIT)
def _solve_kernel(points, weights, bx, by, c0x, c0y, warm, xtol, max_iter):
    """:func:`solve_weber` in one compiled call.

    Returns ``(code, cx, cy, value, taxel, iterations, residual)``: code one of
    ``SOLVED_CONVERGED, SOLVED_ON_TAXEL, SOLVED_MAX_ITER, _TRANSLATION, _SINGLE`` (one point, or
    coincident points) or, from :func:`normalise_contact`, invalid / no contact
    (offset by 10); ``taxel`` indexes ``points``.
    """
    code, idx, px, py, a, ox, oy, scale, total = normalise_contact(points, weights)
    if code != CONTACT_OK:
        return 10 + code, 0.0, 0.0, 0.0, -1, 0, 0.0
    bnx = bx / total
    bny = by / total
    if math.hypot(bnx, bny) >= 1.0:
        return _TRANSLATION, 0.0, 0.0, -math.inf, -1, 0, 0.0
    if scale == 0.0 or idx.size == 1:  # one point (or coincident points): it is optimal
        return _SINGLE, ox, oy, -(bx * ox + by * oy), idx[0], 0, 0.0
    cx = 0.0
    cy = 0.0
    if warm:
        cx = (c0x - ox) / scale
        cy = (c0y - oy) / scale
    m = px.size
    r = np.empty(m)
    work = np.empty(m)
    dist = fill_distances(px, py, a, cx, cy, r)
    status = SOLVED_MAX_ITER
    taxel = -1
    residual = math.inf
    prev = math.inf
    it = 0
    while it < max_iter:
        it += 1
        cx, cy, step, outcome, kink_residual, tx, dist = newton_step(px, py, a, bnx, bny, cx, cy, r, work)
        if outcome == STEP_ON_TAXEL:
            status = SOLVED_ON_TAXEL
            taxel = idx[tx]
            residual = kink_residual
            break
        if outcome == STEP_STALLED or step_converged(step, prev, cx, cy, xtol):
            residual = _gradient_norm(px, py, a, bnx, bny, cx, cy, r)
            status = SOLVED_CONVERGED if residual <= 1e-3 else SOLVED_MAX_ITER
            break
        prev = step
    if status == SOLVED_MAX_ITER and math.isinf(residual):
        residual = _gradient_norm(px, py, a, bnx, bny, cx, cy, r)
    out_x = ox + scale * cx
    out_y = oy + scale * cy
    value = total * scale * dist - (bx * out_x + by * out_y)
    return status, out_x, out_y, value, taxel, it, residual


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
    P = np.asarray(points, dtype=np.float64)
    a_all = np.asarray(weights, dtype=np.float64)
    bv = np.asarray(b, dtype=np.float64).reshape(-1)
    if P.ndim != 2 or P.shape[1] != 2 or a_all.shape != (P.shape[0],) or bv.shape != (2,):
        return WeberResult(None, math.nan, -1, 0, math.inf, SolverStatus.INVALID_INPUT)
    bx, by = float(bv[0]), float(bv[1])
    if not (math.isfinite(bx) and math.isfinite(by)):
        return WeberResult(None, math.nan, -1, 0, math.inf, SolverStatus.INVALID_INPUT)
    warm = c0 is not None
    c0x = c0y = 0.0
    if warm:
        c0x, c0y = (float(v) for v in np.asarray(c0, dtype=np.float64).reshape(2))
        warm = math.isfinite(c0x) and math.isfinite(c0y)
    code, cx, cy, value, taxel, it, residual = _solve_kernel(
        kernel_input(P), kernel_input(a_all), bx, by, c0x, c0y, warm, float(xtol), int(max_iter)
    )
    if code == 10 + CONTACT_INVALID:
        return WeberResult(None, math.nan, -1, 0, math.inf, SolverStatus.INVALID_INPUT)
    if code == 10 + CONTACT_NONE:
        return WeberResult(None, 0.0, -1, 0, 0.0, SolverStatus.NO_CONTACT)
    if code == _TRANSLATION:
        return WeberResult(None, -math.inf, -1, 0, 0.0, SolverStatus.TRANSLATION)
    if code == _SINGLE:
        return WeberResult((cx, cy), value, int(taxel), 0, 0.0, SolverStatus.ON_TAXEL)
    return WeberResult((cx, cy), value, int(taxel), int(it), float(residual), SOLVED_STATUS[code])


def geometric_median(
    points: np.ndarray, weights: np.ndarray, c0: np.ndarray | tuple[float, float] | None = None
) -> WeberResult:
    """Weighted geometric median ``argmin_c Σ a_i |p_i − c|`` (``b = 0``)."""
    return solve_weber(points, weights, (0.0, 0.0), c0)
