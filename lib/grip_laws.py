"""Grip-force laws of the paper's §V (docs/math.md §5), bounds, rate limit and fail-safe.

Every law maps one control step's load to a desired normal force ``f_n`` (N) on the
pad, bounded to ``[f_nom, f_max]``:

More in docs/modules.md, `lib/grip_laws.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum
from typing import ClassVar, Literal, Mapping, Sequence

from slipstack.lib.defaults import MU
from slipstack.lib.errors import ConfigError
from slipstack.lib.status import SLIP_STATES, SlipCase, SlipState

__all__ = [
    "GripReason",
    "GripDecision",
    "GripInput",
    "bound_demand",
    "linear_demand",
    "ft13_demand",
    "ft13_sigma_demand",
    "tactile14_increment",
    "exact_demand",
    "cone_margin_demand",
    "GripLaw",
    "LinearLaw",
    "Ft13Law",
    "Ft13SigmaLaw",
    "Tactile14Law",
    "ExactLaw",
    "ConeMarginLaw",
    "LAWS",
    "make_law",
    "RateLimiter",
    "FingerReport",
    "GripGovernor",
    "NOT_OK",
]

_NAN = float("nan")
NOT_OK = "input status not ok"
"""The fail-safe cause of a step whose caller said its input is not ok (``status_ok`` false)."""


class GripReason(str, Enum):
    """Why the command has its value (compares equal to its string value)."""

    NOMINAL = "nominal"  # the law asks for no more than f_nom
    SLIP = "slip"  # the law asks for more than f_nom (load, failed test, raised grip held)
    SATURATED = "saturated"  # the law asks for more than f_max: clipped to f_max
    FAIL_SAFE = "fail-safe"  # invalid or stale input: last safe grip held


@dataclass(frozen=True, slots=True)
class GripDecision:
    """One grip command.

    Attributes:
        f_n_desired: commanded normal force, N (finite, never NaN).
        law: registry name of the law that produced it.
        reason: see :class:`GripReason`.
        raw: the law's demand before the ``[f_nom, f_max]`` bounds and the rate limit,
            N (``inf`` when a division by a zero capacity asks for unbounded force;
            in fail-safe the value commanded).
        detail: human-readable cause for ``"fail-safe"`` (which input, which limit).
    """

    f_n_desired: float
    law: str
    reason: GripReason
    raw: float
    detail: str = ""


@dataclass(frozen=True, slots=True)
class GripInput:
    """Everything a law may need for one control step; unused fields may stay NaN.

    Attributes:
        f_t: tangential load ``(f_x, f_y)`` in ``F``, N.
        tau: torque about ``z`` through the pad origin, N·m.
        f_n: normal force now applied (measured by fusion), N — used by ``tactile14``
            (the value it raises or holds) and ``exact`` (the force ``γ`` refers to).
        gamma: load factor ``γ`` (docs/math.md §4.1) at ``f_n``, dimensionless.
        n_c: ``n(p_c) = τ + f_t × p_c``, torque of the load about the COR, N·m.
        t_c: ``T(p_c) = μ Σ φ_i |p_i − p_c|``, resistible torque about the COR, N·m.
        sum_dist_m: ``Σ_{i∈A} |p_i − p_c|`` over the taxels in contact, m.
        n_contact: ``N_A``, number of taxels in contact.
        cor_case: the COR estimator's case for this contact (``lib/cor.py``):
            ``rotation`` or ``on-taxel`` (a COR about which the contact would rotate:
            ``n_c``, ``t_c``, ``sum_dist_m`` refer to it), ``translation`` or ``none``
            (no COR: test (11) cannot fail by rotation). Used by ``tactile14``.
        slip_state: the slip detector's latched state (``stick``, ``no-contact`` or a
            slip kind); decides the level at which ``tactile14`` counts (11) as failing.
        demand_n: a squeeze computed outside these laws (the two-finger grasp node's,
            ``lib/grasp.py: SqueezeLaw``), N.
    """

    f_t: tuple[float, float] = (_NAN, _NAN)
    tau: float = _NAN
    f_n: float = _NAN
    gamma: float = _NAN
    n_c: float = _NAN
    t_c: float = _NAN
    sum_dist_m: float = _NAN
    n_contact: int = 0
    cor_case: str = SlipCase.ROTATION
    slip_state: str = SlipState.STICK
    demand_n: float = _NAN

    @property
    def f_t_abs(self) -> float:
        """``|f_t|`` in N (NaN if a component is NaN)."""
        return math.hypot(float(self.f_t[0]), float(self.f_t[1]))


# ---------------------------------------------------------------- the formulas


def linear_demand(f_t_abs: float, mu: float, sigma: float) -> float:
    """§V-A: least safe ``f_n = |f_t| / (σ μ)`` in N, before bounds."""
    return f_t_abs / (sigma * mu)


def ft13_demand(f_t_abs: float, tau_abs: float, mu: float, beta_m: float, k_n: float) -> float:
    """Paper (13): ``f_n = |f_t|/μ + |τ|/β + k`` in N (``τ`` N·m, ``β`` m, ``k`` N)."""
    return f_t_abs / mu + tau_abs / beta_m + k_n


def ft13_sigma_demand(f_t_abs: float, tau_abs: float, mu: float, beta_m: float, sigma: float) -> float:
    """Fig. 12 variant of (13): ``f_n = (|f_t|/μ + |τ|/β) / σ`` in N."""
    return (f_t_abs / mu + tau_abs / beta_m) / sigma


def tactile14_increment(
    n_c: float,
    t_c: float,
    sum_dist_m: float,
    n_contact: int,
    mu: float,
    sigma: float,
    increment: Literal["total", "per_taxel"] = "total",
) -> float:
    """Paper (14): normal-force increment that makes test (11) hold again, N.

    Adding ``δφ`` to each of the ``N_A`` taxels in contact raises the resistible
    torque about ``p_c`` by ``μ δφ Σ_{i∈A}|p_i − p_c|``; asking it to cover the excess
    ``|n(p_c)| − T(p_c)`` with safety factor ``σ`` gives::

        δφ   = (|n(p_c)| − T(p_c)) / (σ μ Σ_{i∈A} |p_i − p_c|)    per taxel
        δf_n = N_A · δφ                                           total

    ``increment="total"`` (default) returns ``δf_n``; ``"per_taxel"`` returns ``δφ``,
    the quantity the paper prints under the name ``δf_n``. ``|n|`` is used so that
    both senses of rotation count (docs/math.md §4.2). Returns 0 when (11) holds and
    ``inf`` when it fails with no lever arm (``Σ|p_i − p_c| = 0``: point contact,
    no torsional capacity can be bought by squeezing).
    """
    excess = abs(n_c) - t_c
    if not excess > 0.0:
        return 0.0
    lever = sigma * mu * sum_dist_m  # may underflow to 0 for a subnormal distance sum
    if not lever > 0.0:
        return math.inf
    dphi = excess / lever
    return dphi * n_contact if increment == "total" else dphi


def exact_demand(gamma: float, f_n: float, sigma: float) -> float:
    """``f_n* / σ = γ f_n / σ`` in N: least holding force with margin (docs/math.md §4.1)."""
    return gamma * f_n / sigma


def cone_margin_demand(f_t_abs: float, mu: float, margin_n: float) -> float:
    """The paper's ref. [9] (docs/math.md §5): the least ``f_n`` whose force lies
    ``margin_n`` (N) inside the friction cone, ``(|f_t| + √(1+μ²)·margin_n) / μ`` in N.

    With ``d_s = (μ f_n − |f_t|)/√(1+μ²)`` the force's distance from the cone's border
    in the (|f_t|, f_n) plane and ``d_f = |f_n − f_nom|`` its distance from the nominal
    grip, this bounded below by ``f_nom`` minimises ``d_f + w/d_s`` for the weight
    ``w = margin_n² √(1+μ²)/μ``: near ``f_nom``, never nearer the cone than ``margin_n``.
    """
    return (f_t_abs + math.sqrt(1.0 + mu * mu) * margin_n) / mu


def bound_demand(raw: float, f_nom_n: float, f_max_n: float, law: str) -> GripDecision:
    """Clip a finite or ``+inf`` demand (N) to ``[f_nom, f_max]`` and classify it."""
    if raw > f_max_n:
        return GripDecision(f_max_n, law, GripReason.SATURATED, raw)
    if raw > f_nom_n:
        return GripDecision(raw, law, GripReason.SLIP, raw)
    return GripDecision(f_nom_n, law, GripReason.NOMINAL, raw)


# ---------------------------------------------------------------- laws with parameters


def _check_positive(name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0.0):
        raise ConfigError(f"grip law parameter {name} must be a finite number > 0, got {value!r}")


@dataclass(frozen=True, kw_only=True)
class GripLaw:
    """Base of the laws: the bounds ``0 ≤ f_nom_n ≤ f_max_n`` (N, ``f_max_n > 0``)."""

    name: ClassVar[str] = ""
    needs: ClassVar[tuple[str, ...]] = ()
    f_nom_n: float
    f_max_n: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.f_nom_n) and math.isfinite(self.f_max_n)
                and 0.0 <= self.f_nom_n <= self.f_max_n and self.f_max_n > 0.0):
            raise ConfigError(
                f"grip law {self.name!r} needs 0 <= f_nom_n <= f_max_n, f_max_n > 0 (N); "
                f"got f_nom_n={self.f_nom_n!r}, f_max_n={self.f_max_n!r}"
            )

    def demand(self, inp: GripInput, dt_s: float) -> float:
        """The law's unbounded demand in N (inputs already checked finite)."""
        raise NotImplementedError

    def required(self, inp: GripInput) -> tuple[str, ...]:
        """The :class:`GripInput` fields this step reads (each must be finite)."""
        return self.needs

    def decide(self, inp: GripInput, dt_s: float = 0.0) -> GripDecision:
        """Bounded decision for one step; ``dt_s`` (s) is only used by ``tactile14``."""
        bad = [k for k in self.required(inp) if not _finite(getattr(inp, k))]
        if bad:
            return GripDecision(self.f_max_n, self.name, GripReason.FAIL_SAFE, self.f_max_n,
                                f"non-finite input {', '.join(bad)}")
        raw = self.demand(inp, dt_s)
        if math.isnan(raw):  # e.g. 0·inf in exotic inputs: treat like bad input
            return GripDecision(self.f_max_n, self.name, GripReason.FAIL_SAFE, self.f_max_n,
                                "law evaluated to NaN")
        return bound_demand(raw, self.f_nom_n, self.f_max_n, self.name)


