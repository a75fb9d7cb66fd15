"""Where a node process's CPU goes, stage by stage (for benchmarks; off by default).

With ``SLIPSTACK_STAGE_CPU=1`` in its environment, a node process charges the CPU
time of its main thread (``time.thread_time_ns``: CLOCK_THREAD_CPUTIME_ID, ns) to
one stage at a time and reports the totals on ``diagnostics`` as
``cpu.<stage>_us`` (cumulative µs of thread CPU time; each node of a container
reports its own decode/handler/encode/send/receive, the first member the
process's poll and loop). The stages:

More in docs/modules.md, `nodes/runtime/stage_cpu.py`.
"""

from __future__ import annotations

import os
import time

__all__ = ["STAGE_CPU_ENV", "STAGES", "StageCpu", "stage_cpu_from_env"]

STAGE_CPU_ENV = "SLIPSTACK_STAGE_CPU"
STAGES = ("poll", "receive", "decode", "handler", "encode", "send", "loop")


class StageCpu:
    """Charges thread CPU time to ``(owner, stage)`` keys, one current key at a time.

    :meth:`enter` closes the running interval (charged to the current key) and makes
    ``key`` current; it returns the key it replaced, so a nested stage restores it.
    """

    def __init__(self, owner: str) -> None:
        self.ns: dict[tuple[str, str], int] = {}
        self.current: tuple[str, str] = (owner, "loop")
        self._t = time.thread_time_ns()

    def enter(self, key: tuple[str, str]) -> tuple[str, str]:
        t = time.thread_time_ns()
        prev = self.current
        self.ns[prev] = self.ns.get(prev, 0) + t - self._t
        self._t = t
        self.current = key
        return prev

    def counters(self, owner: str) -> dict[str, float]:
        """``cpu.<stage>_us`` of ``owner`` (cumulative µs)."""
        return {f"cpu.{stage}_us": ns / 1e3 for (who, stage), ns in self.ns.items() if who == owner}


def stage_cpu_from_env(owner: str) -> StageCpu | None:
    """A :class:`StageCpu` charging the loop to ``owner`` if ``SLIPSTACK_STAGE_CPU`` is 1, else ``None``."""
    return StageCpu(owner) if os.environ.get(STAGE_CPU_ENV) == "1" else None
