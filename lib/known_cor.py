"""Test (11) about a known centre of rotation (the paper's Fig. 13).

When the object can only turn about a fixed pivot ``p_c`` (a motor shaft), the paper
does not solve (12) for the COR: it evaluates test (11) about the pivot directly::

    |n(p_c)| ≤ T(p_c),   n(p_c) = τ + f_t × p_c,   T(p_c) = μ Σ φ_i |p_i − p_c|

More in docs/modules.md, `lib/known_cor.py`.
"""

from __future__ import annotations

import math

import numpy as np

from slipstack.lib.errors import ConfigError
from slipstack.lib.slip_tests import ContactLike, SlipParams, SlipTest, SlipVerdict
from slipstack.lib.status import SolverStatus

__all__ = ["KNOWN_COR_METHOD", "known_cor_test"]

KNOWN_COR_METHOD = "tactile_cor_known"
"""The detector method name of test (11) about a known pivot."""


def known_cor_test(pivot_m: tuple[float, float]) -> SlipTest:
    """The slip test (11) about the fixed ``pivot_m`` (x, y in m, pad frame F).

    Raises ConfigError for a pivot that is not two finite numbers. The test never
    raises on data: non-finite input is ``invalid_input``, no pressure or ``f_n ≤ 0``
    is ``no-contact``, all pressure on the pivot itself with a torque about it is
    ``point_contact`` with ``γ = +inf``.
    """
    try:
        cx, cy = (float(v) for v in pivot_m)
    except (TypeError, ValueError):
        raise ConfigError(f"known COR must be (x, y) in m, got {pivot_m!r}") from None
    if not (math.isfinite(cx) and math.isfinite(cy)):
        raise ConfigError(f"known COR must be finite (x, y) in m, got {pivot_m!r}")
    pivot = (cx, cy)

    def test(contact: ContactLike, params: SlipParams, warm_start=None) -> SlipVerdict:
        phi = np.asarray(contact.phi, dtype=float)
        load = (float(contact.f_n), float(contact.f_t[0]), float(contact.f_t[1]), float(contact.tau))
        if not all(math.isfinite(v) for v in load) or not np.isfinite(phi).all():
            return _answer(params, 0.0, SolverStatus.INVALID_INPUT, None, contact=False)
        f_n, fx, fy, tau = load
        touching = phi > 0
        if not f_n > 0 or not touching.any():
            return _answer(params, 0.0, SolverStatus.NO_CONTACT, None, contact=False)
        n = tau + fx * cy - fy * cx
        p = np.asarray(contact.positions, dtype=float)[touching]
        capacity = params.mu * float(phi[touching] @ np.hypot(p[:, 0] - cx, p[:, 1] - cy))
        if n == 0.0:
            return _answer(params, 0.0, SolverStatus.NO_LOAD, pivot)
        if capacity == 0.0:
            return _answer(params, math.inf, SolverStatus.POINT_CONTACT, pivot)
        return _answer(params, abs(n) / capacity, SolverStatus.OK, pivot)

    return test


def _answer(params: SlipParams, gamma: float, status: SolverStatus, p_c, *, contact: bool = True) -> SlipVerdict:
    if not contact:
        return SlipVerdict(False, 0.0, "no-contact", status, 0.0, None, KNOWN_COR_METHOD)
    margin = 1.0 - gamma
    stick = status.usable and margin >= params.delta
    return SlipVerdict(stick, margin, "stick" if stick else "rotation", status, gamma, p_c, KNOWN_COR_METHOD)