def _finite(value: object) -> bool:
    """True for a finite number or a sequence of finite numbers; False for anything else."""
    if type(value) is float:  # the common case, at every step: no list
        return math.isfinite(value)
    try:
        items = list(value) if hasattr(value, "__iter__") else [value]  # type: ignore[call-overload]
        return all(math.isfinite(float(v)) for v in items)
    except (TypeError, ValueError):
        return False


@dataclass(frozen=True, kw_only=True)
class LinearLaw(GripLaw):
    """§V-A linear σ-law. ``mu`` (μ_s), ``sigma`` in (0, 1]."""

    name: ClassVar[str] = "linear"
    needs: ClassVar[tuple[str, ...]] = ("f_t",)
    mu: float = MU
    sigma: float = 0.5

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_positive("mu", self.mu)
        _check_sigma(self.sigma)

    def demand(self, inp: GripInput, dt_s: float) -> float:
        return linear_demand(inp.f_t_abs, self.mu, self.sigma)


def _check_sigma(sigma: float) -> None:
    if not (math.isfinite(sigma) and 0.0 < sigma <= 1.0):
        raise ConfigError(f"grip law parameter sigma must be in (0, 1], got {sigma!r}")


@dataclass(frozen=True, kw_only=True)
class Ft13Law(GripLaw):
    """Paper (13). ``mu``, ``beta_m`` (m), offset ``k_n`` ≥ 0 (N, paper 2 N)."""

    name: ClassVar[str] = "ft13"
    needs: ClassVar[tuple[str, ...]] = ("f_t", "tau")
    mu: float = MU
    beta_m: float
    k_n: float = 2.0

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_positive("mu", self.mu)
        _check_positive("beta_m", self.beta_m)
        if not (math.isfinite(self.k_n) and self.k_n >= 0.0):
            raise ConfigError(f"grip law parameter k_n must be a finite force >= 0 N, got {self.k_n!r}")

    def demand(self, inp: GripInput, dt_s: float) -> float:
        return ft13_demand(inp.f_t_abs, abs(inp.tau), self.mu, self.beta_m, self.k_n)


