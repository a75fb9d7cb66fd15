"""The exact limit set of a tactile contact: load factor γ and the COR of impending slip.

docs/math.md §4. Each taxel ``i`` (position ``p_i`` in the pad frame F, m; normal force
``φ_i`` N) supplies a tangential force ``|q_i| ≤ μ φ_i``. The load
``w = (f_t, τ)`` (N, N·m about z through the pad origin, in F) sticks iff
``γ(w) ≤ 1`` with the load factor::

More in docs/modules.md, `lib/limit_set.py`.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass

import numpy as np
from numba import njit

from slipstack.lib.status import SlipCase, SolverStatus
from slipstack.lib.weber import (
    CONTACT_INVALID,
    CONTACT_NONE,
    JIT,
    SOLVED_CONVERGED,
    SOLVED_MAX_ITER,
    SOLVED_ON_TAXEL,
    SOLVED_STATUS,
    STEP_ON_TAXEL,
    STEP_STALLED,
    fill_distances,
    geometric_median,
    kernel_input,
    newton_step,
    normalise_contact,
    step_converged,
)

__all__ = ["LimitSetResult", "TorsionResult", "compile_kernels", "contact_subset", "load_factor", "torsional_coefficient"]

_NEAR_TRANSLATION = 1e-5
_FORCE_BELOW_ROUNDING = 1e-16
"""``|f_t|/(μ f_n)`` below this times the normalised torque about ``p̄``: the force changes
``n(c)`` by less than rounding within a contact radius, γ is ``|τ|/T_min`` to machine
precision, and only the pure-torque answer gives a unique COR (``s·n/T`` would be flat
to rounding wherever ``T`` is, e.g. along the segment between two equal taxels)."""
_MAX_FAR = 1e7
_MAX_RESIDUAL = 1e-3


@dataclass(frozen=True, slots=True)
class LimitSetResult:
    """Load factor and centre of rotation of impending slip (pad frame F, SI).

    Attributes:
        case: ROTATION, ON_TAXEL (COR on a taxel), TRANSLATION (no finite COR),
            NONE (no load / no contact / invalid input).
        gamma: load factor γ (dimensionless); stick iff ``γ ≤ 1``.
        p_c: centre of rotation of impending slip (m), ``None`` unless case is
            ROTATION or ON_TAXEL.
        torque_capacity: ``T(p_c)`` = μ Σ φ_i |p_i − p_c| (N·m); 0 when ``p_c`` is None.
        load_torque: ``n(p_c) = τ + f_t × p_c`` (N·m, signed); 0 when ``p_c`` is None.
        sense: +1 counter-clockwise / −1 clockwise rotation of the object, 0 otherwise.
        iterations: Dinkelbach updates (sub-solver steps).
        residual: relative stationarity residual ``|s·perp(f_t) − γ∇T| /(μ f_n γ)``,
            or the Kuhn excess on a taxel (dimensionless).
        status: see :class:`SolverStatus`.
        taxel: index of the taxel the COR sits on, −1 otherwise.
        cop: centre of pressure ``p̄`` (m, F); (0, 0) without contact.
        contact_radius_m: RMS radius ``L`` of the pressure about ``p̄`` (m).

    ``status`` is CONVERGED only if the last step was below ``xtol·L`` (COR error
    about ``xtol·L``, γ error second order in it) *and* the relative stationarity
    residual is ≤ 1e-3 (a loose guard: near a taxel the 1/r curvature makes the
    gradient residual large for tiny COR errors); otherwise MAX_ITER (γ is then the ratio at the last iterate,
    a lower bound on the exact γ).
    """

    case: SlipCase
    gamma: float
    p_c: tuple[float, float] | None
    torque_capacity: float
    load_torque: float
    sense: int
    iterations: int
    residual: float
    status: SolverStatus
    taxel: int = -1
    cop: tuple[float, float] = (0.0, 0.0)
    contact_radius_m: float = 0.0

    @property
    def converged(self) -> bool:
        """True when the numbers are exact answers (status usable)."""
        return self.status.usable

    @property
    def margin(self) -> float:
        """``1 − γ``: positive when sticking."""
        return 1.0 - self.gamma


def _none(status: SolverStatus, gamma: float = 0.0) -> LimitSetResult:
    return LimitSetResult(SlipCase.NONE, gamma, None, 0.0, 0.0, 0, 0, 0.0, status)


def contact_subset(phi: np.ndarray, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The taxels in contact: ``(indices, φ_sub (m,), positions_sub (m,2))``.

    Returns ``None`` if shapes mismatch or any value is non-finite or φ negative.
    """
    phi = np.asarray(phi, dtype=float)
    positions = np.asarray(positions, dtype=float)
    if phi.ndim != 1 or positions.shape != (phi.shape[0], 2):
        return None
    if not np.isfinite(phi).all() or (phi < 0).any():
        return None
    idx = np.flatnonzero(phi)
    return idx, phi[idx], positions[idx]


