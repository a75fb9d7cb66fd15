"""The vocabularies of slipstack: solver outcomes, slip cases and states, COR solvers
(docs/architecture.md §10.1).

Solvers in ``lib/`` never raise inside the control loop: they return a frozen
result with a :class:`SolverStatus`, whose :attr:`~SolverStatus.message` says in
words what happened, and :attr:`~SolverStatus.usable` whether the numbers in the
result may be acted on.

More in docs/modules.md, `lib/status.py`.
"""

from __future__ import annotations

import enum

__all__ = ["SolverStatus", "SlipCase", "SlipState", "SLIP_STATES", "CorSolver", "SAMPLE_OK", "SAMPLE_NO_CONTACT",
           "SAMPLE_UNUSABLE"]

SAMPLE_OK, SAMPLE_NO_CONTACT, SAMPLE_UNUSABLE = 0, 1, 2
"""What an earlier F/T sample of a batch was (the ``contact`` message's ``earlier_status``):
its own contact would have been ``ok``, ``no_contact`` (usable data, nothing pressed), or
anything else (unusable: stale, disconnected, a device status, implausible …; any other
code reads as unusable)."""


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


class SlipCase(enum.StrEnum):
    """Which motion the contact would make at impending slip (the ``cor`` topic's ``case``)."""

    ROTATION = "rotation"
    TRANSLATION = "translation"
    ON_TAXEL = "on-taxel"
    NONE = "none"


class SlipState(enum.StrEnum):
    """The detector's verdict on the contact: the ``slip`` topic's ``state``, and the
    ``kind`` of one slip test's verdict."""

    STICK = "stick"
    TRANSLATION = "translation"
    ROTATION = "rotation"
    COMBINED = "combined"
    NO_CONTACT = "no-contact"


SLIP_STATES = frozenset({SlipState.TRANSLATION, SlipState.ROTATION, SlipState.COMBINED})
"""The states of slip (a plain string of one of these values is a member too)."""


class CorSolver(enum.StrEnum):
    """How the COR of impending slip is found (docs/math.md §3–4): ``cor_estimator``'s
    ``solver``. The tactile slip tests of ``lib/slip_tests.py`` use one each:
    ``exact`` the exact solver, ``tactile_cor_robust`` the robust one, ``tactile_cor``
    the paper's."""

    EXACT = "exact"
    """the exact limit set: Dinkelbach load factor with Fermat–Weber steps."""
    ROBUST = "robust"
    """the paper's (12) solved robustly (the maximiser over both senses)."""
    PAPER = "paper"
    """the paper's fixed-gain iteration for (12)."""
