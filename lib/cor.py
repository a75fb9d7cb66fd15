"""Centre of rotation (COR) for the paper's tactile slip test (11)+(12).

The paper's test (11) at a point ``p_c`` (pad frame F, m) is::

    |n(p_c)| ≤ T(p_c),   n(c) = τ + f_t × c,   T(c) = μ Σ φ_i |p_i − c|,

with ``p_c`` the solution of (12), ``∇_c (n − T) = 0``, i.e.::

More in docs/modules.md, `lib/cor.py`.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass

import numpy as np

from slipstack.lib.limit_set import contact_subset
from slipstack.lib.status import SlipCase, SolverStatus
from slipstack.lib.weber import solve_weber

__all__ = ["CorResult", "paper_cor", "robust_cor", "cor_equations"]

_SMALLEST_NORMAL = sys.float_info.min
"""N: a friction capacity μΣφ below this (subnormal) is no measured force."""


@dataclass(frozen=True, slots=True)
class CorResult:
    """A COR of (12) and the quantities of test (11) there (F, SI).

    Attributes:
        case: ROTATION, ON_TAXEL, TRANSLATION (``|f_t| ≥ μ f_n``: no finite COR), NONE.
        p_c: the COR (m) or ``None``.
        load_torque: ``n(p_c)`` (N·m, signed); 0 without a COR.
        torque_capacity: ``T(p_c)`` (N·m); 0 without a COR.
        ratio: test-(11) load factor analogue: ``|n(p_c)|/T(p_c)``, or
            ``|f_t|/(μ f_n)`` for TRANSLATION; stick iff ``ratio ≤ 1``.
            ``+inf`` only for a point contact with torque about it.
        sense: +1 / −1 the sense of the reported maximiser (0 if none).
        iterations: solver steps.
        residual: ``|F(p_c)|/(μ f_n)`` (dimensionless) or the Kuhn excess on a taxel.
        status: see :class:`SolverStatus`.
    """

    case: SlipCase
    p_c: tuple[float, float] | None
    load_torque: float
    torque_capacity: float
    ratio: float
    sense: int
    iterations: int
    residual: float
    status: SolverStatus

    @property
    def stick(self) -> bool:
        """Test (11): ``|n(p_c)| ≤ T(p_c)`` (and no translation)."""
        return self.ratio <= 1.0


def _invalid(status: SolverStatus) -> CorResult:
    return CorResult(SlipCase.NONE, None, 0.0, 0.0, 0.0, 0, 0, 0.0, status)


def _load_terms(P: np.ndarray, ph: np.ndarray, ft: np.ndarray, tau: float, mu: float, c: np.ndarray):
    n = tau + ft[0] * c[1] - ft[1] * c[0]
    T = mu * float(ph @ np.hypot(*(P - c).T))
    return n, T


def cor_equations(
    c: np.ndarray, phi: np.ndarray, positions: np.ndarray, f_t: np.ndarray, mu: float
) -> tuple[np.ndarray, np.ndarray]:
    """Residual and Jacobian of (12) at ``c``: ``F = perp(f_t) − μΣφ(c−p)/r``, ``J = −μΣφ(I/r − dd^T/r³)``.

    Args: ``c`` (2,) m; ``phi`` (m,) N; ``positions`` (m, 2) m; ``f_t`` (2,) N.
    Returns ``(F (2,) N, J (2, 2) N/m)``; non-finite when ``c`` is on a taxel.
    """
    d = c - positions
    r = np.hypot(d[:, 0], d[:, 1])
    w = mu * phi / r
    F = np.array([-f_t[1], f_t[0]]) - d.T @ w
    J = -(np.sum(w) * np.eye(2) - (d * (w / r**2)[:, None]).T @ d)
    return F, J


def _validate(phi, positions, f_t, tau, mu):
    sub = contact_subset(phi, positions)
    ft = np.asarray(f_t, dtype=float).reshape(-1)
    if sub is None or ft.shape != (2,) or not np.isfinite(ft).all() or not math.isfinite(tau):
        return None
    if not (math.isfinite(mu) and mu > 0):
        return None
    return sub[0], sub[1], sub[2], ft


def _translation_ratio(ph, ft, mu) -> float:
    """``|f_t| / (μ Σφ)``: the load over the contact's translational capacity."""
    return math.hypot(ft[0], ft[1]) / (mu * float(ph.sum()))