@dataclass(frozen=True, kw_only=True)
class Ft13SigmaLaw(GripLaw):
    """Fig. 12 variant of (13). ``mu``, ``beta_m`` (m), ``sigma`` in (0, 1]."""

    name: ClassVar[str] = "ft13_sigma"
    needs: ClassVar[tuple[str, ...]] = ("f_t", "tau")
    mu: float = MU
    beta_m: float
    sigma: float = 0.5

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_positive("mu", self.mu)
        _check_positive("beta_m", self.beta_m)
        _check_sigma(self.sigma)

    def demand(self, inp: GripInput, dt_s: float) -> float:
        return ft13_sigma_demand(inp.f_t_abs, abs(inp.tau), self.mu, self.beta_m, self.sigma)


@dataclass(frozen=True, kw_only=True)
class Tactile14Law(GripLaw):
    """Paper (14), both sensors: raise while the tactile test (11) fails.

    Test (11) fails iff ``|n(p_c)| > T(p_c)``; then the demand is
    ``f_n + δf_n`` (see :func:`tactile14_increment`; ``increment`` selects the total
    ``N_A·δφ``, default, or the paper's per-taxel ``δφ``). While (11) holds the law
    does not release: with ``decay_n_per_s = 0`` (default, as in the paper) it holds
    the present ``f_n``; with ``decay_n_per_s > 0`` (N/s) it lowers the demand by
    ``decay_n_per_s · dt_s`` per step, towards ``f_nom``. ``f_n`` is the force now
    applied (N).

    The test is applied to loads *measured* while the contact holds, which never
    exceed the capacity: so (11) counts as failing once ``|n(p_c)| > (1 − δ) T(p_c)``
    (the slip detector's onset band ``delta``), and, while the detector reports slip
    (``inp.slip_state`` neither ``stick`` nor ``no-contact``), as long as
    ``|n(p_c)| > γ_release T(p_c)`` (its release level ``gamma_release``: sliding
    friction holds the load near ``μ_d/μ_s`` of the capacity). The defaults
    (``delta = 0``, ``gamma_release = 1``) give the paper's plain test ``|n| > T``.
    Without a COR of rotation (``inp.cor_case`` ``translation`` or ``none``) (11)
    cannot fail by rotation: the law holds (or decays) and reads only ``f_n``.
    """

    name: ClassVar[str] = "tactile14"
    needs: ClassVar[tuple[str, ...]] = ("f_n", "n_c", "t_c", "sum_dist_m")
    rotation_cases: ClassVar[tuple[str, ...]] = (SlipCase.ROTATION, SlipCase.ON_TAXEL)
    mu: float = MU
    sigma: float = 0.5
    increment: Literal["total", "per_taxel"] = "total"
    decay_n_per_s: float = 0.0
    delta: float = 0.0
    gamma_release: float = 1.0

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_positive("mu", self.mu)
        _check_sigma(self.sigma)
        if self.increment not in ("total", "per_taxel"):
            raise ConfigError(f"tactile14 increment must be 'total' or 'per_taxel', got {self.increment!r}")
        if not (math.isfinite(self.decay_n_per_s) and self.decay_n_per_s >= 0.0):
            raise ConfigError(
                f"tactile14 decay_n_per_s must be a finite rate >= 0 N/s, got {self.decay_n_per_s!r}")
        if not (math.isfinite(self.delta) and 0.0 <= self.delta < 1.0):
            raise ConfigError(f"tactile14 delta must lie in [0, 1), got {self.delta!r}")
        if not (math.isfinite(self.gamma_release) and 0.0 < self.gamma_release <= 1.0):
            raise ConfigError(f"tactile14 gamma_release must lie in (0, 1], got {self.gamma_release!r}")

    def required(self, inp: GripInput) -> tuple[str, ...]:
        return self.needs if inp.cor_case in self.rotation_cases else ("f_n",)

    def failing_level(self, slip_state: str) -> float:
        """The share of ``T(p_c)`` above which (11) counts as failing (dimensionless)."""
        return self.gamma_release if slip_state in SLIP_STATES else 1.0 - self.delta

    def demand(self, inp: GripInput, dt_s: float) -> float:
        if inp.cor_case in self.rotation_cases:
            t_c = self.failing_level(inp.slip_state) * inp.t_c
            if abs(inp.n_c) > t_c:  # test (11) fails
                return inp.f_n + tactile14_increment(inp.n_c, t_c, inp.sum_dist_m, inp.n_contact,
                                                     self.mu, self.sigma, self.increment)
        step = self.decay_n_per_s * dt_s if math.isfinite(dt_s) and dt_s > 0.0 else 0.0
        return inp.f_n - step


