"""The slip detector without the node graph: one fused contact in, one verdict out.

:class:`Detector` is what the ``slip_detector`` node runs, usable offline on
recorded or synthetic data: feed it, frame by frame, a contact in the pad frame ``F``
(a wrench, and the pressure frame paired with it, if any) and its time stamp; it
returns a :class:`DetectorVerdict` with the deciding test's load factor γ and margin,
the latched slip state, the kind of slip, the COR of impending slip, the solver
status, the verdict's validity status and every side test's ``[stick, margin]``.

More in docs/modules.md, `lib/detector.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from slipstack.lib.contact_view import ContactView, FusedContact
from slipstack.lib.detection import DetectorConfig
from slipstack.lib.errors import ConfigError
from slipstack.lib.known_cor import KNOWN_COR_METHOD, known_cor_test
from slipstack.lib.material import Material, detector_thresholds
from slipstack.lib.online_calibration import CalibratedLatch
from slipstack.lib.onset_band import OnsetBand, pressure_spread
from slipstack.lib.slip_tests import (BETA_TESTS, FT_TESTS, SlipParams, SlipVerdict, ft_beta, ft_stick_margins,
                                      get_slip_test)
from slipstack.lib.status import SAMPLE_NO_CONTACT, SAMPLE_OK, SLIP_STATES, SlipState, SolverStatus

__all__ = [
    "BELOW_NOISE",
    "NOISE_CAPACITY",
    "FT_TESTS",
    "VALID",
    "CONTACT_LOST",
    "ONSET_NS_PER_FRAME",
    "PadContact",
    "DetectorSettings",
    "DetectorVerdict",
    "Detector",
]

VALID = SolverStatus.OK.value
"""The status of a verdict that judged valid data (and of a valid contact)."""

CONTACT_LOST = SolverStatus.NO_CONTACT.value
"""The fused contact's status when the wrench says nothing touches the pad."""

_UNUSABLE = "unusable"
"""Validity status of an earlier sample of a batch whose data were not usable."""

BELOW_NOISE = "below_noise"
"""The status of a verdict on a capacity the F/T's noise swamps."""

NOISE_CAPACITY = 10.0
"""A verdict is judged only on a capacity of at least this many times the F/T's noise: below,
the noise alone moves γ by more than 0.1 (pressing or letting go: f_n of some tenths of a
newton, or a pressure frame with one taxel pressed, whose torsional capacity is 0)."""

ONSET_NS_PER_FRAME = 900_000
"""Time an onset frame stands for, ns: the paper's 1 kHz F/T period less 10 % for the
jitter of receive stamps (two frames at 1 kHz span 1 ms ≥ 0.9 ms, as before)."""


@dataclass(frozen=True)
class PadContact:
    """A :class:`~slipstack.lib.contact_view.FusedContact` built from its parts.

    f_n: normal force, N; f_t: (2,) tangential force, N; tau: torque about z through
    the pad origin, N·m (all in the pad frame ``F``); phi: (rows·cols,) N per taxel,
    row-major, or empty without a pressure frame; rows, cols, pitch_m (m): the pad;
    status: the wrench's status (``ok`` for valid data).
    """

    f_n: float
    f_t: np.ndarray
    tau: float
    phi: np.ndarray = field(default_factory=lambda: np.zeros(0))
    rows: int = 16
    cols: int = 16
    pitch_m: float = 1.25e-3
    status: str = VALID

    @property
    def has_tactile(self) -> bool:
        """Whether a pressure frame is given."""
        return self.phi.size > 0

    @property
    def tactile_status(self) -> str:
        """``ok`` with a pressure frame, ``none`` without."""
        return VALID if self.has_tactile else "none"


