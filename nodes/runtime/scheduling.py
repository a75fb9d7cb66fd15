"""Whether a process runs with real-time priority (SCHED_FIFO; launch/priority.py grants it)."""

from __future__ import annotations

import os

__all__ = ["has_realtime_priority", "runs_realtime"]


def has_realtime_priority(pid: int) -> bool:
    """Whether process ``pid`` runs under ``SCHED_FIFO`` (``False`` if it is gone)."""
    try:
        return os.sched_getscheduler(pid) & ~os.SCHED_RESET_ON_FORK == os.SCHED_FIFO
    except OSError:
        return False


def runs_realtime() -> bool:
    """Whether this process runs under ``SCHED_FIFO``."""
    return has_realtime_priority(0)
