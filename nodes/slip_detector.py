"""slip_detector: the slip verdict from each ``contact`` (docs/math.md §3).

The chosen ``method`` decides; the cheaper tests in ``also`` are computed alongside
and published in ``verdicts`` (name → [stick, margin]) so their agreement can be
watched and recorded. A :class:`~slipstack.lib.detection.SlipLatch` turns the
method's margin into the latched state (onset band ``delta`` held for
``onset_frames``, release level ``gamma_release`` and ``gamma_resume``, ``release_ms``).

More in docs/modules.md, `nodes/slip_detector.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from slipstack.lib.contact_view import pool_misfit
from slipstack.lib.detection import DetectorConfig
from slipstack.lib.detector import BELOW_NOISE, CONTACT_LOST, FT_TESTS, NOISE_CAPACITY, VALID, Detector, DetectorSettings
from slipstack.lib.known_cor import KNOWN_COR_METHOD
from slipstack.lib.limit_set import compile_kernels
from slipstack.lib.slip_tests import BETA_TESTS, SLIP_TESTS
from slipstack.messages import Contact, Slip
from slipstack.lib.errors import ConfigError
from slipstack.lib.material import Material, detector_thresholds
from slipstack.lib.onset_band import OnsetBand
from slipstack.lib.online_calibration import Learned
from slipstack.nodes.material_param import DEFAULT_MATERIAL, fill_from_material, refuse_implausible, resolve_material
from slipstack.nodes.runtime.node import Context, Input, Node, Output

__all__ = ["SlipDetector", "SlipDetectorParams"]


@dataclass(frozen=True)
class SlipDetectorParams:
    method: str = field(default="exact", metadata={
        "help": f"deciding test: one of {sorted([*SLIP_TESTS, KNOWN_COR_METHOD])}"})
    also: list[str] = field(default_factory=lambda: list(FT_TESTS), metadata={"help": "tests published alongside"})
    material: str = field(default="", metadata={
        "help": "material file (launch/materials/ name or path): mu, delta, gamma_release, gamma_resume unless "
                f"given; '': none, the shipped {DEFAULT_MATERIAL} (reported as uncalibrated)"})
    band: str = field(default="path", metadata={
        "help": "path: the onset band of each load's path and pressure spread where the material identified "
                "onsets of that kind (a material without load paths: delta), and a slip is released when the "
                "load proves the contact sticks (lib/onset_band.py); fixed: delta for every load, released only "
                "below gamma_release"})
    calibrate: str = field(default="off", metadata={
        "help": "online: learn mu, the band and the release level from the contact's confirmed slips "
                "(lib/online_calibration.py); off: keep the material's"})
    mu: float = field(default=math.nan, metadata={"help": "static friction coefficient; nan: the material's mu_s"})
    beta_m: float = field(default=0.0, metadata={"help": "torsional coefficient for F/T tests (m); 0: from tactile"})
    delta: float = field(default=math.nan, metadata={
        "help": "onset band: slip when gamma >= 1 - delta; nan: from the material (lib/material.py); with "
                "band path used only where the material has no load paths"})
    gamma_release: float = field(default=math.nan, metadata={
        "help": "slip stays latched while gamma >= this (just below mu_d/mu_s); nan: from the material"})
    release_ms: float = field(default=DetectorConfig.release_ns / 1e6,
                              metadata={"help": "gamma below release this long -> stick (ms)"})
    onset_frames: int = field(default=DetectorConfig.onset_frames, metadata={
        "help": "valid frames in a row in the band that raise the slip flag (>= 1), and as long as "
                "that many take at 1 kHz at any F/T rate"})
    gamma_resume: float = field(default=math.nan, metadata={
        "help": "a frame with gamma >= this restarts the release dwell (a noise margin above gamma_release); "
                "nan: from the material"})
    pool: int = field(default=1, metadata={"help": "sum taxels in pool x pool blocks before testing (1: off)"})
    known_cor_x_m: float = field(default=math.nan, metadata={
        "help": f"{KNOWN_COR_METHOD}: the fixed pivot's x in the pad frame (m); nan: none"})
    known_cor_y_m: float = field(default=math.nan, metadata={
        "help": f"{KNOWN_COR_METHOD}: the fixed pivot's y in the pad frame (m); nan: none"})

    def __post_init__(self) -> None:
        if self.calibrate not in CALIBRATE:
            raise ConfigError(f"slip_detector calibrate must be one of {CALIBRATE}, got {self.calibrate!r}")
        if self.band not in BANDS:
            raise ConfigError(f"slip_detector band must be one of {BANDS}, got {self.band!r}")
        if not (math.isfinite(self.release_ms) and self.release_ms >= 0.0):
            raise ConfigError(f"slip_detector release_ms must be a time >= 0 ms, got {self.release_ms!r}")
        refuse_implausible(self, beta_m="beta_s_m")
        delta_given = not math.isnan(self.delta)
        fill_from_material(self, mu="mu_s", delta="delta", gamma_release="gamma_release",
                           gamma_resume="gamma_resume")
        if delta_given and self.band == "path" and OnsetBand.of(resolve_material(self.material)).kinds:
            raise ConfigError(f"slip_detector delta := {self.delta:g} is not used with band path: the material "
                              f"{self.material!r} identified the band of each load path. Give band:=fixed to use "
                              "delta for every load, or leave delta at nan")


CALIBRATE = ("online", "off")
"""The values of ``calibrate``."""
BANDS = ("path", "fixed")
"""The values of ``band``."""
_UNCALIBRATED = "uncalibrated"
"""The node's status while it runs on the default material and has learned nothing."""

