"""A node process's scheduling priority: its ``nice``, applied where Linux weighs it, and
its real-time priority.

More in docs/modules.md, `launch/priority.py`.
"""

from __future__ import annotations

import os
from pathlib import Path

from slipstack.nodes.runtime.scheduling import has_realtime_priority

__all__ = ["AUTOGROUP_PATH", "grant_realtime_priority", "has_realtime_priority", "set_autogroup_nice"]

AUTOGROUP_PATH = Path("/proc/self/autogroup")
"""This process's autogroup and its nice value (``/autogroup-123 nice 0``); absent when the
kernel has no autogroups."""


def set_autogroup_nice(nice: int, path: Path = AUTOGROUP_PATH) -> bool:
    """Give the calling process's autogroup the nice value ``nice`` (-20..19).

    Returns whether it took effect: ``False`` without autogroups or, for a value below
    the current one, without the privilege (the group keeps its priority).
    Call it in the node's process after it has started its own session.
    """
    try:
        path.write_text(f"{nice}\n")
    except OSError:
        return False
    return True


def grant_realtime_priority(pid: int, priority: int) -> bool:
    """Put every thread of process ``pid`` under ``SCHED_FIFO`` at ``priority`` (1-99); the
    threads it starts later share it. Returns whether it took effect (``False`` without the
    privilege, or if the process is gone)."""
    try:
        for tid in os.listdir(f"/proc/{pid}/task"):
            os.sched_setscheduler(int(tid), os.SCHED_FIFO, os.sched_param(priority))
    except OSError:
        return False
    return True

