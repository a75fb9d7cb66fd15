"""A node process's scheduling priority: its ``nice``, applied where Linux weighs it, and
its real-time priority.

The launcher starts every node in a session of its own (``start_new_session``: a
Ctrl-C in the launcher's terminal reaches the launcher only, which stops the nodes in
order). With ``/proc/sys/kernel/sched_autogroup_enabled`` = 1 (the default of most
desktop distributions) each session is a scheduling *autogroup*: the CPU is shared
between autogroups first, and a process's own nice value only ranks it against the
other processes of its group. A node alone in its session would therefore ignore its
``nice``; :func:`set_autogroup_nice` gives the node's autogroup the same value, so that
``nice`` ranks nodes against each other and against the rest of the machine.

As for ``nice`` itself, a positive value (lower priority) needs no privilege; a
negative one needs CAP_SYS_NICE and is otherwise left at 0.

A node with a ``realtime_priority`` (1-99) runs under ``SCHED_FIFO`` instead, where the
launcher may set it (root, CAP_SYS_NICE, or ``ulimit -r`` at least that high): a
real-time process runs as soon as it wakes, ahead of every normal process, so other
users' work on the machine no longer delays the control path (beside two CPU hogs on 2
cores: 0.6-3.1 % of F/T samples skipped and p99 0.73 ms, against 15-16 % and 3.0-4.4 ms with
``nice = -5`` alone; docs/benchmarks.md, scheduling). Linux's real-time throttling
(``/proc/sys/kernel/sched_rt_runtime_us``, 95 % of each CPU by default) bounds what a
runaway node could take. The threads a node starts share its priority (ZeroMQ's I/O
thread moves its frames: ``SCHED_RESET_ON_FORK`` would leave it at normal scheduling,
since a thread is a fork to Linux here). A node process starts, and a warm standby
waits, at normal scheduling: their imports and kernel loads (about a second of CPU each)
run beside the running graph rather than ahead of it, and the launcher gives a process
its priority once its nodes report ready (:func:`grant_realtime_priority`). A process that
replaces a crashed one starts at ``SCHED_FIFO`` 1 until then: ahead of other users' work
(a cold respawn beside busy loops took 4.3 s), behind the running nodes.
"""

from __future__ import annotations

import os
from pathlib import Path

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


def has_realtime_priority(pid: int) -> bool:
    """Whether process ``pid`` runs under ``SCHED_FIFO`` (``False`` if it is gone)."""
    try:
        return os.sched_getscheduler(pid) & ~os.SCHED_RESET_ON_FORK == os.SCHED_FIFO
    except OSError:
        return False
