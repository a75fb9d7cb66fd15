"""A node's ``nice`` reaches its autogroup (each node runs in a session of its own), and its
``realtime_priority`` puts it, and the threads it starts, under SCHED_FIFO where permitted."""

from __future__ import annotations

import subprocess
import sys

import pytest

from slipstack.launch.priority import AUTOGROUP_PATH, set_autogroup_nice

needs_autogroups = pytest.mark.skipif(not AUTOGROUP_PATH.exists(), reason="kernel without scheduling autogroups")


def _autogroup_nice_of_child(nice: int) -> int:
    """Start a process in a new session as the launcher does, with ``nice``; its autogroup's nice."""
    child = subprocess.run(
        [sys.executable, "-c", "print(open('/proc/self/autogroup').read())"],
        start_new_session=True, preexec_fn=lambda: set_autogroup_nice(nice), capture_output=True, text=True,
        check=True, timeout=30)
    return int(child.stdout.split("nice")[1])


@needs_autogroups
def test_a_nice_reaches_the_autogroup_of_the_nodes_session() -> None:
    assert _autogroup_nice_of_child(7) == 7


def test_a_nice_in_a_missing_file_is_reported_not_raised(tmp_path) -> None:
    assert set_autogroup_nice(5, tmp_path / "absent" / "autogroup") is False


REALTIME_CHILD = """
import os, threading
from slipstack.launch.priority import has_realtime_priority, set_realtime_priority
granted = set_realtime_priority(3)
policies = []
thread = threading.Thread(target=lambda: policies.append(os.sched_getscheduler(0)))
thread.start(); thread.join()
print(granted, has_realtime_priority(os.getpid()), os.sched_getparam(0).sched_priority, policies[0] == os.SCHED_FIFO)
"""


def test_a_realtime_priority_is_granted_or_reported_and_reaches_the_threads_started_after() -> None:
    """Where the privilege is held (root, CAP_SYS_NICE, ``ulimit -r``) the process and a thread it
    starts afterwards (as ZeroMQ starts its I/O thread) run under SCHED_FIFO at the priority;
    without it the call says so and the process stays at normal scheduling."""
    child = subprocess.run([sys.executable, "-c", REALTIME_CHILD], capture_output=True, text=True, check=True, timeout=30)
    granted, is_fifo, priority, thread_fifo = child.stdout.split()
    if granted == "True":
        assert (is_fifo, priority, thread_fifo) == ("True", "3", "True")
    else:
        assert (is_fifo, priority, thread_fifo) == ("False", "0", "False")