def _translation(ratio_t: float) -> CorResult:
    """Pure translation (the COR at infinity) with the translational load ratio."""
    return CorResult(SlipCase.TRANSLATION, None, 0.0, 0.0, ratio_t, 0, 0, 0.0, SolverStatus.TRANSLATION)


def _measurable(ph, mu) -> bool:
    """Whether the friction capacity ``μΣφ`` is a normal finite number: a subnormal one is no
    force a sensor measures (its ratios are rounding noise or overflow), an overflowing one
    makes every ratio 0."""
    with np.errstate(over="ignore"):
        capacity = mu * float(ph.sum())
    return _SMALLEST_NORMAL <= capacity < math.inf


def _in_float_range(res: CorResult) -> CorResult:
    """``res``, or INVALID_INPUT when its ratio overflowed (only a point contact's may be +inf)."""
    if math.isfinite(res.ratio) or res.status is SolverStatus.POINT_CONTACT:
        return res
    return _invalid(SolverStatus.INVALID_INPUT)


def _special(ph, P, ft, tau, mu) -> CorResult | None:
    """No contact, a pad without a measurable force (invalid), no load, translation and point
    contact: answered without iterating."""
    if ph.size == 0:
        return _invalid(SolverStatus.NO_CONTACT)
    if not _measurable(ph, mu):
        return _invalid(SolverStatus.INVALID_INPUT)
    if ft[0] == 0.0 and ft[1] == 0.0 and tau == 0.0:
        return _invalid(SolverStatus.NO_LOAD)
    ratio_t = _translation_ratio(ph, ft, mu)
    if ratio_t >= 1.0:
        return _translation(ratio_t)
    if ph.size == 1:
        n, _ = _load_terms(P, ph, ft, tau, mu, P[0])
        ratio = math.inf if n != 0.0 else ratio_t
        sense = int(n > 0) - int(n < 0)
        pc = (float(P[0, 0]), float(P[0, 1]))
        return CorResult(SlipCase.ON_TAXEL, pc, float(n), 0.0, ratio, sense, 0, 0.0, SolverStatus.POINT_CONTACT)
    return None


