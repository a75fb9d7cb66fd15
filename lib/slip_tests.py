"""Slip tests of the paper (§III–IV, docs/math.md §3) behind one interface.

Every test has the signature ``test(contact, params, warm_start=None) -> SlipVerdict``
and returns a load factor ``γ`` (or its analogue) with ``margin = 1 − γ``:

More in docs/modules.md, `lib/slip_tests.py`.
"""

from __future__ import annotations

import math
import operator
from dataclasses import dataclass
from typing import Callable, Protocol, Sequence

import numpy as np

from slipstack.lib.cor import CorResult, paper_cor, robust_cor
from slipstack.lib.defaults import MU
from slipstack.lib.errors import ConfigError
from slipstack.lib.limit_set import load_factor, torsional_coefficient
from slipstack.lib.status import SlipCase, SlipState, SolverStatus

__all__ = [
    "ContactLike",
    "SlipParams",
    "SlipVerdict",
    "SlipTest",
    "SLIP_TESTS",
    "ft_beta",
    "ft_stick_margins",
    "FT_TESTS",
    "BETA_TESTS",
    "get_slip_test",
    "coulomb",
    "decoupled",
    "linear_ls",
    "elliptic_ls",
    "tactile_cor",
    "tactile_cor_robust",
    "exact",
    "KIND_TRANSLATION_BELOW",
    "KIND_ROTATION_ABOVE",
]

KIND_TRANSLATION_BELOW = 1.0 / 3.0
"""Rotation share below which a slip is called a translation."""
KIND_ROTATION_ABOVE = 2.0 / 3.0
"""Rotation share above which a slip is called a rotation."""


class ContactLike(Protocol):
    """What a slip test reads (pad frame F, SI); :class:`~slipstack.lib.fusion.FusionResult` fits."""

    f_n: float  # N, > 0 when in contact
    f_t: np.ndarray  # (2,) N
    tau: float  # N·m about the pad origin
    phi: np.ndarray  # (N,) N per taxel
    positions: np.ndarray  # (N, 2) m


@dataclass(frozen=True)
class SlipParams:
    """Parameters shared by the slip tests.

    Attributes:
        mu: static friction coefficient μ_s (> 0).
        beta_m: torsional coefficient β (m, > 0) for the F/T tests; ``None`` → β_s from tactile data.
        delta: detection margin δ (docs/math.md §3.1): stick iff ``γ ≤ 1 − δ``; 0 ≤ δ < 1.
        paper_gain: gain ``h`` of the paper's COR iteration (``tactile_cor``).
    """

    mu: float = MU
    beta_m: float | None = None
    delta: float = 0.0
    paper_gain: float = 0.5

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mu) and self.mu > 0):
            raise ConfigError(f"friction coefficient mu must be > 0, got {self.mu}")
        if self.beta_m is not None and not (math.isfinite(self.beta_m) and self.beta_m > 0):
            raise ConfigError(f"beta_m must be a length > 0 in metres or None, got {self.beta_m}")
        if not (0.0 <= self.delta < 1.0):
            raise ConfigError(f"detection margin delta must be in [0, 1), got {self.delta}")
        if not (0.0 < self.paper_gain <= 1.0):
            raise ConfigError(f"paper_gain must be in (0, 1], got {self.paper_gain}")


@dataclass(frozen=True, slots=True)
class SlipVerdict:
    """The answer of one slip test.

    Attributes:
        stick: True iff the test predicts stick: ``margin ≥ δ`` *and* a usable status.
            A solver that failed (MAX_ITER, SINGULAR, DIVERGED) cannot certify stick;
            its ``γ`` is still the ratio at its last iterate, a lower bound on the
            exact γ, so a slip it reports is real.
        margin: ``1 − γ`` (dimensionless; 1 for no load, ``−inf`` for a torqued point contact).
        kind: 'stick', 'translation', 'rotation', 'combined' or 'no-contact' (module docstring).
        status: the status of the computation behind the verdict.
        gamma: the test's load factor ``γ``.
        p_c: the COR used (m, F) — the warm start for the next frame — or ``None``.
        method: the registry name of the test.
    """

    stick: bool
    margin: float
    kind: SlipState
    status: SolverStatus
    gamma: float
    p_c: tuple[float, float] | None
    method: str


SlipTest = Callable[[ContactLike, SlipParams, "tuple[float, float] | None"], SlipVerdict]


