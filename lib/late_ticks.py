"""Late ticks of a real-time loop (the simulated rig's), told in numbers with what to do.

A loop paced by a timer of period ``T`` that is handed its ticks late (its process
waited for a CPU core) makes them up at once: a tick ``late`` ns after the one before
plus ``T`` stands for ``late // T`` ticks that came in a burst, and every sensor sample
of that time left up to ``late`` late. :class:`LateTicks` is fed the time of each tick
(ns, any monotonic clock; nothing here reads a clock) and words a report after a late
tick, at most one per ``report_every_ns``: how many ticks were late since the last
report, the worst by how much, and what to do (:func:`behind_real_time_advice`).
"""

from __future__ import annotations

__all__ = ["behind_real_time_advice", "LateTicks"]

_OTHER_REMEDIES = ("or lower the sensor rates (`ft_rate_hz:=250 tactile_rate_hz:=125`); or run `slipstack launch ... "
                   "--lockstep` for a deterministic run on the simulated clock, which never falls behind")


def behind_real_time_advice(realtime: bool) -> str:
    """What to do when a real-time loop cannot keep its tick (launch arguments of the shipped
    files); ``realtime``: the loop already ran under SCHED_FIFO, so raising its priority is no remedy."""
    if realtime:
        return ("it already runs with real-time priority (SCHED_FIFO), so something of equal or higher priority, "
                "or the kernel, held its core: free a core (stop other real-time work); " + _OTHER_REMEDIES)
    return ("give it a CPU core: run with `realtime:=10` (SCHED_FIFO, the default where the launcher may set it: "
            "as root, with CAP_SYS_NICE or after `ulimit -r 10`; the launch log says when it was not granted) or free "
            "a core; " + _OTHER_REMEDIES)


class LateTicks:
    """Counts the late ticks of a loop with period ``period_ns`` and words a rate-limited report.

    Args:
        period_ns: the timer's period (ns, > 0).
        late_after_ns: a tick later than this after its due time counts as late (ns, ≥ 0).
        report_every_ns: at most one report per this long (ns); the first late tick is
            reported at once, later ones summed up into the next report.
    """

    def __init__(self, period_ns: int, late_after_ns: int, report_every_ns: int) -> None:
        if period_ns <= 0 or late_after_ns < 0 or report_every_ns < 0:
            raise ValueError(f"LateTicks needs period_ns > 0 and the other times >= 0, got {period_ns}, "
                             f"{late_after_ns}, {report_every_ns}")
        self.period_ns = period_ns
        self.late_after_ns = late_after_ns
        self.report_every_ns = report_every_ns
        self.late_ticks = 0
        """Late ticks since the start (a burst of made-up ticks counts once)."""
        self.worst_ns = 0
        """The latest tick since the start, ns after its due time."""
        self._previous_ns: int | None = None
        self._reported_ns: int | None = None
        self._unreported = 0
        self._unreported_worst_ns = 0
        self._unreported_first_ns = 0

    def tick(self, now_ns: int) -> bool:
        """Note a tick handled at ``now_ns``; whether it was late."""
        previous, self._previous_ns = self._previous_ns, now_ns
        late = 0 if previous is None else now_ns - previous - self.period_ns
        if late <= self.late_after_ns:
            return False
        self.late_ticks += 1
        self.worst_ns = max(self.worst_ns, late)
        if not self._unreported:
            self._unreported_first_ns = now_ns - late
        self._unreported += 1
        self._unreported_worst_ns = max(self._unreported_worst_ns, late)
        return True

    def report(self, now_ns: int, scene_start_ns: int, realtime: bool = False) -> str | None:
        """The report due at ``now_ns``, if a late tick is untold and none was given for
        ``report_every_ns``; times in it count from ``scene_start_ns`` (s); ``realtime``: the
        loop runs under SCHED_FIFO (it changes what to do)."""
        if not self._unreported or (self._reported_ns is not None
                                    and now_ns - self._reported_ns < self.report_every_ns):
            return None
        text = self._report(scene_start_ns, realtime)
        self._reported_ns = now_ns
        self._unreported = self._unreported_worst_ns = 0
        return text

    def _report(self, scene_start_ns: int, realtime: bool) -> str:
        worst_ms = self._unreported_worst_ns / 1e6
        burst = self._unreported_worst_ns // self.period_ns
        since = (self._unreported_first_ns - scene_start_ns) / 1e9
        ticks = "1 tick" if self._unreported == 1 else f"{self._unreported} ticks"
        return (f"fell behind real time: {ticks} late from {since:.2f} s into the scene, the worst by "
                f"{worst_ms:.1f} ms ({burst} ticks of {self.period_ns / 1e6:g} ms made up at once: the sensor "
                f"samples of that time left in a burst, up to {worst_ms:.0f} ms late, and the controller saw them "
                f"that late); {self.late_ticks} late ticks in all, the worst by {self.worst_ns / 1e6:.1f} ms. "
                f"What to do: {behind_real_time_advice(realtime)}")
