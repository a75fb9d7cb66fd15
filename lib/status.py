"""Outcome codes shared by every slipstack solver (docs/architecture.md §10.1).

Solvers in ``lib/`` never raise inside the control loop: they return a frozen
result with a :class:`SolverStatus`, whose :attr:`~SolverStatus.message` says in
words what happened, and :attr:`~SolverStatus.usable` whether the numbers in the
result may be acted on.
"""

from __future__ import annotations

import enum

__all__ = ["SolverStatus", "SlipCase"]


class SolverStatus(enum.Enum):
    """Outcome of a solver or of fusion. The value is a stable lower-case name."""

    OK = "ok"
    CONVERGED = "converged"
    ON_TAXEL = "on_taxel"
    TRANSLATION = "translation"
    POINT_CONTACT = "point_contact"
    NO_LOAD = "no_load"
    NO_CONTACT = "no_contact"
    CLIPPED_INPUT = "clipped_input"
    MAX_ITER = "max_iter"
    SINGULAR = "singular"
    DIVERGED = "diverged"
    INVALID_INPUT = "invalid_input"

    @property
    def message(self) -> str:
        """A human-readable explanation of the status."""
        return _MESSAGES[self]

    @property
    def usable(self) -> bool:
        """True when the result's numbers are exact answers to the posed problem."""
        return self in _USABLE


_MESSAGES = {
    SolverStatus.OK: "ok: direct computation, inputs valid",
    SolverStatus.CONVERGED: "converged: step below the relative tolerance xtol",
    SolverStatus.ON_TAXEL: (
        "converged at a taxel: the optimum is a kink, certified by the subgradient "
        "(Kuhn) test |R_j| <= weight_j"
    ),
    SolverStatus.TRANSLATION: (
        "translation: |f_t| >= gamma*mu*f_n or the load passes through the centre of "
        "pressure, so there is no finite centre of rotation"
    ),
    SolverStatus.POINT_CONTACT: (
        "point contact: all normal force on one taxel, so there is no torsional "
        "friction about that taxel"
    ),
    SolverStatus.NO_LOAD: "no load: f_t = 0 and tau = 0, stick with margin 1",
    SolverStatus.NO_CONTACT: (
        "no contact: f_n or the pressure sum is not above its threshold; no friction capacity"
    ),
    SolverStatus.CLIPPED_INPUT: (
        "input clipped: non-finite or negative taxel values were set to 0 (see counts)"
    ),
    SolverStatus.MAX_ITER: "iteration limit reached before the tolerance was met",
    SolverStatus.SINGULAR: (
        "singular Jacobian: an iterate fell on a taxel (1/r blows up), the method cannot continue"
    ),
    SolverStatus.DIVERGED: "diverged: the iterate left the finite range or produced NaN",
    SolverStatus.INVALID_INPUT: "invalid input: non-finite load, mu <= 0, shape mismatch, or load/capacity ratio beyond float range",
}

_USABLE = frozenset(
    {
        SolverStatus.OK,
        SolverStatus.CONVERGED,
        SolverStatus.ON_TAXEL,
        SolverStatus.TRANSLATION,
        SolverStatus.POINT_CONTACT,
        SolverStatus.NO_LOAD,
        SolverStatus.NO_CONTACT,
        SolverStatus.CLIPPED_INPUT,
    }
)


class SlipCase(enum.Enum):
    """Which motion the contact would make at impending slip (ARCHITECTURE ``cor.case``)."""

    ROTATION = "rotation"
    TRANSLATION = "translation"
    ON_TAXEL = "on-taxel"
    NONE = "none"