def _kind_from_share(rho: float) -> SlipState:
    if rho < KIND_TRANSLATION_BELOW:
        return SlipState.TRANSLATION
    if rho > KIND_ROTATION_ABOVE:
        return SlipState.ROTATION
    return SlipState.COMBINED


def _no_contact(method: str, status: SolverStatus = SolverStatus.NO_CONTACT) -> SlipVerdict:
    return SlipVerdict(False, 0.0, SlipState.NO_CONTACT, status, 0.0, None, method)


def _bad(method: str) -> SlipVerdict:
    return SlipVerdict(False, 0.0, SlipState.NO_CONTACT, SolverStatus.INVALID_INPUT, 0.0, None, method)


def _load(contact: ContactLike, mu: float) -> tuple[float, float, float, float] | None:
    """``(f_n, f_tx, f_ty, τ)`` as floats, or None if any is non-finite or the friction
    capacity μ f_n of a positive f_n underflows to 0 (every test divides by it)."""
    f_n, f_tx, f_ty, tau = float(contact.f_n), float(contact.f_t[0]), float(contact.f_t[1]), float(contact.tau)
    isfinite = math.isfinite  # every test of every frame passes here: no generator
    if not (isfinite(f_n) and isfinite(f_tx) and isfinite(f_ty) and isfinite(tau)) or (
            f_n > 0.0 and not mu * f_n > 0.0):
        return None
    return f_n, f_tx, f_ty, tau


def _stick_margin(gamma: float, params: SlipParams, usable: bool) -> tuple[bool, float]:
    """``(stick, margin)`` of a load factor γ computed with a status that is ``usable`` or not
    (Python bool and float also where γ is a numpy scalar: a kernel run with numba's JIT off)."""
    margin = 1.0 - float(gamma)
    return usable and margin >= params.delta, margin


def _verdict(gamma: float, rho: float, params: SlipParams, status, p_c, method) -> SlipVerdict:
    stick, margin = _stick_margin(gamma, params, status.usable)
    kind = SlipState.STICK if stick else _kind_from_share(rho)
    return SlipVerdict(stick, margin, kind, status, gamma, p_c, method)


def ft_beta(contact: ContactLike, params: SlipParams) -> float | None:
    """β (m) for the F/T tests: ``params.beta_m``, else β_s from the tactile data (0 for a
    point contact), else None."""
    if params.beta_m is not None:
        return params.beta_m
    tor = torsional_coefficient(contact.phi, contact.positions, params.mu)
    return tor.beta_m if tor.status.usable and tor.median is not None else None


def _ft_load(contact: ContactLike, params: SlipParams) -> tuple[SolverStatus, float, float, float]:
    """What every F/T test reads first: ``(status, a_t, τ, f_n)`` with ``a_t = |f_t|/(μ f_n)``
    (τ N·m, f_n N). status OK; NO_LOAD: neither force nor torque (``a_t = 0``);
    NO_CONTACT (``f_n ≤ 0``) or INVALID_INPUT (a non-finite load): no ratio (all 0)."""
    load = _load(contact, params.mu)
    if load is None:
        return SolverStatus.INVALID_INPUT, 0.0, 0.0, 0.0
    f_n, fx, fy, tau = load
    if not f_n > 0:
        return SolverStatus.NO_CONTACT, 0.0, 0.0, 0.0
    a_t = math.hypot(fx, fy) / (params.mu * f_n)
    return (SolverStatus.NO_LOAD if a_t == 0.0 and tau == 0.0 else SolverStatus.OK), a_t, tau, f_n


def _ft_ratios(contact: ContactLike, params: SlipParams,
               load: tuple[SolverStatus, float, float, float]) -> tuple[SolverStatus, float, float]:
    """The part of the F/T tests with β that does not depend on how they combine, from the
    contact's :func:`_ft_load`: ``(status, a_t, a_r)`` with ``a_r = |τ|/(β f_n)``.

    status OK: both ratios (``a_r = 0`` for a tactile point contact without torque);
    NO_LOAD: no load, or a torque so small that its ratio underflows (both 0);
    POINT_CONTACT: a tactile point contact (β = 0) under a torque (``a_r = inf``);
    NO_CONTACT, INVALID_INPUT (a bad load or no β): no ratios (both 0).
    """
    status, a_t, tau, f_n = load
    if status is not SolverStatus.OK:
        return status, 0.0, 0.0
    beta = ft_beta(contact, params)
    if beta is None:
        return SolverStatus.INVALID_INPUT, 0.0, 0.0
    if beta == 0.0:  # tactile point contact: no torsional friction
        return (SolverStatus.OK, a_t, 0.0) if tau == 0.0 else (SolverStatus.POINT_CONTACT, a_t, math.inf)
    a_r = abs(tau) / (beta * f_n) if beta * f_n > 0.0 else math.inf
    if a_t == 0.0 and a_r == 0.0:  # a torque so small that its ratio underflows: no load either
        return SolverStatus.NO_LOAD, 0.0, 0.0
    return SolverStatus.OK, a_t, a_r