def _prepare(phi, positions, f_t, tau, mu) -> CorResult | tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The taxels in contact ``(φ, P, f_t)``, or the answer when no iteration is needed
    (invalid input, no contact, no load, translation, point contact)."""
    v = _validate(phi, positions, f_t, tau, mu)
    if v is None:
        return _invalid(SolverStatus.INVALID_INPUT)
    _, ph, P, ft = v
    special = _special(ph, P, ft, tau, mu)
    return _in_float_range(special) if special is not None else (ph, P, ft)


def paper_cor(
    phi: np.ndarray,
    positions: np.ndarray,
    f_t: np.ndarray | tuple[float, float],
    tau: float,
    mu: float,
    *,
    gain: float = 0.5,
    c0: np.ndarray | tuple[float, float] | None = None,
    xtol: float = 1e-7,
    max_iter: int = 200,
) -> CorResult:
    """The paper's fixed-gain Jacobian iteration for (12), then test (11).

    Args:
        phi: (N,) normal force per taxel (N); positions: (N, 2) m in F.
        f_t: (2,) N; tau: N·m about the pad origin; mu: friction coefficient.
        gain: the fixed gain ``h`` (0 < h ≤ 1).
        c0: start point (m); the centre of pressure if ``None``.
        xtol: stop when ``|h J⁻¹F|`` < ``xtol`` × RMS contact radius.
        max_iter: iteration limit.

    Returns:
        :class:`CorResult` for the sense ``s = +1``. Status SINGULAR when an iterate
        lands on a taxel that fails the paper's special-case test or J is singular,
        DIVERGED when the iterate becomes non-finite, MAX_ITER otherwise.
    """
    prepared = _prepare(phi, positions, f_t, tau, mu)
    if isinstance(prepared, CorResult):
        return prepared
    ph, P, ft = prepared
    cap = mu * float(ph.sum())
    pbar = ph @ P / float(ph.sum())
    L = math.sqrt(float(ph @ np.sum((P - pbar) ** 2, axis=1)) / float(ph.sum()))
    c = pbar.copy() if c0 is None else np.asarray(c0, dtype=float).reshape(2)
    status = SolverStatus.MAX_ITER
    F = np.full(2, np.inf)
    it = 0
    # a pad near the top of float range overflows in (12); the non-finite results are the
    # statuses below (SINGULAR, DIVERGED), not warnings
    with np.errstate(over="ignore", invalid="ignore"):
        for it in range(1, max_iter + 1):
            r = np.hypot(*(c - P).T)
            j = int(r.argmin())
            if r[j] == 0.0:
                rest = np.ones(ph.size, dtype=bool)
                rest[j] = False
                Fj, _ = cor_equations(c, ph[rest], P[rest], ft, mu)
                if math.hypot(*Fj) <= mu * ph[j]:  # the paper's on-taxel condition
                    status = SolverStatus.ON_TAXEL
                    F = np.zeros(2)
                else:
                    status = SolverStatus.SINGULAR
                break
            F, J = cor_equations(c, ph, P, ft, mu)
            det = np.linalg.det(J)
            if not math.isfinite(det) or abs(det) <= 1e-300:
                status = SolverStatus.SINGULAR
                break
            step = gain * np.linalg.solve(J, F)
            c = c - step
            if not np.isfinite(c).all() or math.hypot(*(c - pbar)) > 1e12 * L:
                status = SolverStatus.DIVERGED
                break
            if math.hypot(*step) <= xtol * L:
                status = SolverStatus.CONVERGED
                F, _ = cor_equations(c, ph, P, ft, mu)
                break
    if not np.isfinite(c).all():
        return CorResult(SlipCase.NONE, None, 0.0, 0.0, 0.0, 0, it, math.inf, status)
    n, T = _load_terms(P, ph, ft, tau, mu, c)
    ratio = abs(n) / T if T > 0 else math.inf
    case = SlipCase.ON_TAXEL if status is SolverStatus.ON_TAXEL else SlipCase.ROTATION
    residual = math.hypot(*F) / cap if np.isfinite(F).all() else math.inf
    return _in_float_range(
        CorResult(case, (float(c[0]), float(c[1])), float(n), float(T), float(ratio), 1, it, residual, status))


def robust_cor(
    phi: np.ndarray,
    positions: np.ndarray,
    f_t: np.ndarray | tuple[float, float],
    tau: float,
    mu: float,
    *,
    c0: np.ndarray | tuple[float, float] | None = None,
    xtol: float = 1e-9,
    max_iter: int = 100,
) -> CorResult:
    """Maximise ``g_s = s·n − T`` for ``s = ±1`` (safeguarded Newton + Kuhn), then test (11).

    Args: as :func:`paper_cor`; ``c0`` warm-starts both senses.

    Returns:
        :class:`CorResult` for the sense with the larger ``max g_s`` (the binding
        one); ``ratio = |n(p_c)|/T(p_c)`` there, so stick iff ``ratio ≤ 1``.
    """
    prepared = _prepare(phi, positions, f_t, tau, mu)
    if isinstance(prepared, CorResult):
        return prepared
    ph, P, ft = prepared
    best = None
    iterations = 0
    for s in (1, -1):
        res = solve_weber(P, mu * ph, (-s * ft[1], s * ft[0]), c0, xtol=xtol, max_iter=max_iter)
        iterations += res.iterations
        if res.status is SolverStatus.TRANSLATION:
            # |f_t| reaches μΣφ to rounding: the Weber minimum runs off to infinity although
            # the ratio computed above came out a rounding step below 1. Translation, at
            # that ratio (not 0, which would read as "no load": stick with margin 1).
            return _translation(_translation_ratio(ph, ft, mu))
        if res.c is None:
            return _invalid(res.status)
        g = s * tau - res.value  # max_c g_s = s·τ − min_c (T − s·perp(f_t)·c)
        if best is None or g > best[0]:
            best = (g, s, res)
    _, s, res = best
    c = np.array(res.c)
    n, T = _load_terms(P, ph, ft, tau, mu, c)
    case = SlipCase.ON_TAXEL if res.status is SolverStatus.ON_TAXEL else SlipCase.ROTATION
    return _in_float_range(CorResult(
        case, res.c, float(n), float(T), float(abs(n) / T), s, iterations, res.residual, res.status
    ))