@dataclass(frozen=True, kw_only=True)
class ExactLaw(GripLaw):
    """Exact law ``γ f_n / σ``; assumes the pressure shape scales with ``f_n``."""

    name: ClassVar[str] = "exact"
    needs: ClassVar[tuple[str, ...]] = ("gamma", "f_n")
    sigma: float = 0.5

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_sigma(self.sigma)

    def demand(self, inp: GripInput, dt_s: float) -> float:
        return exact_demand(inp.gamma, inp.f_n, self.sigma)


@dataclass(frozen=True, kw_only=True)
class ConeMarginLaw(GripLaw):
    """The paper's ref. [9]: nearest ``f_nom``, ``cone_margin_n`` (N, > 0) inside the cone
    of ``mu`` (:func:`cone_margin_demand`)."""

    name: ClassVar[str] = "cone_margin"
    needs: ClassVar[tuple[str, ...]] = ("f_t",)
    mu: float = MU
    cone_margin_n: float = 1.0

    def __post_init__(self) -> None:
        super().__post_init__()
        _check_positive("mu", self.mu)
        _check_positive("cone_margin_n", self.cone_margin_n)

    def demand(self, inp: GripInput, dt_s: float) -> float:
        return cone_margin_demand(inp.f_t_abs, self.mu, self.cone_margin_n)