def load_factor(
    phi: np.ndarray,
    positions: np.ndarray,
    f_t: np.ndarray | tuple[float, float],
    tau: float,
    mu: float,
    *,
    c0: np.ndarray | tuple[float, float] | None = None,
    xtol: float = 1e-8,
    max_iter: int = 100,
) -> LimitSetResult:
    """Exact load factor γ and COR of impending slip (see module docstring).

    Args:
        phi: (N,) normal force per taxel, N, ``φ_i ≥ 0``.
        positions: (N, 2) taxel positions in F, m.
        f_t: (2,) tangential load in F, N.
        tau: torque about z through the pad origin, N·m.
        mu: static friction coefficient, > 0.
        c0: warm start, e.g. the previous frame's ``p_c`` (m, F); ignored if unusable.
        xtol: stop when a step is below ``xtol`` × the RMS contact radius.
        max_iter: limit on Dinkelbach updates.

    Returns:
        :class:`LimitSetResult`; never raises.
    """
    ph_all = np.asarray(phi, dtype=np.float64)
    pos = np.asarray(positions, dtype=np.float64)
    ft = np.asarray(f_t, dtype=np.float64).reshape(-1)
    if ph_all.ndim != 1 or pos.shape != (ph_all.shape[0], 2) or ft.shape != (2,):
        return _none(SolverStatus.INVALID_INPUT)
    (fx, fy), tau = ft.tolist(), float(tau)
    if not (math.isfinite(fx) and math.isfinite(fy) and math.isfinite(tau) and math.isfinite(mu) and mu > 0):
        return _none(SolverStatus.INVALID_INPUT)
    given, c0x, c0y = _warm_point(c0)
    (branch, taxel, ox, oy, L, f_n, cap, gt, n_bar, tn, s, lever, sig2, outcome, cx, cy, gamma, T, n_s, it,
     residual) = _solve(kernel_input(pos), kernel_input(ph_all), fx, fy, tau, float(mu), math.hypot(fx, fy),
                        given, c0x, c0y, float(xtol), int(max_iter))
    if branch == _SOLVED:
        if not math.isfinite(gamma):  # the ratio overflows on the way (a load ~1e308 times the capacity)
            return _none(SolverStatus.INVALID_INPUT)
        status = SOLVED_STATUS[outcome]
        case = SlipCase.ON_TAXEL if status is SolverStatus.ON_TAXEL else SlipCase.ROTATION
        return LimitSetResult(
            case,
            float(gamma),
            (ox + L * cx, oy + L * cy),
            float(cap * L * T),
            float(s * cap * L * n_s),
            s,
            int(it),
            float(residual),
            status,
            taxel,
            (ox, oy),
            L,
        )
    if branch == _NEAR_TRANSLATION_CASE:
        gamma = gt * (1.0 + (lever * lever / (2.0 * sig2) if sig2 > 0 else 0.0))
        return LimitSetResult(SlipCase.TRANSLATION, float(gamma), None, 0.0, 0.0, 0, 0, 0.0,
                              SolverStatus.TRANSLATION, -1, (ox, oy), L)
    if branch == _POINT_CONTACT:
        return _point_contact(n_bar, tau, fx, fy, (ox, oy), gt, taxel)
    if branch == _PURE_TORQUE:
        return _pure_torque(pos, ph_all, tn, tau, (ox, oy), L, cap, f_n, c0)
    return _none(_EARLY_STATUS[branch])


_SOLVED, _NEAR_TRANSLATION_CASE, _POINT_CONTACT, _PURE_TORQUE = 0, 1, 2, 3
""":func:`_solve`'s outcomes that :func:`load_factor` turns into a result with numbers."""
_BAD_INPUT, _NO_CONTACT, _NO_LOAD = 4, 5, 6
""":func:`_solve`'s outcomes without numbers, and their status (:data:`_EARLY_STATUS`)."""
_EARLY_STATUS = {_BAD_INPUT: SolverStatus.INVALID_INPUT, _NO_CONTACT: SolverStatus.NO_CONTACT,
                 _NO_LOAD: SolverStatus.NO_LOAD}
_FLOAT_MIN = sys.float_info.min


