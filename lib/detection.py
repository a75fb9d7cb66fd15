"""Slip detection over time: thresholds, hysteresis and latching (docs/math.md §3.1).

A load factor computed from *measured* data never exceeds 1: it reaches 1 at slip
onset and, once sliding, drops to about ``μ_d/μ_s`` (the peak of the paper's
Fig. 4). So the detector

- flags slip when the contact is *at* the limit: ``γ ≥ 1 − δ`` (margin ``≤ δ``),
- latches it through the static→dynamic drop: slip stays flagged while
  ``γ ≥ γ_release``, and
- releases only after ``γ < γ_release`` has held for ``release_ns``.

The release level is the *kinetic-friction floor*: while the contact slides, every
sliding patch carries at least ``μ_d φ_i`` (Coulomb friction only weakens from μ_s
down to μ_d with the distance slid, never below), so the measured load factor stays at
or above ``μ_d/μ_s``, up to sensor noise; a γ clearly below that floor means the
friction is no longer saturated: the object sticks again. Hence
``γ_release = μ_d/μ_s − 4σ_γ``: with the shipped rubber (μ_d/μ_s = 0.36/0.45 = 0.80)
and the measured frame-to-frame noise of the exact test's γ while sliding
(σ_γ ≈ 0.006–0.010 at F/T 500 Hz, tactile 250 Hz; ``tests/bench/bench_detection.py``)
the default is 0.76: under 0.03 % of the gross-slip frames of the shipped scenes fall
below it, except in the fast stick–slip jumps of Fig. 4a, which dip below it for under
20 ms as the object decelerates and re-sticks; the release dwell (20 ms) rides them
out. A different material needs ``gamma_release`` set from its own μ_d/μ_s
(``lib/identify.py`` identifies both from a Fig. 4a record).

What force data cannot tell: after the object re-sticks, the load can stay at or above
``μ_d/μ_s`` (a load held just under the sliding friction, or re-loading towards the
limit between stick–slip episodes); the latch then holds, or the onset band flags,
although the contact sticks. ``δ`` is the speed/accuracy knob: larger warns earlier and
costs such false alarms (measured in ``tests/bench/bench_detection.py``). Times are
integer ns.
"""

from __future__ import annotations

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
    """

    delta: float = 0.18
    gamma_release: float = 0.76
    release_ns: int = 20_000_000

    def __post_init__(self) -> None:
        if not 0.0 <= self.delta < 1.0:
            raise ConfigError(f"detector delta must lie in [0, 1), got {self.delta}")
        if not 0.0 < self.gamma_release <= 1.0:
            raise ConfigError(f"detector gamma_release must lie in (0, 1], got {self.gamma_release}")
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

        A non-finite margin (no verdict) keeps the current flag and restarts the release
        dwell: release needs ``release_ns`` of *valid* frames below the level, so a stretch
        without information never counts towards it. No contact clears the flag.
        """
        if not in_contact:
            self.slipping, self._below_since = False, None
            return False
        if margin != margin:  # NaN: no information, keep the flag, start the dwell again
            self._below_since = None
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