_WITHOUT_TACTILE = "tactile_off"
"""A tactile test's verdict on a contact of a stack run without tactile (fusion ``use_tactile = false``)."""
_JUDGED = (VALID, CONTACT_LOST)
"""Verdict statuses of a contact the slip test judged (valid data, or a loss of contact);
any other status of an earlier contact of a batch is the published verdict's, as fusion
passes an earlier sample's on, so the grip is held, not lowered, after a backlog with a
bad sample in it."""


class SlipDetector(Node):
    """Publishes ``slip`` for every contact: :class:`~slipstack.lib.detector.Detector`'s verdict."""

    name = "slip_detector"
    inputs = {"contact": Input("contact", Contact, policy="batch")}
    outputs = {"slip": Output("slip", Slip)}
    Params = SlipDetectorParams

    def __init__(self, params: SlipDetectorParams | None = None) -> None:
        super().__init__(params)
        p = self.params
        material = resolve_material(p.material)
        path = {}
        if p.band == "path":
            thresholds = detector_thresholds(material)
            path = {"onset_band": OnsetBand.of(material), "sliding_level": thresholds.sliding_level,
                    "stuck_margin": thresholds.stuck_margin}
        self.detector = Detector(DetectorSettings(
            mu=p.mu, delta=p.delta, gamma_release=p.gamma_release, method=p.method, also=tuple(p.also),
            beta_m=p.beta_m, release_ns=round(p.release_ms * 1e6), pool=p.pool, gamma_resume=p.gamma_resume,
            onset_frames=p.onset_frames, known_cor_m=self._known_cor(p),
            calibrate_from=material if p.calibrate == "online" else None, force_noise_n=material.force_noise_n,
            torque_noise_nm=material.torque_noise_nm, **path))
        self._said_without_tactile = False
        self._material_beta_m = material.beta_s_m  # for the advice when β is needed and there is no pad
        self._said_pool_misfit = False
        self._revision = 0
        self._said = (0, self.detector.settings.mu)  # (episodes, mu) of the last calibration line
        self._status = self._calibration_status(material)
        self._below_noise = False  # the last verdict's capacity was under the F/T's noise

    @staticmethod
    def _known_cor(p: SlipDetectorParams) -> tuple[float, float] | None:
        """The pivot if either coordinate is given (a half-given one is refused by the settings)."""
        given = (p.known_cor_x_m, p.known_cor_y_m)
        return None if all(math.isnan(v) for v in given) else given

    def _calibration_status(self, material: Material) -> tuple[str, str, str]:
        """(status, short detail for ``diagnostics``, advice for the start line): what the
        thresholds come from."""
        p, d = self.params, self.detector.settings
        now = f"mu {d.mu:.3f}, band delta {d.delta:.3f}, release {d.gamma_release:.3f}"
        if material.refused:
            return ("refused-material", f"{p.material} written by identify --force ({now})",
                    f"identify refused it: {material.refused}")
        if p.material:
            return "ok", "", ""
        online = " It learns online from the contact's confirmed slips (calibrate:=online)." if p.calibrate == "online" else ""
        return (_UNCALIBRATED, f"no material file, the shipped {DEFAULT_MATERIAL} ({now})",
                "On another contact slip is flagged early, or late or not at all (docs/benchmarks.md). Identify "
                "yours: slipstack identify RAMP.mcap... -o mine.toml, then material:=mine.toml." + online)

    def _say_learned(self, learned: Learned, ctx: Context) -> None:
        """Status: what the online calibration learned; a log line when it confirmed a slip
        or μ moved by 1 % since the last line (the capacity rule moves it in small steps)."""
        mu = self.detector.settings.mu * learned.mu_scale
        text = (f"from {learned.episodes} confirmed slip(s) and the loads carried: mu {mu:.3f}, band delta "
                f"{learned.delta:.3f}, release {learned.gamma_release:.3f}")
        self._status = ("calibrated-online", text, "")
        if not self._below_noise:
            ctx.set_status("calibrated-online", text)
        said_episodes, said_mu = self._said
        if learned.episodes != said_episodes or abs(mu - said_mu) >= 0.01 * said_mu:
            self._said = (learned.episodes, mu)
            ctx.log(f"calibrated online {text}")

    def start(self, ctx: Context) -> None:
        compile_kernels()  # before the node reports ready, so its first contact runs at full speed
        status, detail, advice = self._status
        ctx.set_status(status, detail)
        if status != "ok":
            ctx.log(f"{status}: {detail}. {advice}")

    def _say_below_noise(self, below: bool, f_n: float, ctx: Context) -> None:
        """Status ``below-noise`` while the contact's capacity is under the F/T's noise (no
        verdict: the grip controller holds the grip), the calibration status again after."""
        self._below_noise = below
        if below:
            ctx.set_status("below-noise", f"f_n {f_n:.2f} N: a friction capacity under {NOISE_CAPACITY:g} x the F/T's "
                           "noise is not judged; the grip is held")
        else:
            ctx.set_status(*self._status[:2])

    def _without_tactile_advice(self) -> str:
        """What to do when the deciding test needs the pad that fusion runs without."""
        p = self.params
        if p.method in BETA_TESTS:
            beta = self._material_beta_m
            given = f"e.g. the material's {beta:.3g} m" if math.isfinite(beta) else "in m"
            return (f"method {p.method} takes beta from the tactile pad unless beta_m is given, but fusion runs "
                    f"F/T-only (tactile:=false): every verdict holds the grip (fail-safe). Set beta_m:= ({given}) "
                    "as `slipstack launch fig11` does, or method:=coulomb")
        return (f"method {p.method} needs the tactile pad, but fusion runs F/T-only (tactile:=false): every verdict "
                "holds the grip (fail-safe). Pick an F/T test, e.g. method:=coulomb law:=linear as `slipstack launch "
                f"fig10` does, or {', '.join(BETA_TESTS)} with beta_m:= (m)")

    def on_contact(self, msgs: tuple[Contact, ...], ctx: Context) -> None:
        detector = self.detector
        judged = detector.samples_judged
        held = None  # the first earlier contact's status without a usable verdict
        for msg in msgs:
            v = detector.step(msg, msg.header.stamp_ns, tactile_frame=msg.header.sources.get("tactile"))
            if held is None and v.status not in _JUDGED and msg is not msgs[-1]:
                held = v.status
        ctx.count("slip_test.samples_judged", detector.samples_judged - judged)
        cal = detector.calibration
        if cal is not None and cal.revision != self._revision:
            self._revision = cal.revision
            self._say_learned(cal.learned, ctx)
        status = held if held is not None and v.status in _JUDGED else v.status
        if not v.solver_status.usable:
            ctx.count(f"slip.{v.solver_status.value}")
        if v.status == BELOW_NOISE:
            ctx.count("slip.below_noise")
        if (v.status == BELOW_NOISE) != self._below_noise:
            self._say_below_noise(v.status == BELOW_NOISE, msg.f_n, ctx)
        if v.status == _WITHOUT_TACTILE and not self._said_without_tactile:
            self._said_without_tactile = True
            ctx.report_error(self._without_tactile_advice())
        if not self._said_pool_misfit and (misfit := pool_misfit(msg, self.params.pool)):
            self._said_pool_misfit = True
            ctx.report_error(misfit)
        ctx.publish("slip", Slip(state=v.state, margin=v.margin, method=v.method,
                                 verdicts={name: list(pair) for name, pair in v.verdicts.items()},
                                 gamma=v.gamma, status=status, f_n=msg.f_n, f_t=msg.f_t, tau=msg.tau,
                                 p_c=np.array(v.p_c if v.p_c is not None else (0.0, 0.0)),
                                 p_c_valid=v.p_c is not None),
                    stamp_ns=v.t_ns, sources=msg.header.sources)
