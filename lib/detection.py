"""Slip detection over time: thresholds, hysteresis and latching (MATH.md §3.1).

A load factor computed from *measured* data never exceeds 1: it reaches 1 at slip
onset and, once sliding, drops to about ``μ_d/μ_s`` (the peak of the paper's
Fig. 4). So the detector

- flags slip when the contact is *at* the limit: ``γ ≥ 1 − δ`` (margin ``≤ δ``),
- latches it through the static→dynamic drop: slip stays flagged while
  ``γ ≥ γ_release`` (set below ``μ_d/μ_s``), and
- releases only after ``γ < γ_release`` has held for ``release_ns``.

``δ`` is the speed/accuracy knob: larger warns earlier and costs false alarms
(measured in ``tests/bench/bench_detection.py``). Times are integer ns.
"""

from __future__ import annotations

from dataclasses import dataclass

from slipstack.lib.errors import ConfigError

__all__ = ["DetectorConfig", "SlipLatch"]


@dataclass(frozen=True)
class DetectorConfig:
    """Thresholds of :class:`SlipLatch`.

    delta: onset band: slip when margin ``1 − γ ≤ delta`` (dimensionless, ≥ 0).
    gamma_release: slip stays latched while ``γ ≥ gamma_release`` (dimensionless).
    release_ns: how long ``γ < gamma_release`` must hold before stick is declared (ns).
    """

    delta: float = 0.18
    gamma_release: float = 0.7
    release_ns: int = 30_000_000

    def __post_init__(self) -> None:
        if not 0.0 <= self.delta < 1.0:
            raise ConfigError(f"detector delta must lie in [0, 1), got {self.delta}")
        if not 0.0 < self.gamma_release <= 1.0 - self.delta:
            raise ConfigError(
                f"detector gamma_release must lie in (0, 1 - delta] = (0, {1 - self.delta:g}], got {self.gamma_release}"
            )
        if self.release_ns < 0:
            raise ConfigError(f"detector release_ns must be >= 0 ns, got {self.release_ns}")


class SlipLatch:
    """Turns a per-frame margin into a latched slip flag."""

    def __init__(self, config: DetectorConfig | None = None) -> None:
        self.config = config or DetectorConfig()
        self.slipping = False
        self._below_since: int | None = None

    def update(self, t_ns: int, margin: float, *, in_contact: bool = True) -> bool:
        """Feed one frame's margin (``1 − γ``); returns whether slip is flagged.

        A non-finite margin (no verdict) keeps the current flag; no contact clears it.
        """
        if not in_contact:
            self.slipping, self._below_since = False, None
            return False
        if margin != margin:  # NaN: no information, keep the state
            return self.slipping
        gamma = 1.0 - margin
        cfg = self.config
        if margin <= cfg.delta:
            self.slipping, self._below_since = True, None
        elif self.slipping:
            if gamma >= cfg.gamma_release:
                self._below_since = None
            elif self._below_since is None:
                self._below_since = t_ns
            elif t_ns - self._below_since >= cfg.release_ns:
                self.slipping, self._below_since = False, None
        return self.slipping