@dataclass(frozen=True)
class DetectorSettings:
    """What :class:`Detector` needs; the ``slip_detector`` node's parameters.

    mu: static friction coefficient μ_s (> 0).
    delta: onset band: slip when γ ≥ 1 − delta (in [0, 1)).
    gamma_release: slip stays latched while γ ≥ this (in (0, 1]).
    method: the deciding slip test (``lib/slip_tests.py`` registry name).
    also: tests computed alongside (the deciding one is skipped if listed).
    beta_m: torsional coefficient β for the F/T tests, m; 0: β_s of each pressure frame.
    release_ns: γ below the release level this long releases the latch, ns.
    pool: sum taxels in pool × pool blocks before testing (1: off).
    gamma_resume: a frame with γ ≥ this restarts the release dwell (NaN: gamma_release).
    onset_frames: valid frames in a row in the band that raise the flag, and for as
        long as they take at the paper's 1 kHz (:data:`ONSET_NS_PER_FRAME` each after
        the first), whatever the F/T rate: at 7 kHz the band must hold as long, over
        about seven times as many samples.
    known_cor_m: (x, y) of a fixed pivot in the pad frame, m; only with
        ``method = "tactile_cor_known"``, which needs it.
    calibrate_from: the material whose μ and thresholds these are, to calibrate online
        from (None: no online calibration).
    onset_band: the band of each sample's load path and pressure spread (None: ``delta``
        for every sample).
    sliding_level, stuck_margin: release a slip that reached the sliding level when γ
        stays ``stuck_margin`` above it (``lib/detection.py``; NaN: no such release).
    force_noise_n, torque_noise_nm: the F/T's noise (N, N·m; NaN: no noise guard).
    """

    mu: float
    delta: float
    gamma_release: float
    method: str = "exact"
    also: tuple[str, ...] = FT_TESTS
    beta_m: float = 0.0
    release_ns: int = DetectorConfig.release_ns
    pool: int = 1
    gamma_resume: float = math.nan
    onset_frames: int = DetectorConfig.onset_frames
    known_cor_m: tuple[float, float] | None = None
    calibrate_from: Material | None = None
    onset_band: OnsetBand | None = None
    sliding_level: float = math.nan
    stuck_margin: float = math.nan
    force_noise_n: float = math.nan
    torque_noise_nm: float = math.nan

    def __post_init__(self) -> None:
        if (self.method == KNOWN_COR_METHOD) != (self.known_cor_m is not None):
            raise ConfigError(f"detector method {KNOWN_COR_METHOD!r} goes with a known COR (x, y) in m, and a "
                              f"known COR with that method only; got method {self.method!r}, known COR "
                              f"{self.known_cor_m!r}")
        if not (math.isfinite(self.beta_m) and self.beta_m >= 0.0):
            raise ConfigError(f"detector beta_m must be a length >= 0 m (0: from tactile), got {self.beta_m!r}")
        if not (isinstance(self.pool, int) and self.pool >= 1):
            raise ConfigError(f"detector pool must be an integer >= 1 (1: off), got {self.pool!r}")

    @classmethod
    def from_material(cls, material: Material, **overrides: Any) -> DetectorSettings:
        """Settings with μ = μ_s, the thresholds ``lib/material.py`` derives from it and its
        onset band; ``overrides`` replaces any field (e.g. ``method="tactile_cor"``)."""
        thresholds = detector_thresholds(material)
        derived = {"mu": material.mu_s, "delta": thresholds.delta, "gamma_release": thresholds.gamma_release,
                   "gamma_resume": thresholds.gamma_resume, "onset_band": OnsetBand.of(material),
                   "sliding_level": thresholds.sliding_level, "stuck_margin": thresholds.stuck_margin,
                   "force_noise_n": material.force_noise_n, "torque_noise_nm": material.torque_noise_nm}
        return cls(**{**derived, **overrides})


@dataclass(frozen=True, slots=True)
class DetectorVerdict:
    """One frame's verdict.

    t_ns: the contact's time stamp, ns.
    state: ``stick``, ``no-contact``, or while slip is latched the latest slip kind
        (``translation``, ``rotation``, ``combined``).
    slipping: whether slip is latched.
    kind: this frame's kind by the deciding test (``stick``, ``no-contact`` or a slip kind).
    gamma: the deciding test's load factor γ; margin: ``1 − γ`` (dimensionless).
    method: the deciding test.
    p_c: COR of impending slip in ``F`` (m), or ``None``.
    solver_status: the deciding test's computation status.
    status: ``ok`` when the verdict judged valid data, otherwise why not (module docstring).
    verdicts: test name → ``(stick, margin)``, the deciding test first.
    """

    t_ns: int
    state: str
    slipping: bool
    kind: str
    gamma: float
    margin: float
    method: str
    p_c: tuple[float, float] | None
    solver_status: SolverStatus
    status: str
    verdicts: dict[str, tuple[bool, float]]