@njit(**JIT)
def _solve(points, weights, fx, fy, tau, mu, f_t_abs, given, c0x, c0y, xtol, max_iter):
    """Steps 1–4 of the module docstring in one compiled call, from the pressure to the
    Dinkelbach answer: :func:`~slipstack.lib.weber.normalise_contact`, the special
    cases, :func:`_spread_along`, the warm start and :func:`_dinkelbach`.

    It replaces four calls from Python (two of them returning or taking the normalised
    taxel arrays, which cost more to pass than the sums over them) with one that returns
    numbers only; every number is computed by the same operations as before.
    ``f_t_abs`` is ``math.hypot(fx, fy)`` from Python (the rounding it always had);
    ``given, c0x, c0y`` the warm start (m, F), if any. Only the warm start's distance
    bound (1e7 contact radii) is now taken with the C library's ``hypot``, which may
    round its last bit unlike Python's: it decides nothing but whether so far a start is
    used.

    Returns ``(branch, taxel, ox, oy, L, f_n, cap, gt, n_bar, tn, s, lever, sig2, code,
    cx, cy, gamma, T, n_s, iterations, residual)``: the branch (:data:`_SOLVED` …
    :data:`_NO_LOAD`), the taxel of a point contact or of the COR (an index of
    ``weights``, −1: none), the centre of pressure and contact radius (m), ``f_n``,
    ``μ f_n`` (N), ``γ_t``, the torque about the centre of pressure (N·m), its normalised
    value and sense, the lever arm, the spread along the force, and
    :func:`_dinkelbach`'s answer (zeros on the other branches).
    """
    code, idx, px, py, a, ox, oy, L, f_n = normalise_contact(points, weights)
    none = (-1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0.0, 0.0, SOLVED_MAX_ITER, 0.0, 0.0, 0.0, 0.0, 0.0, 0, 0.0)
    if code == CONTACT_INVALID:
        return (_BAD_INPUT,) + none
    if code == CONTACT_NONE:
        return (_NO_CONTACT,) + none
    cap = mu * f_n
    if not cap >= _FLOAT_MIN:  # μ f_n subnormal: no measured force (pressures at the bottom of float range)
        return (_BAD_INPUT,) + none
    if fx == 0.0 and fy == 0.0 and tau == 0.0:
        return (_NO_LOAD,) + none
    gt = f_t_abs / cap
    n_bar = tau + fx * oy - fy * ox  # torque about the centre of pressure
    if idx.size == 1 or L == 0.0:
        return (_POINT_CONTACT, idx[0], ox, oy, L, f_n, cap, gt, n_bar, 0.0, 0, 0.0, 0.0, SOLVED_MAX_ITER, 0.0, 0.0,
                0.0, 0.0, 0.0, 0, 0.0)
    scale = cap * L
    tn = n_bar / scale if scale > 0.0 else math.inf  # normalised torque about p̄ (inf: μ f_n L underflows)
    if not (math.isfinite(tn) and math.isfinite(gt)):  # load/capacity beyond float range
        return (_BAD_INPUT,) + none
    if gt <= abs(tn) * _FORCE_BELOW_ROUNDING:  # the force cannot change n(c) in double precision
        return (_PURE_TORQUE, -1, ox, oy, L, f_n, cap, gt, n_bar, tn, 0, 0.0, 0.0, SOLVED_MAX_ITER, 0.0, 0.0, 0.0,
                0.0, 0.0, 0, 0.0)
    s = 1 if tn > 0 else -1
    fx_n = fx / cap  # normalised force f_t/(μ f_n)
    fy_n = fy / cap
    lever = abs(tn) / gt
    sig2 = _spread_along(px, py, a, fx_n / gt, fy_n / gt)
    if tn == 0.0 or lever <= _NEAR_TRANSLATION * math.sqrt(sig2):
        return (_NEAR_TRANSLATION_CASE, -1, ox, oy, L, f_n, cap, gt, n_bar, tn, s, lever, sig2, SOLVED_MAX_ITER, 0.0,
                0.0, 0.0, 0.0, 0.0, 0, 0.0)
    warm = False
    wx = 0.0
    wy = 0.0
    if given:  # usable if finite and within 1e7 contact radii
        wx = (c0x - ox) / L
        wy = (c0y - oy) / L
        warm = math.isfinite(wx) and math.isfinite(wy) and math.hypot(wx, wy) < _MAX_FAR
    outcome, cx, cy, gamma, T, n_s, it, residual, taxel = _dinkelbach(
        px, py, a, s, tn, fx_n, fy_n, lever, warm, wx, wy, xtol, max_iter
    )
    return (_SOLVED, idx[taxel] if taxel >= 0 else -1, ox, oy, L, f_n, cap, gt, n_bar, tn, s, lever, sig2, outcome,
            cx, cy, gamma, T, n_s, it, residual)


