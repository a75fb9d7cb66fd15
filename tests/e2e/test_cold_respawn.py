"""A process that replaces a crashed one starts ahead of other users' work: SCHED_FIFO 1 until
its nodes are ready (then its own priority), where the launcher may set it (root, CAP_SYS_NICE,
``ulimit -r``). A cold respawn beside busy loops took 4.3 s at normal scheduling.

The default graph, its control container killed twice in a row: the second restart has no warm
standby yet and starts a new process, whose scheduling is read while it imports."""

from __future__ import annotations

import os
import signal
import time

import pytest

from .conftest import pid_alive

pytestmark = pytest.mark.e2e


def _fifo_allowed() -> bool:
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
    except OSError:
        return False
    os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    return True


def _new_pid(g, node: str, old: int, timeout: float = 60.0) -> int:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        pid = g.graph()["nodes"][node].get("pid")
        if pid and pid != old and pid_alive(pid):
            return pid
        time.sleep(0.005)
    raise AssertionError(f"{node} not respawned:\n{g.log()[-3000:]}")


@pytest.mark.skipif(not _fifo_allowed(), reason="SCHED_FIFO needs root, CAP_SYS_NICE or `ulimit -r`")
def test_a_cold_respawn_starts_ahead_of_other_work(launch):
    g = launch("default", "record:=false", "check:=false")  # no check: two kills fail it by design
    g.wait_ready(timeout=120)
    first = g.graph()["nodes"]["fusion"]["pid"]
    os.kill(first, signal.SIGKILL)
    warm = _new_pid(g, "fusion", first)
    os.kill(warm, signal.SIGKILL)  # before its standby is ready: the next one starts cold
    cold = _new_pid(g, "fusion", warm)
    seen = set()
    deadline = time.monotonic() + 60
    while g.log().count("ready again") < 2 and time.monotonic() < deadline:
        try:
            seen.add((os.sched_getscheduler(cold) & ~os.SCHED_RESET_ON_FORK, os.sched_getparam(cold).sched_priority))
        except OSError:
            break
        time.sleep(0.002)
    assert "from a new process" in g.log(), g.log()[-3000:]
    assert (os.SCHED_FIFO, 1) in seen and (os.SCHED_OTHER, 0) not in seen, seen