LAWS: Mapping[str, type[GripLaw]] = {
    cls.name: cls for cls in (LinearLaw, Ft13Law, Ft13SigmaLaw, Tactile14Law, ExactLaw, ConeMarginLaw)
}


def make_law(name: str, **params: object) -> GripLaw:
    """Build a law from its registry name and keyword parameters (node parameters).

    Raises:
        ConfigError: unknown name, unknown/missing parameter, or a value out of range.
    """
    cls = LAWS.get(name)
    if cls is None:
        raise ConfigError(f"unknown grip law {name!r}; choose one of {sorted(LAWS)}")
    try:
        return cls(**params)  # type: ignore[arg-type]
    except TypeError as exc:
        raise ConfigError(f"grip law {name!r}: {exc}") from None


# ---------------------------------------------------------------- actuator and fail-safe


class RateLimiter:
    """Slew-rate limit of the commanded force, N/s.

    ``step(target_n, dt_s)`` moves the output towards ``target_n`` by at most
    ``max_rate_n_per_s · dt_s`` up and ``max_fall_rate_n_per_s · dt_s`` down
    (default: the same rate). The first call without ``initial_n`` passes the target
    through. ``dt_s ≤ 0`` or non-finite holds the output.
    """

    def __init__(self, max_rate_n_per_s: float, *, max_fall_rate_n_per_s: float | None = None,
                 initial_n: float | None = None) -> None:
        fall = max_rate_n_per_s if max_fall_rate_n_per_s is None else max_fall_rate_n_per_s
        for label, rate in (("max_rate_n_per_s", max_rate_n_per_s), ("max_fall_rate_n_per_s", fall)):
            if not (rate > 0.0):  # inf allowed: no limit
                raise ConfigError(f"rate limiter {label} must be > 0 N/s, got {rate!r}")
        if initial_n is not None and not math.isfinite(initial_n):
            raise ConfigError(f"rate limiter initial_n must be a finite force in N, got {initial_n!r}")
        self.max_rise_n_per_s = float(max_rate_n_per_s)
        self.max_fall_n_per_s = float(fall)
        self._value = initial_n

    @property
    def value(self) -> float | None:
        """Last output in N (``None`` before the first step without ``initial_n``)."""
        return self._value

    def step(self, target_n: float, dt_s: float) -> float:
        """Next output in N; ``target_n`` must be finite (callers guarantee it)."""
        if self._value is None:
            self._value = float(target_n)
            return self._value
        dt = dt_s if math.isfinite(dt_s) and dt_s > 0.0 else 0.0
        lo = self._value - self.max_fall_n_per_s * dt
        hi = self._value + self.max_rise_n_per_s * dt
        self._value = min(max(float(target_n), lo), hi)
        return self._value

    def reset(self, value_n: float) -> None:
        """Set the output (N), e.g. to the measured actuator force."""
        self._value = float(value_n)


@dataclass(frozen=True, slots=True)
class FingerReport:
    """What the finger says it holds to (``grip/state``).

    Attributes:
        f_n_command: the normal force it holds to now, N.
        commanded: it has followed a controller's command since it powered on (a controller
            ran before: the grip it holds is one the stack chose for a load).
    """

    f_n_command: float
    commanded: bool


