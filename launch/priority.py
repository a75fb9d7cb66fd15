"""A node process's scheduling priority: its ``nice``, applied where Linux weighs it.

The launcher starts every node in a session of its own (``start_new_session``: a
Ctrl-C in the launcher's terminal reaches the launcher only, which stops the nodes in
order). With ``/proc/sys/kernel/sched_autogroup_enabled`` = 1 (the default of most
desktop distributions) each session is a scheduling *autogroup*: the CPU is shared
between autogroups first, and a process's own nice value only ranks it against the
other processes of its group. A node alone in its session would therefore ignore its
``nice``; :func:`set_autogroup_nice` gives the node's autogroup the same value, so that
``nice`` ranks nodes against each other and against the rest of the machine.

As for ``nice`` itself, a positive value (lower priority) needs no privilege; a
negative one needs CAP_SYS_NICE and is otherwise left at 0. docs/benchmarks.md
(scheduling) has the measurement.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["AUTOGROUP_PATH", "set_autogroup_nice"]

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
