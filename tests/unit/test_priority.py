"""A node's ``nice`` reaches its autogroup (each node runs in a session of its own), and its
``realtime_priority`` puts it, and the threads it starts, under SCHED_FIFO where permitted."""

from __future__ import annotations

import subprocess
import sys

import pytest

from slipstack.launch.priority import AUTOGROUP_PATH, grant_realtime_priority, set_autogroup_nice

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
import os, sys, threading
from slipstack.launch.priority import has_realtime_priority
before = threading.Event()
older = threading.Thread(target=before.wait)
older.start()
print("ready", flush=True)
sys.stdin.readline()
policies = []
newer = threading.Thread(target=lambda: policies.append(os.sched_getscheduler(0)))
newer.start(); newer.join()
older_policy = os.sched_getscheduler(older.native_id)
before.set(); older.join()
print(has_realtime_priority(os.getpid()), os.sched_getparam(0).sched_priority, older_policy == os.SCHED_FIFO,
      policies[0] == os.SCHED_FIFO)
"""


def test_a_realtime_priority_is_granted_to_every_thread_of_a_ready_process_or_reported():
    """Where the privilege is held (root, CAP_SYS_NICE, ``ulimit -r``) the launcher's grant puts a
    running process under SCHED_FIFO at the priority: the threads it had (as ZeroMQ's I/O thread)
    and the threads it starts afterwards; without it the call says so and nothing changes."""
    child = subprocess.Popen([sys.executable, "-c", REALTIME_CHILD], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                             text=True)
    try:
        assert child.stdout.readline().strip() == "ready"
        granted = grant_realtime_priority(child.pid, 3)
        out, _ = child.communicate("go\n", timeout=30)
    finally:
        child.kill()
    is_fifo, priority, older_fifo, newer_fifo = out.split()
    if granted:
        assert (is_fifo, priority, older_fifo, newer_fifo) == ("True", "3", "True", "True")
    else:
        assert (is_fifo, priority, older_fifo, newer_fifo) == ("False", "0", "False", "False")
    assert grant_realtime_priority(child.pid, 3) is False  # gone