def _warm_point(c0) -> tuple[bool, float, float]:
    """``(given, x, y)`` of the warm start ``c0`` (m, F): given if it is two numbers."""
    if c0 is None:
        return False, 0.0, 0.0
    if type(c0) is tuple and len(c0) == 2 and type(c0[0]) is float and type(c0[1]) is float:
        return True, c0[0], c0[1]  # a previous result's COR: no array to build at every frame
    cw = np.asarray(c0, dtype=np.float64).reshape(-1)
    if cw.shape != (2,):
        return False, 0.0, 0.0
    return True, float(cw[0]), float(cw[1])


@njit(**JIT)
def _spread_along(px, py, a, ux, uy):
    """``Σ a_i (p_i·u)²``: the contact's (normalised) variance along the unit vector ``u``."""
    total = 0.0
    for i in range(px.size):
        d = px[i] * ux + py[i] * uy
        total += a[i] * d * d
    return total


_RAY = np.logspace(-2.0, 7.0, 37)


@njit(**JIT)
def _start(px, py, a, s, tn, fx, fy, lever, warm, wx, wy, r):
    """A start with ratio ``s·n/T > |f_t|/(μ f_n)``, so every sub-problem is bounded.

    The warm start if it qualifies, else the best point on the ray ``p̄ + t·b̂``
    (t = 1e-2 … 1e7 contact radii): along it ``T̃ − t`` falls to 0 while
    ``s·ñ/|f̃| − t`` stays at the lever arm ``a > 0``, so some ``t`` qualifies.
    Returns the start (normalised); ``r`` holds its distances.
    """
    gt = math.hypot(fx, fy)
    if warm:
        T = fill_distances(px, py, a, wx, wy, r)
        if s * (tn + fx * wy - fy * wx) > gt * T:
            return wx, wy
    ux = -s * fy / gt
    uy = s * fx / gt
    best = -math.inf
    best_t = _RAY[0]
    for t in _RAY:
        T = fill_distances(px, py, a, ux * t, uy * t, r)
        ratio = (t + lever) / T
        if ratio > best:
            best = ratio
            best_t = t
    fill_distances(px, py, a, ux * best_t, uy * best_t, r)
    return ux * best_t, uy * best_t


@njit(**JIT)
def _dinkelbach(px, py, a, s, tn, fx, fy, lever, warm, wx, wy, xtol, max_iter):
    """Inexact Dinkelbach on ``max_c s·ñ(c)/T̃(c)`` (normalised; see module docstring, step 4).

    Returns ``(code, cx, cy, gamma, T, n_s, iterations, residual, taxel)`` with code
    ``SOLVED_CONVERGED``, ``SOLVED_ON_TAXEL`` or ``SOLVED_MAX_ITER`` (not converged); ``T = Σ a_i|p_i − c|`` and
    ``n_s = s·ñ(c)`` at the COR; ``taxel`` indexes ``px`` (−1: none).
    """
    m = px.size
    r = np.empty(m)
    work = np.empty(m)
    bx = -s * fy
    by = s * fx
    cx, cy = _start(px, py, a, s, tn, fx, fy, lever, warm, wx, wy, r)
    T = 0.0
    for i in range(m):
        T += a[i] * r[i]
    code = SOLVED_MAX_ITER
    taxel = -1
    kink_residual = 0.0
    prev = math.inf
    it = 0
    while it < max_iter:
        it += 1
        gamma = s * (tn + fx * cy - fy * cx) / T
        cx, cy, step, outcome, kink_residual, tx, T = newton_step(px, py, a, bx / gamma, by / gamma, cx, cy, r, work)
        if outcome == STEP_ON_TAXEL:
            if tx == taxel:
                code = SOLVED_ON_TAXEL
                break
            taxel = tx
            continue
        taxel = -1
        if outcome == STEP_STALLED or step_converged(step, prev, cx, cy, xtol):
            code = SOLVED_CONVERGED
            break
        prev = step
    n_s = s * (tn + fx * cy - fy * cx)
    gamma = n_s / T
    if code == SOLVED_ON_TAXEL:
        residual = kink_residual
    else:
        gx = bx
        gy = by
        for i in range(m):
            if r[i] > 0.0:
                w = gamma * a[i] / r[i]
                gx -= w * (cx - px[i])
                gy -= w * (cy - py[i])
        residual = math.hypot(gx, gy) / gamma
        if residual > _MAX_RESIDUAL:  # a small step far from stationarity is no convergence
            code = SOLVED_MAX_ITER
    return code, cx, cy, gamma, T, n_s, it, residual, taxel


