"""Online calibration: the detector follows the contact at hand (docs/math.md §3.3).

From a material's thresholds (the shipped default without a file) it learns from the
detector's own load factors: μ rises to any load the contact carried beyond it (capacity
rule); each confirmed slip (the flag up 50 ms without a break) narrows the band to the
lower prediction bound of the confirmed onset levels and raises the release level to the
lowest sliding level less its noise. Only ever towards fewer flags, never past what a
measurement shows, bounded; a false alarm cannot widen anything. :class:`CalibratedLatch`
is the detector's latch with it (``lib/detector.py`` and the detection benchmark).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, replace

import numpy as np

from slipstack.lib.detection import DetectorConfig, SlipLatch
from slipstack.lib.material import DetectorThresholds, Material, detector_thresholds

__all__ = ["CalibrationSettings", "Learned", "OnlineCalibration", "CalibratedLatch", "MAX_LEVELS"]

_LEAST = 1e-3
"""Levels are kept in [_LEAST, 1] (a load factor computed from measured data stays under 1)."""

MAX_LEVELS = 64
"""Onset and sliding levels kept (the newest)."""


@dataclass(frozen=True)
class CalibrationSettings:
    """How the calibration confirms and bounds what it learns.

    confirm_ns: how long the flag must stay up for an episode to count, ns.
    min_frames: valid frames in a row whose mean γ above 1 raises μ.
    max_scale: μ never rises beyond this multiple of the starting μ.
    """

    confirm_ns: int = 50_000_000
    min_frames: int = 8
    max_scale: float = 3.0


@dataclass(frozen=True)
class Learned:
    """What the calibration has learned so far (all dimensionless; ``mu_scale``: the
    learned μ over the starting one)."""

    mu_scale: float
    delta: float
    gamma_release: float
    gamma_resume: float
    episodes: int


class OnlineCalibration:
    """Feed every verdict with :meth:`step`; read :attr:`learned` (what the latch should use)."""

    def __init__(self, material: Material, start: DetectorThresholds | None = None,
                 settings: CalibrationSettings = CalibrationSettings()) -> None:
        """``material``: the starting point (its noise, and its thresholds unless ``start`` gives them)."""
        self.material, self.settings = material, settings
        start = start or detector_thresholds(material)
        self.learned = Learned(1.0, start.delta, start.gamma_release, start.gamma_resume, 0)
        self._sigma = max(material.gamma_noise_stick, 0.002) if math.isfinite(material.gamma_noise_stick) else 0.002
        self._recent: deque[float] = deque(maxlen=settings.min_frames)
        self._onsets: deque[float] = deque(maxlen=MAX_LEVELS)
        self._slides: deque[float] = deque(maxlen=MAX_LEVELS)
        self._run_start: int | None = None
        self._run: list[float] = []
        self._confirmed = False
        self.revision = 0
        """How many times :attr:`learned` changed."""

    def scaled(self, gamma: float) -> float:
        """``gamma`` (computed with the starting μ) with the learned μ."""
        return gamma / self.learned.mu_scale

    def step(self, t_ns: int, gamma: float, slipping: bool) -> bool:
        """One verdict: ``gamma`` with the starting μ (NaN: no valid verdict), whether the
        latch says slip. Returns whether :attr:`learned` changed."""
        changed = self._capacity(gamma)
        g = self.scaled(gamma)
        if slipping:
            if self._run_start is None:
                self._run_start, self._run, self._confirmed = t_ns, [], False
            if math.isfinite(g) and len(self._run) < 100_000:
                self._run.append(g)
            if not self._confirmed and t_ns - self._run_start >= self.settings.confirm_ns and self._run:
                self._confirmed = True
        elif self._run_start is not None:
            if self._confirmed and self._run:
                changed |= self._learn_episode(np.asarray(self._run))
            self._run_start, self._run = None, []
        self.revision += changed
        return changed

    def _capacity(self, gamma: float) -> bool:
        if not math.isfinite(gamma):
            self._recent.clear()
            return False
        self._recent.append(gamma)
        m = self.settings.min_frames
        if len(self._recent) < m:
            return False
        lower = float(np.mean(self._recent)) - 3.0 * self._sigma / math.sqrt(m)  # in starting-μ units
        scale = min(lower, self.settings.max_scale)
        if scale <= self.learned.mu_scale:
            return False
        self.learned = replace(self.learned, mu_scale=scale)
        self._recent.clear()
        return True

    def _learn_episode(self, run: np.ndarray) -> bool:
        smooth = np.convolve(run, np.ones(min(5, run.size)) / min(5, run.size), mode="valid")
        self._onsets.append(min(max(float(smooth.max()), _LEAST), 1.0))
        self._slides.append(min(max(float(np.median(run[run.size // 2:])), _LEAST), 1.0))
        seen = replace(self.material, mu_d=self.material.mu_s * min(self._slides), beta_s_m=math.nan,
                       onset_gamma=tuple(self._onsets), onset_path=(), onset_spread=())
        new = detector_thresholds(seen)
        old = self.learned
        delta = min(old.delta, new.delta)
        release = min(max(old.gamma_release, new.gamma_release), 1.0 - delta)
        resume = max(release, min(max(old.gamma_resume, new.gamma_resume), 1.0 - delta))
        self.learned = Learned(old.mu_scale, delta, release, resume, old.episodes + 1)
        return True


class CalibratedLatch:
    """A :class:`~slipstack.lib.detection.SlipLatch` with :class:`OnlineCalibration` from
    ``calibrate_from`` (None: the plain latch): margins computed with the starting μ in,
    the slip flag and the margin with the learned μ out."""

    def __init__(self, config: DetectorConfig, calibrate_from: Material | None = None) -> None:
        self.latch = SlipLatch(config)
        start = DetectorThresholds(config.delta, config.gamma_release, config.resume_level)
        self.calibration = OnlineCalibration(calibrate_from, start) if calibrate_from is not None else None

    @property
    def config(self) -> DetectorConfig:
        return self.latch.config

    def update(self, t_ns: int, margin: float, *, in_contact: bool = True,
               delta: float | None = None) -> tuple[bool, float]:
        """(slip flag, margin with the learned μ) for one frame's ``margin`` (NaN: no verdict)
        and band ``delta`` (None: the config's, or what the calibration learned)."""
        cal = self.calibration
        if cal is None:
            return self.latch.update(t_ns, margin, in_contact=in_contact, delta=delta), margin
        raw = 1.0 - margin  # γ with the starting μ; NaN stays NaN
        margin = 1.0 - cal.scaled(raw)
        slipping = self.latch.update(t_ns, margin, in_contact=in_contact,
                                     delta=None if delta is None or cal.learned.episodes else delta)
        if in_contact and cal.step(t_ns, raw, slipping):
            learned = cal.learned
            self.latch.config = replace(self.latch.config, delta=learned.delta, gamma_release=learned.gamma_release,
                                        gamma_resume=learned.gamma_resume)
        return slipping, margin