def _ft_gamma(ratios: tuple[SolverStatus, float, float], method: str) -> float | None:
    """γ of the F/T test ``method`` on the :func:`_ft_ratios` of a contact (``None``: no
    verdict, for no contact or bad input)."""
    status, a_t, a_r = ratios
    if status is SolverStatus.OK:
        return _FT_COMBINE[method](a_t, a_r)
    if status is SolverStatus.NO_LOAD:
        return 0.0
    return math.inf if status is SolverStatus.POINT_CONTACT else None


def _ft_verdict(ratios: tuple[SolverStatus, float, float], params: SlipParams, method: str) -> SlipVerdict:
    """The verdict of the F/T test ``method`` on the :func:`_ft_ratios` of a contact."""
    status, a_t, a_r = ratios
    gamma = _ft_gamma(ratios, method)
    if gamma is None:
        return _no_contact(method) if status is SolverStatus.NO_CONTACT else _bad(method)
    rho = a_r / (a_t + a_r) if status is SolverStatus.OK else 1.0 if status is SolverStatus.POINT_CONTACT else 0.0
    return _verdict(gamma, rho, params, status, None, method)


def _ft_test(contact: ContactLike, params: SlipParams, method: str) -> SlipVerdict:
    """The verdict of the F/T test with β ``method`` on ``contact``."""
    return _ft_verdict(_ft_ratios(contact, params, _ft_load(contact, params)), params, method)


def ft_stick_margins(contact: ContactLike, params: SlipParams, methods: Sequence[str]) -> list[tuple[bool, float]]:
    """``(stick, margin)`` of each F/T test named in ``methods`` (:data:`FT_TESTS`),
    as in the verdict its own function returns, from one evaluation of the load and the
    ratios they share and without building the verdicts: what a detector publishes of the
    tests it runs alongside on every contact."""
    load = _ft_load(contact, params)
    ratios = None
    out = []
    for method in methods:
        if method == "coulomb":
            status, gamma = load[0], (load[1] if load[0] in _COULOMB_JUDGES else None)
        else:
            ratios = ratios or _ft_ratios(contact, params, load)
            status, gamma = ratios[0], _ft_gamma(ratios, method)
        out.append((False, 0.0) if gamma is None else _stick_margin(gamma, params, status.usable))
    return out


def coulomb(contact: ContactLike, params: SlipParams, warm_start=None) -> SlipVerdict:
    """Linear Coulomb test (7): stick iff ``|f_t| ≤ μ f_n``; torque ignored."""
    status, gamma, _, _ = _ft_load(contact, params)
    if status not in _COULOMB_JUDGES:
        return _no_contact("coulomb") if status is SolverStatus.NO_CONTACT else _bad("coulomb")
    return _verdict(gamma, 0.0, params, status, None, "coulomb")


_COULOMB_JUDGES = (SolverStatus.OK, SolverStatus.NO_LOAD)
"""The :func:`_ft_load` statuses on which the Coulomb test judges (γ = ``a_t``)."""


def decoupled(contact: ContactLike, params: SlipParams, warm_start=None) -> SlipVerdict:
    """Decoupled test (Fig. 5d): ``|f_t| ≤ μ f_n`` and ``|τ| ≤ β f_n``."""
    return _ft_test(contact, params, "decoupled")


def linear_ls(contact: ContactLike, params: SlipParams, warm_start=None) -> SlipVerdict:
    """Linear limit surface (5): ``|f_t|/μ + |τ|/β ≤ f_n``."""
    return _ft_test(contact, params, "linear_ls")


def elliptic_ls(contact: ContactLike, params: SlipParams, warm_start=None) -> SlipVerdict:
    """Elliptical limit surface (6): ``f_t²/μ² + τ²/β² ≤ f_n²``."""
    return _ft_test(contact, params, "elliptic_ls")


