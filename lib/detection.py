"""Slip detection over time: onset band, latch and release (docs/math.md §3.1).

A load factor computed from *measured* data never exceeds 1: it reaches 1 at slip
onset and, once sliding, drops to about ``μ_d/μ_s`` (the peak of the paper's
Fig. 4). So :class:`SlipLatch`

More in docs/modules.md, `lib/detection.py`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from slipstack.lib.errors import ConfigError

__all__ = ["DetectorConfig", "SlipLatch"]


@dataclass(frozen=True)
class DetectorConfig:
    """Thresholds of :class:`SlipLatch`.

    delta: onset band: slip when margin ``1 − γ ≤ delta`` (dimensionless, ≥ 0).
    gamma_release: slip stays latched while ``γ ≥ gamma_release`` (dimensionless, in
        (0, 1]); just below the kinetic-friction floor ``μ_d/μ_s`` (see the module
        docstring). Above ``1 − delta`` it acts as ``1 − delta`` (the onset band then
        holds the flag by itself), so a wide band needs no matching release level.
    release_ns: how long ``γ < gamma_release`` must hold before stick is declared (ns).
    gamma_resume: a frame with ``γ ≥ gamma_resume`` restarts the release dwell
        (dimensionless); NaN or anything below ``gamma_release`` acts as
        ``gamma_release``. Set it a noise margin above the release level, so that a
        frame above the level only by the noise does not restart the dwell.
    onset_frames: how many valid frames in a row must be in the band to raise the flag
        (≥ 1; frames without a verdict neither count nor break the row). Two: a load
        held just under the band's edge crosses it on single noisy frames; two in a
        row are that much rarer, at the cost of one frame at an onset.
    onset_ns: and how long, ns (≥ 0): from the stamp of the row's first frame to the
        current one. 0: frames only (the latch's own default, for offline use).
    sliding_level: γ a sliding contact transmits (``μ_d/μ_s``; dimensionless); with
        ``stuck_margin`` (the noise margin above it), a flag whose slip reached below
        ``sliding_level + stuck_margin`` is released after ``release_ns`` above it
        (outside the band). NaN: no such release.
    """

    delta: float = 0.18
    gamma_release: float = 0.76
    release_ns: int = 20_000_000
    gamma_resume: float = math.nan
    onset_frames: int = 2
    onset_ns: int = 0
    sliding_level: float = math.nan
    stuck_margin: float = math.nan

    def __post_init__(self) -> None:
        if not 0.0 <= self.delta < 1.0:
            raise ConfigError(f"detector delta must lie in [0, 1), got {self.delta}")
        if not 0.0 < self.gamma_release <= 1.0:
            raise ConfigError(f"detector gamma_release must lie in (0, 1], got {self.gamma_release}")
        if self.release_ns < 0:
            raise ConfigError(f"detector release_ns must be >= 0 ns, got {self.release_ns}")
        if not (isinstance(self.onset_frames, int) and self.onset_frames >= 1):
            raise ConfigError(f"detector onset_frames must be an integer >= 1, got {self.onset_frames!r}")
        if not (isinstance(self.onset_ns, int) and self.onset_ns >= 0):
            raise ConfigError(f"detector onset_ns must be an integer >= 0 ns, got {self.onset_ns!r}")
        if not (math.isnan(self.sliding_level) or 0.0 < self.sliding_level <= 1.0) or not (
                math.isnan(self.stuck_margin) or self.stuck_margin >= 0.0):
            raise ConfigError(f"detector sliding_level must lie in (0, 1] and stuck_margin be >= 0 (or nan: no "
                              f"release when stuck), got {self.sliding_level}, {self.stuck_margin}")
        if not (math.isnan(self.gamma_resume) or 0.0 < self.gamma_resume <= 1.0):
            raise ConfigError(f"detector gamma_resume must lie in (0, 1] (or be nan: gamma_release), "
                              f"got {self.gamma_resume}")

    @property
    def stuck_level(self) -> float:
        """γ above which a contact that slid proves that it sticks (inf: never)."""
        level = self.sliding_level + self.stuck_margin
        return level if level == level else math.inf

    @property
    def resume_level(self) -> float:
        """The γ at or above which a frame restarts the release dwell (dimensionless)."""
        if math.isnan(self.gamma_resume):
            return self.gamma_release
        return max(self.gamma_resume, self.gamma_release)


class SlipLatch:
    """Turns a per-frame margin into a latched slip flag."""

    def __init__(self, config: DetectorConfig | None = None) -> None:
        self.config = config or DetectorConfig()
        self.slipping = False
        self._below_since: int | None = None
        self._in_band = 0  # valid frames in a row in the band (while not yet slipping)
        self._band_since: int | None = None  # stamp of the row's first frame (ns)
        self._slid = False  # since the flag rose, a frame below the stuck level
        self._above_since: int | None = None  # since when above the stuck level after that (ns)

    def update(self, t_ns: int, margin: float, *, in_contact: bool = True, delta: float | None = None) -> bool:
        """Feed one frame's margin (``1 − γ``); returns whether slip is flagged.

        ``delta``: this frame's band width (``lib/onset_band.py``; None: the config's).
        A non-finite margin (no verdict) keeps the current flag and restarts the release
        dwells: a release needs ``release_ns`` of *valid* frames, so a stretch without
        information never counts towards it. No contact clears the flag.
        """
        if not in_contact:
            self.slipping, self._below_since, self._in_band, self._band_since = False, None, 0, None
            self._above_since = None
            return False
        if margin != margin:  # NaN: no information, keep the flag, start the dwells again
            self._below_since = self._above_since = None
            return self.slipping
        gamma = 1.0 - margin
        cfg = self.config
        if margin <= (cfg.delta if delta is None else delta):
            self._in_band = min(self._in_band + 1, cfg.onset_frames)
            if self._band_since is None:
                self._band_since = t_ns
            if not self.slipping and self._in_band >= cfg.onset_frames and t_ns - self._band_since >= cfg.onset_ns:
                self.slipping, self._slid = True, False
            if self.slipping:
                self._below_since = self._above_since = None
            return self.slipping
        self._in_band, self._band_since = 0, None
        if self.slipping:
            self._release_when_stuck(t_ns, gamma)
        if self.slipping:
            if gamma >= cfg.resume_level:
                self._below_since = None
            elif self._below_since is None:
                if gamma < cfg.gamma_release:
                    self._below_since = t_ns
            elif t_ns - self._below_since >= cfg.release_ns:
                self.slipping, self._below_since = False, None
        return self.slipping

    def _release_when_stuck(self, t_ns: int, gamma: float) -> None:
        """Clear the flag after ``release_ns`` above the stuck level, once the slip went below it."""
        cfg = self.config
        if gamma < cfg.stuck_level:
            self._slid, self._above_since = True, None
        elif self._slid:
            if self._above_since is None:
                self._above_since = t_ns
            elif t_ns - self._above_since >= cfg.release_ns:
                self.slipping, self._below_since, self._above_since = False, None, None