class Detector:
    """Slip verdicts over a sequence of contacts; keeps the latch, β_s and the warm start."""

    def __init__(self, settings: DetectorSettings) -> None:
        """Raises ConfigError for an unknown test or a threshold out of range."""
        s = self.settings = settings
        self._test = known_cor_test(s.known_cor_m) if s.known_cor_m is not None else get_slip_test(s.method)
        others = [name for name in s.also if name != s.method]
        self._others = [(name, None if name in FT_TESTS else get_slip_test(name)) for name in others]
        """The side tests in the order of ``also``; ``None`` for an F/T test: those are
        judged together, by :func:`ft_stick_margins` on the load they share, in ``_ft_others``."""
        self._ft_others = [name for name, test in self._others if test is None]
        self._deciding_ft = s.method in FT_TESTS
        self._needs_pad = not self._deciding_ft or (s.method in BETA_TESTS and not s.beta_m)
        """Whether the deciding test needs a pressure frame: a tactile one, or an F/T one whose β comes from it."""
        self._params = SlipParams(mu=s.mu, beta_m=s.beta_m or None, delta=s.delta)
        self._ft_params = self._params  # with β_s of the current pressure frame when beta_m is 0
        self._beta_frame: object = None
        self._frame_beta: float | None = None  # β_s of the last pressure frame (0: a point contact)
        self._torsion_beta: float | None = None  # β of the current contact's torsional capacity, m
        onset_ns = (s.onset_frames - 1) * ONSET_NS_PER_FRAME if isinstance(s.onset_frames, int) else 0
        self._latch = CalibratedLatch(DetectorConfig(s.delta, s.gamma_release, s.release_ns, s.gamma_resume,
                                                     s.onset_frames, onset_ns, s.sliding_level, s.stuck_margin),
                                      s.calibrate_from)
        self._band = s.onset_band if s.onset_band is not None and s.onset_band.kinds else None
        self.calibration = self._latch.calibration
        """The online calibration (None: off); its ``learned`` is what the latch uses."""
        self._warm: tuple[float, float] | None = None
        self._kind = SlipState.TRANSLATION  # the latest slip kind, reported while the latch holds
        self.samples_judged = 0
        """F/T samples judged since construction: the deciding test's verdict on valid data,
        or a loss of contact (each clears or moves the latch; samples without usable data
        leave it as it is and are not counted)."""

    def step(self, contact: FusedContact, t_ns: int, *, tactile_frame: object = None) -> DetectorVerdict:
        """The verdict on ``contact`` stamped ``t_ns`` (ns; one clock, non-decreasing).

        ``tactile_frame`` identifies the pressure frame (e.g. its stamp): β_s is computed
        once per frame; ``None`` recomputes it whenever the previous frame was not ``None``.
        A contact with ``earlier_samples`` has those stepped first (module docstring).
        Never raises on bad data: it shows in ``status``.
        """
        view = ContactView(contact, self.settings.pool)
        ft_params = self._params_for_ft_tests(view, tactile_frame)
        params = ft_params if self._deciding_ft else self._params
        spread = pressure_spread(view.phi) if self._band is not None else math.nan
        if getattr(contact, "earlier_samples", 0):
            self._step_earlier(contact, view, params, spread)
        v = self._test(view, params, self._warm)
        if v.p_c is not None:
            self._warm = v.p_c
        status = self._guard(self._verdict_status(contact.status, contact, v), view.f_n)
        slipping, in_contact, margin = self._advance(t_ns, v, status, contact_lost=contact.status == CONTACT_LOST,
                                                     delta=self._delta(view.f_t, view.tau, spread))
        verdicts = {v.method: (v.stick, v.margin)}
        ft_judged = iter(ft_stick_margins(view, ft_params, self._ft_others) if self._ft_others else ())
        for name, test in self._others:
            if test is None:
                verdicts[name] = next(ft_judged)
            else:
                o = test(view, ft_params, None)
                verdicts[name] = (o.stick, o.margin)
        if not in_contact:
            state = SlipState.NO_CONTACT
        elif slipping:
            state = self._kind
        else:
            state = SlipState.STICK
        return DetectorVerdict(t_ns=t_ns, state=state, slipping=slipping, kind=v.kind, gamma=1.0 - margin,
                               margin=margin, method=v.method, p_c=v.p_c, solver_status=v.status,
                               status=status, verdicts=verdicts)

    def _delta(self, f_t: np.ndarray, tau: float, spread: float) -> float | None:
        """The band for this load (None: the configured ``delta``)."""
        return None if self._band is None else self._band.delta_of_load(f_t, tau, spread)

    def _advance(self, t_ns: int, v: SlipVerdict, status: str, *, contact_lost: bool,
                 delta: float | None) -> tuple[bool, bool, float]:
        """Feed one sample's verdict (its validity ``status``) and band to the latch:
        (slipping, in contact, the deciding margin, with the learned μ when calibrating online)."""
        fresh = status == VALID
        self.samples_judged += fresh or contact_lost
        in_contact = v.kind != SlipState.NO_CONTACT if fresh else not contact_lost
        slipping, margin = self._latch.update(t_ns, v.margin if fresh else math.nan, in_contact=in_contact,
                                              delta=delta)
        if slipping and in_contact and v.kind in SLIP_STATES:
            self._kind = v.kind
        return slipping, in_contact, v.margin if math.isnan(margin) else margin

    def _step_earlier(self, contact: Any, view: ContactView, params: SlipParams, spread: float) -> None:
        """The deciding test and the latch over the contact's earlier samples, oldest first,
        each as its own contact would be judged: its load with the contact's pressure frame
        scaled to its normal force (a contact whose newest sample pressed nothing has no
        pressure to scale: a tactile test then has no verdict on its earlier samples)."""
        phi_sum = float(view.phi.sum()) if view.phi.size else 0.0
        for t_ns, f_n, f_tx, f_ty, tau, code in zip(
                contact.earlier_stamp_ns.tolist(), contact.earlier_f_n.tolist(), contact.earlier_f_tx.tolist(),
                contact.earlier_f_ty.tolist(), contact.earlier_tau.tolist(), contact.earlier_status.tolist()):
            phi = view.phi * (f_n / phi_sum) if phi_sum > 0.0 else view.phi
            v = self._test(_SampleView(f_n, np.array((f_tx, f_ty)), tau, phi, view.positions), params, self._warm)
            if v.p_c is not None:
                self._warm = v.p_c
            sample_status = VALID if code == SAMPLE_OK else CONTACT_LOST if code == SAMPLE_NO_CONTACT else _UNUSABLE
            status = self._guard(self._verdict_status(sample_status, contact, v), f_n)
            if status == VALID and view.phi.size and phi_sum <= 0.0 and not self._deciding_ft:
                status = _UNUSABLE  # a pressure frame with nothing to scale: no verdict for a tactile test
            self._advance(t_ns, v, status, contact_lost=code == SAMPLE_NO_CONTACT,
                          delta=self._delta((f_tx, f_ty), tau, spread))

    def _params_for_ft_tests(self, view: ContactView, frame: object) -> SlipParams:
        """SlipParams with β fixed: the configured one, or β_s of this pressure frame."""
        if self._params.beta_m is not None or not view.phi.size:
            self._torsion_beta = self._params.beta_m
            return self._params
        if frame != self._beta_frame:
            beta = ft_beta(view, self._params)  # β_s: the configured β is None on this path
            self._ft_params = replace(self._params, beta_m=beta) if beta else self._params
            self._beta_frame = frame
            self._frame_beta = beta
        self._torsion_beta = self._frame_beta
        return self._ft_params

    def _guard(self, status: str, f_n: float) -> str:
        """``below_noise`` for a valid verdict on a capacity under :data:`NOISE_CAPACITY` times
        the F/T's noise (the force's ``μ f_n``; the torque's ``β f_n`` with the configured β,
        else β_s of the pressure frame, 0 for a point contact), else ``status``."""
        s = self.settings
        if status != VALID:
            return status
        if s.force_noise_n > 0.0 and s.mu * f_n < NOISE_CAPACITY * s.force_noise_n:
            return BELOW_NOISE
        beta = self._torsion_beta
        if beta is not None and s.torque_noise_nm > 0.0 and beta * f_n < NOISE_CAPACITY * s.torque_noise_nm:
            return BELOW_NOISE
        return status

    def _verdict_status(self, sample_status: str, contact: FusedContact, v: SlipVerdict) -> str:
        """``ok`` when the verdict judged valid data; otherwise the sample's status (the
        contact's, for its newest), ``tactile_<why>`` for a test that needs a pressure frame
        (a tactile one, or an F/T one with β from the frame) without a paired one, or the solver's."""
        if sample_status != VALID:
            return sample_status
        if not contact.has_tactile and self._needs_pad:
            # a contact without a frame that claims its pairing was fine contradicts itself
            why = contact.tactile_status if contact.tactile_status != VALID else "fault"
            return f"tactile_{why}"
        return VALID if v.status.usable else v.status.value


@dataclass(frozen=True, slots=True)
class _SampleView:
    """One earlier F/T sample of a batch as the slip tests read it (:class:`ContactView`'s
    fields): ``f_n`` N, ``f_t`` (2,) N, ``tau`` N·m, ``phi`` (N,) N, ``positions`` (N, 2) m."""

    f_n: float
    f_t: np.ndarray
    tau: float
    phi: np.ndarray
    positions: np.ndarray