@dataclass
class GripGovernor:
    """The controller state around a law: staleness, status, hold, escalation, rate limit.

    Each :meth:`step` gets the time now, the stamps of the inputs it used (integer ns,
    one clock) and whether the contact is loaded. The step is *fail-safe* when any
    input is older than ``timeout_ns``, stamped more than ``timeout_ns`` in the future
    (a clock that jumped), when no stamp is given, when ``status_ok`` is false, or when
    the law reports non-finite input. The contract (docs/safety.md):

    - **Start from what the finger holds.** The first command is ``initial_n`` if given,
      else the highest of: the normal force the pad measures (``inp.f_n``) when the
      step is trusted (fresh and ``status_ok``), and the force the finger reports
      holding (``finger``); with neither, ``f_hold_n`` once ``finger_wait_ns`` has passed
      since the first step was asked for (the finger's report may be on its way). All
      within ``[f_nom, f_max]``. Until one of them is known :meth:`step` returns
      ``None``: no command, the finger keeps its grip.
    - **Hold.** In fail-safe the command stays at the last commanded force (never
      lower, never released, reason ``"fail-safe"``).
    - **Escalate while blind and loaded.** Once fail-safe has lasted ``blind_grace_ns``
      and the last valid step saw a loaded contact (before any: the finger reports that
      a controller commanded it, so a load was held), the command rises at
      ``blind_rise_n_per_s`` towards ``blind_limit_n`` (default ``f_max``): the load
      may be growing where the controller cannot see it. A launch never squeezes
      blind: holding is not squeezing.
    - **Recover rate-limited.** The next valid step resumes the law through the rate
      limiter, from wherever the hold or escalation left the command.

    Attributes:
        law: the grip law.
        timeout_ns: largest accepted input age, ns.
        max_rate_n_per_s: actuator force slew limit when raising, N/s.
        max_fall_rate_n_per_s: slew limit when lowering, N/s (default: the same).
        initial_n: first command, N (default: as above).
        f_hold_n: first command on untrusted data without a finger report, N (None: no
            command until one of the two is known).
        finger_wait_ns: how long the first command waits for the finger's report before
            ``f_hold_n``, ns.
        blind_grace_ns: fail-safe time before escalation starts, ns (< 0: never escalate).
        blind_rise_n_per_s: escalation rate, N/s.
        blind_limit_n: escalation ceiling, N (default ``f_max``).
    """

    law: GripLaw
    timeout_ns: int
    max_rate_n_per_s: float
    max_fall_rate_n_per_s: float | None = None
    initial_n: float | None = None
    f_hold_n: float | None = None
    finger_wait_ns: int = 100_000_000
    blind_grace_ns: int = 50_000_000
    blind_rise_n_per_s: float = 10.0
    blind_limit_n: float | None = None
    _limiter: RateLimiter = field(init=False, repr=False)
    _escalation: RateLimiter = field(init=False, repr=False)
    _last_now_ns: int | None = field(init=False, default=None, repr=False)
    _blind_since_ns: int | None = field(init=False, default=None, repr=False)
    _loaded: bool = field(init=False, default=False, repr=False)
    _asked_since_ns: int | None = field(init=False, default=None, repr=False)

    def __post_init__(self) -> None:
        law = self.law
        if not self.timeout_ns > 0:
            raise ConfigError(f"grip governor timeout_ns must be > 0 ns, got {self.timeout_ns!r}")
        if self.initial_n is not None and not (
                math.isfinite(self.initial_n) and law.f_nom_n <= self.initial_n <= law.f_max_n):
            raise ConfigError(f"grip governor initial_n must lie in [f_nom_n, f_max_n], got {self.initial_n!r}")
        if self.f_hold_n is not None and not (math.isfinite(self.f_hold_n) and self.f_hold_n >= 0.0):
            raise ConfigError(f"grip governor f_hold_n must be a finite force >= 0 N, got {self.f_hold_n!r}")
        if not self.finger_wait_ns >= 0:
            raise ConfigError(f"grip governor finger_wait_ns must be >= 0 ns, got {self.finger_wait_ns!r}")
        ceiling = law.f_max_n if self.blind_limit_n is None else self.blind_limit_n
        if not (math.isfinite(ceiling) and law.f_nom_n <= ceiling <= law.f_max_n):
            raise ConfigError(f"grip governor blind_limit_n must lie in [f_nom_n, f_max_n], got {ceiling!r}")
        self.blind_limit_n = ceiling
        self._limiter = RateLimiter(self.max_rate_n_per_s, max_fall_rate_n_per_s=self.max_fall_rate_n_per_s,
                                    initial_n=self.initial_n)
        self._escalation = RateLimiter(min(self.blind_rise_n_per_s, self.max_rate_n_per_s))

    @property
    def last_n(self) -> float | None:
        """Last commanded normal force, N (``None`` before the first step)."""
        return self._limiter.value

    @property
    def in_fail_safe(self) -> bool:
        """Whether the last step held (or escalated) the grip."""
        return self._blind_since_ns is not None

    def step(self, inp: GripInput, *, now_ns: int, stamps_ns: Sequence[int], status_ok: bool = True,
             loaded: bool = True, finger: FingerReport | None = None) -> GripDecision | None:
        """One control step; returns the command (never NaN, never raises), or ``None``
        before the first command while its start is unknown (class docstring).

        ``loaded``: the contact carries a load (the verdict saw contact); only a valid
        step updates what the governor believes about it. ``finger``: the finger's
        newest report (read at the first command only).
        """
        cause = self._stale_cause(now_ns, stamps_ns) or ("" if status_ok else NOT_OK)
        if self._limiter.value is None and not self._start(inp, now_ns, trusted=not cause, finger=finger):
            return None
        last = self._last_now_ns
        dt_s = 0.0 if last is None or now_ns <= last else (now_ns - last) * 1e-9
        self._last_now_ns = now_ns if last is None else max(now_ns, last)
        if not cause:
            decision = self.law.decide(inp, dt_s)
            if decision.reason is not GripReason.FAIL_SAFE:
                self._blind_since_ns, self._loaded = None, loaded
                commanded = self._limiter.step(decision.f_n_desired, dt_s)
                return GripDecision(commanded, decision.law, decision.reason, decision.raw)
            cause = decision.detail
        return self._fail_safe(cause, now_ns, dt_s)

    def _start(self, inp: GripInput, now_ns: int, *, trusted: bool, finger: FingerReport | None) -> bool:
        """Set the first command from what is known (class docstring); False while nothing is."""
        if self._asked_since_ns is None:
            self._asked_since_ns = now_ns
        known = [inp.f_n] if trusted and math.isfinite(inp.f_n) else []
        if finger is not None and math.isfinite(finger.f_n_command):
            known.append(finger.f_n_command)
            self._loaded = finger.commanded
        if not known and self.f_hold_n is not None and now_ns - self._asked_since_ns >= self.finger_wait_ns:
            known.append(self.f_hold_n)
        if not known:
            return False
        self._limiter.reset(min(max(max(known), self.law.f_nom_n), self.law.f_max_n))
        return True

    def _fail_safe(self, cause: str, now_ns: int, dt_s: float) -> GripDecision:
        """Hold the last command; escalate once blind for ``blind_grace_ns`` with a load."""
        if self._blind_since_ns is None:
            self._blind_since_ns = now_ns
            self._escalation.reset(self.last_n)
        blind_ns = now_ns - self._blind_since_ns
        held = self.last_n
        if self._loaded and 0 <= self.blind_grace_ns <= blind_ns and held < self.blind_limit_n:
            held = max(held, self._escalation.step(self.blind_limit_n, dt_s))
            self._limiter.reset(held)
            cause = f"{cause}; blind {blind_ns * 1e-6:.0f} ms with a load: raising the grip"
        return GripDecision(held, self.law.name, GripReason.FAIL_SAFE, held, cause)

    def _stale_cause(self, now_ns: int, stamps_ns: Sequence[int]) -> str:
        """Why the inputs are stale or untrustworthy ('' if fresh)."""
        if len(stamps_ns) == 0:
            return "no input stamps"
        age_ns = now_ns - min(stamps_ns)
        if age_ns > self.timeout_ns:
            return f"input age {age_ns * 1e-6:.3f} ms > timeout {self.timeout_ns * 1e-6:.3f} ms"
        ahead_ns = max(stamps_ns) - now_ns
        if ahead_ns > self.timeout_ns:
            return f"input stamped {ahead_ns * 1e-6:.3f} ms in the future (a sensor clock jumped)"
        return ""