_FT_COMBINE: dict[str, Callable[[float, float], float]] = {
    "decoupled": max,
    "linear_ls": operator.add,
    "elliptic_ls": math.hypot,
}
"""How each F/T test with β makes γ of ``a_t = |f_t|/(μ f_n)`` and ``a_r = |τ|/(β f_n)``."""
FT_TESTS: tuple[str, ...] = ("coulomb", *_FT_COMBINE)
"""The slip tests that read only the wrench (and β): valid without a pressure frame
(:func:`ft_stick_margins` judges any of them)."""
BETA_TESTS: tuple[str, ...] = tuple(_FT_COMBINE)
"""The F/T tests that need β: without a configured one, that of a pressure frame (:func:`ft_beta`)."""


def _rotation_share(contact: ContactLike, p_c: tuple[float, float] | None,
                    cop: tuple[float, float] | None = None, ell: float | None = None) -> float:
    """``ℓ/(ℓ + d)``: ℓ the RMS contact radius about the centre of pressure, d its distance to p_c."""
    if p_c is None:
        return 0.0
    if cop is None or ell is None:
        phi = np.asarray(contact.phi, dtype=float)
        P = np.asarray(contact.positions, dtype=float)
        f_n = float(phi.sum())
        cop = phi @ P / f_n
        ell = math.sqrt(max(float(phi @ np.sum((P - cop) ** 2, axis=1)) / f_n, 0.0))
    d = math.hypot(p_c[0] - cop[0], p_c[1] - cop[1])
    return 1.0 if ell + d == 0.0 else ell / (ell + d)


def _cor_verdict(contact, params, res: CorResult, method: str) -> SlipVerdict:
    if res.status in (SolverStatus.NO_CONTACT, SolverStatus.INVALID_INPUT):
        return _no_contact(method, res.status)
    if res.status is SolverStatus.NO_LOAD:
        return _verdict(0.0, 0.0, params, res.status, None, method)
    gamma = res.ratio
    return _verdict(gamma, _rotation_share(contact, res.p_c), params, res.status, res.p_c, method)


def tactile_cor(contact: ContactLike, params: SlipParams, warm_start=None) -> SlipVerdict:
    """Tactile COR test (11) at the COR of (12) from the paper's fixed-gain iteration."""
    load = _load(contact, params.mu)
    if load is None:
        return _bad("tactile_cor")
    res = paper_cor(contact.phi, contact.positions, contact.f_t, load[3], params.mu,
                    gain=params.paper_gain, c0=warm_start)
    return _cor_verdict(contact, params, res, "tactile_cor")


def tactile_cor_robust(contact: ContactLike, params: SlipParams, warm_start=None) -> SlipVerdict:
    """Tactile COR test (11) at the maximiser of ``s·n − T`` over both senses (robust solver)."""
    load = _load(contact, params.mu)
    if load is None:
        return _bad("tactile_cor_robust")
    res = robust_cor(contact.phi, contact.positions, contact.f_t, load[3], params.mu, c0=warm_start)
    return _cor_verdict(contact, params, res, "tactile_cor_robust")


def exact(contact: ContactLike, params: SlipParams, warm_start=None) -> SlipVerdict:
    """Exact limit-set test (§4): stick iff the load factor ``γ ≤ 1 − δ``."""
    load = _load(contact, params.mu)
    if load is None:
        return _bad("exact")
    res = load_factor(contact.phi, contact.positions, contact.f_t, load[3], params.mu, c0=warm_start)
    if res.status in (SolverStatus.NO_CONTACT, SolverStatus.INVALID_INPUT):
        return _no_contact("exact", res.status)
    rho = 0.0
    if res.case not in (SlipCase.TRANSLATION, SlipCase.NONE):
        rho = _rotation_share(contact, res.p_c, res.cop, res.contact_radius_m)
    return _verdict(res.gamma, rho, params, res.status, res.p_c, "exact")


SLIP_TESTS: dict[str, SlipTest] = {
    "coulomb": coulomb,
    "decoupled": decoupled,
    "linear_ls": linear_ls,
    "elliptic_ls": elliptic_ls,
    "tactile_cor": tactile_cor,
    "tactile_cor_robust": tactile_cor_robust,
    "exact": exact,
}
"""Method name (a node parameter) → slip test."""


def get_slip_test(name: str) -> SlipTest:
    """The slip test registered under ``name``; ConfigError listing the valid names otherwise."""
    try:
        return SLIP_TESTS[name]
    except KeyError:
        raise ConfigError(f"unknown slip test {name!r}; choose one of {sorted(SLIP_TESTS)}") from None
