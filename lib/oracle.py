"""The oracle grip: the least normal force that holds a known load (docs/math.md §4.1).

Benchmarks compare a grip law's force with this lower bound, computed from the
*true* pressure and load (e.g. the simulated rig's), not from sensor data.

More in docs/modules.md, `lib/oracle.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from slipstack.lib.limit_set import load_factor
from slipstack.lib.status import SolverStatus

__all__ = ["OracleForce", "oracle_normal_force", "least_holding_force"]


@dataclass(frozen=True)
class OracleForce:
    """Least normal force that holds a load.

    Attributes:
        f_n_min: least holding normal force, N. 0 with no load; ``+inf`` when no force
            can hold it (point contact under torque); NaN when the input is invalid,
            there is no contact to scale, or the solver failed (see ``status``).
        gamma: load factor γ at the last force evaluated (dimensionless).
        status: the limit-set solver's status at the last evaluation, or MAX_ITER /
            DIVERGED from the fixed-point iteration of :func:`least_holding_force`.
        iterations: load-factor evaluations used.
    """

    f_n_min: float
    gamma: float
    status: SolverStatus
    iterations: int = 1

    @property
    def usable(self) -> bool:
        """True when ``f_n_min`` is an exact answer (finite or a certified ``inf``)."""
        return self.status.usable and not math.isnan(self.f_n_min)


def _from_gamma(gamma: float, f_n: float, status: SolverStatus, iterations: int) -> OracleForce:
    if status is SolverStatus.NO_LOAD:
        return OracleForce(0.0, 0.0, status, iterations)
    if not status.usable or status is SolverStatus.NO_CONTACT:  # nothing to scale
        return OracleForce(math.nan, gamma, status, iterations)
    return OracleForce(math.inf if math.isinf(gamma) else gamma * f_n, gamma, status, iterations)


def oracle_normal_force(
    phi: np.ndarray,
    positions: np.ndarray,
    f_t: np.ndarray | tuple[float, float],
    tau: float,
    mu: float,
) -> OracleForce:
    """``f_n* = γ·f_n`` for a pressure shape that scales with the force.

    Args:
        phi: (N,) true normal force per taxel, N, ``φ_i ≥ 0``; ``f_n = Σ φ_i``.
        positions: (N, 2) taxel positions in F, m.
        f_t: (2,) true tangential load in F, N.
        tau: true torque about z through the pad origin, N·m.
        mu: static friction coefficient ``μ_s`` (> 0).

    Returns:
        :class:`OracleForce` (uniform pressure, pure force: ``f_n* = |f_t|/μ``).
    """
    res = load_factor(phi, positions, f_t, tau, mu)
    f_n = float(np.sum(phi)) if res.status.usable else math.nan
    return _from_gamma(res.gamma, f_n, res.status, 1)


def least_holding_force(
    phi_of_f: Callable[[float], np.ndarray],
    positions: np.ndarray,
    f_t: np.ndarray | tuple[float, float],
    tau: float,
    mu: float,
    f_start: float,
    *,
    rtol: float = 1e-6,
    max_iter: int = 50,
) -> OracleForce:
    """Least ``f*`` with ``γ(φ(f*)) ≤ 1`` for a force-dependent pressure shape.

    Iterates ``f_{k+1} = γ(φ(f_k))·f_k`` from ``f_start`` until the relative change
    is ≤ ``rtol``. For a shape that does not depend on ``f`` this stops after the
    first step at :func:`oracle_normal_force`'s answer. For a Hertzian contact the
    map has slope between −1/3 (pure torque) and 0 (pure force) at the fixed point,
    so the error shrinks at least threefold per step. Every evaluation also narrows a
    bracket ``lo < f* ≤ hi`` (``γ > 1`` at ``lo``, ``≤ 1`` at ``hi``); when a step
    leaves the bracket or does not halve the previous one — a sampled shape jumps
    where a taxel enters the contact, and the plain iteration then oscillates — the
    next force is the bracket's midpoint, and the answer is ``hi`` once the bracket
    is within ``rtol``. A point contact under torque (``γ = inf``, e.g. a tiny
    Hertzian contact inside one taxel) counts as not holding; if it occurs before
    any force was found that holds, the answer is ``inf`` with POINT_CONTACT.

    Args:
        phi_of_f: ``f ↦ φ`` (N,) per-taxel normal forces (N) summing to ``f`` (N),
            the true pressure at normal force ``f`` and the current object pose.
        positions: (N, 2) taxel positions in F, m.
        f_t, tau, mu: as :func:`oracle_normal_force`.
        f_start: first force to evaluate, N (> 0), e.g. the force now applied.
        rtol: relative tolerance on ``f*``.
        max_iter: limit on load-factor evaluations.

    Returns:
        :class:`OracleForce` with ``γ`` at the returned force (to first order in
        ``rtol``); MAX_ITER (not usable) if neither test met ``rtol`` in time.
    """
    f = float(f_start)
    if not (math.isfinite(f) and f > 0.0):
        return OracleForce(math.nan, math.nan, SolverStatus.INVALID_INPUT, 0)
    lo, hi, at_hi = 0.0, math.inf, None
    step = math.inf
    for k in range(1, max_iter + 1):
        r = oracle_normal_force(phi_of_f(f), positions, f_t, tau, mu)
        if not r.usable or r.f_n_min == 0.0 or (math.isinf(r.f_n_min) and hi == math.inf):
            return OracleForce(r.f_n_min, r.gamma, r.status, k)  # invalid, no load, or never holds
        if r.gamma > 1.0:
            lo = max(lo, f)
        else:
            hi, at_hi = f, r
        f_next = r.f_n_min
        if math.isfinite(f_next) and abs(f_next - f) <= rtol * f_next:
            return OracleForce(f_next, r.gamma, r.status, k)
        if at_hi is not None and hi - lo <= rtol * hi:
            return OracleForce(hi, at_hi.gamma, at_hi.status, k)
        if not (lo < f_next < hi and abs(f_next - f) <= 0.5 * step):
            f_next = 0.5 * (lo + hi) if hi < math.inf else f_next
        step, f = abs(f_next - f), f_next
    return OracleForce(f, math.nan, SolverStatus.MAX_ITER, max_iter)
