"""Clock offset between two machines from ping exchanges (the NTP on-wire formula).

A ping leaves here at ``t1`` (our clock), arrives there at ``t2`` and its answer leaves
at ``t3`` (their clock), and is back here at ``t4`` (our clock). With equal delays both
ways, their clock minus ours is

    θ = ((t2 − t1) + (t3 − t4)) / 2,      round trip δ = (t4 − t1) − (t3 − t2),

More in docs/modules.md, `lib/clock_offset.py`.
"""

from __future__ import annotations

import statistics
from collections import deque
from dataclasses import dataclass

__all__ = ["OffsetEstimate", "ClockOffset"]


@dataclass(frozen=True)
class OffsetEstimate:
    """Their clock minus ours (ns), how far off that may be (ns), and from how many exchanges."""

    offset_ns: int
    uncertainty_ns: int
    samples: int


class ClockOffset:
    """The offset of a peer's clock, from the last ``window`` ping exchanges."""

    def __init__(self, window: int = 64) -> None:
        if window < 1:
            raise ValueError(f"window must be >= 1; got {window}")
        self._samples: deque[tuple[int, int]] = deque(maxlen=window)  # (round trip, offset)

    def add(self, t1: int, t2: int, t3: int, t4: int) -> bool:
        """One exchange; False (and ignored) if its times are impossible (negative round
        trip: a reply to another ping, or a clock stepped meanwhile)."""
        round_trip = (t4 - t1) - (t3 - t2)
        if round_trip < 0 or t3 < t2:
            return False
        self._samples.append((round_trip, ((t2 - t1) + (t3 - t4)) // 2))
        return True

    def estimate(self) -> OffsetEstimate | None:
        """The offset from the exchanges so far; None before the first."""
        samples = tuple(self._samples)  # one C call: a snapshot even while another thread adds
        if not samples:
            return None
        trips = sorted(rt for rt, _ in samples)
        cut = trips[(len(trips) - 1) // 2]
        kept = [(rt, off) for rt, off in samples if rt <= cut]
        offsets = [off for _, off in kept]
        median = statistics.median(offsets)
        spread = 1.4826 * statistics.median(abs(o - median) for o in offsets)
        half_trip = min(rt for rt, _ in kept) / 2
        return OffsetEstimate(round(median), round(max(half_trip, spread)), len(samples))