def _point_contact(n_bar, tau, fx, fy, pbar, gt, taxel) -> LimitSetResult:
    """All force on one taxel: no torsional friction about it (docs/math.md §4.4)."""
    scale = abs(tau) + math.hypot(fx, fy) * math.hypot(pbar[0], pbar[1])
    if abs(n_bar) <= 1e-12 * scale:
        return LimitSetResult(SlipCase.TRANSLATION, float(gt), None, 0.0, 0.0, 0, 0, 0.0, SolverStatus.TRANSLATION,
                              -1, (float(pbar[0]), float(pbar[1])))
    p_c = (float(pbar[0]), float(pbar[1]))
    sense = 1 if n_bar > 0 else -1
    return LimitSetResult(
        SlipCase.ON_TAXEL, math.inf, p_c, 0.0, float(n_bar), sense, 0, 0.0, SolverStatus.POINT_CONTACT, taxel, p_c
    )


def _pure_torque(positions, phi, tn, tau, pbar, L, cap, f_n, c0) -> LimitSetResult:
    """``f_t = 0``: the COR is the weighted geometric median, γ = |τ|/T_min."""
    med = geometric_median(positions, phi, c0)
    if med.c is None:
        return _none(med.status)
    T = cap / f_n * med.value
    gamma = abs(tau) / T if T > 0.0 else math.inf
    if not math.isfinite(gamma):  # the torsional capacity underflows (ZeroDivisionError before)
        return _none(SolverStatus.INVALID_INPUT)
    sense = 1 if tau > 0 else -1
    case = SlipCase.ON_TAXEL if med.status is SolverStatus.ON_TAXEL else SlipCase.ROTATION
    return LimitSetResult(
        case, gamma, med.c, T, tau, sense, med.iterations, med.residual, med.status, med.taxel, pbar, L
    )


@dataclass(frozen=True, slots=True)
class TorsionResult:
    """Torsional coefficient from tactile data (docs/math.md §4.3).

    Attributes:
        beta_m: ``β_s = μ·min_c Σ φ_i|p_i − c| / f_n`` (m); 0 for a point contact.
        median: the weighted geometric median (m, F), ``None`` without contact.
        status: from the geometric-median solve (ON_TAXEL for a point contact).
    """

    beta_m: float
    median: tuple[float, float] | None
    status: SolverStatus


def torsional_coefficient(
    phi: np.ndarray, positions: np.ndarray, mu: float, c0: tuple[float, float] | None = None
) -> TorsionResult:
    """``β_s`` from the pressure alone: the pure-torque capacity divided by ``f_n``.

    The Weber solver validates the input and keeps the taxels in contact itself
    (INVALID_INPUT, NO_CONTACT as its status).
    """
    if not (math.isfinite(mu) and mu > 0):
        return TorsionResult(0.0, None, SolverStatus.INVALID_INPUT)
    med = geometric_median(positions, phi, c0)
    if med.c is None:
        return TorsionResult(0.0, None, med.status)
    ph = np.asarray(phi, dtype=float)
    return TorsionResult(mu * med.value / float(np.add.reduce(ph[ph > 0])), med.c, med.status)  # ph[ph > 0].sum()


def compile_kernels() -> None:
    """Compile the numba kernels of :func:`load_factor` and the Weber solver, or load
    them from the cache (about 0.05 s; 5 s the first time after an install).

    Nodes call it in ``start`` (before they report ready), so their first frame runs at full
    speed; building a node object (the launcher does, to check parameters) does not. The
    kernels take every array read-only (:func:`~slipstack.lib.weber.kernel_input`), so one
    specialisation each is all a node can need.
    """
    square = np.array([[0.0, 0.0], [1e-3, 0.0], [0.0, 1e-3], [1e-3, 1e-3]])
    weights = np.array([1.0, 2.0, 3.0, 4.0])
    load_factor(weights, square, (0.1, 0.2), 1e-4, 0.5, c0=(5e-4, 5e-4))  # Dinkelbach, warm
    load_factor(weights, square, (0.1, 0.2), 1e-4, 0.5)  # Dinkelbach, ray start
    torsional_coefficient(weights, square, 0.5)  # the Weber solver
