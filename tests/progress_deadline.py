"""Deadlines for tests that wait on real processes, counted in the time those processes could
run: wall time less the longest time any of them waited for a CPU (``run_delay`` of
/proc/PID/schedstat). On an idle host that is the wall clock; beside busy loops it
stretches by as much as the work was held back, so a wait fails on a stuck process, not
on a busy machine (docs/portability.md §4)."""

from __future__ import annotations

import os
import subprocess
import tempfile
import time
from typing import Iterable

__all__ = ["ProgressDeadline", "process_tree", "run"]


def _run_delay_ns(pid: int) -> int | None:
    try:
        with open(f"/proc/{pid}/schedstat") as fh:
            return int(fh.read().split()[1])
    except (OSError, IndexError, ValueError):
        return None


def process_tree(root: int) -> list[int]:
    """``root`` and its live descendants (a launcher's node processes, their children)."""
    children: dict[int, list[int]] = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as fh:
                    ppid = int(fh.read().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(entry))
    tree, todo = [], [root]
    while todo:
        pid = todo.pop()
        tree.append(pid)
        todo += children.get(pid, [])
    return tree


class ProgressDeadline:
    """``budget_s`` of the time the watched processes (the test's own and ``pids()``) could run."""

    def __init__(self, budget_s: float, pids=lambda: ()) -> None:
        self.budget_s = budget_s
        self._pids = pids
        self._start = time.monotonic()
        self._first: dict[int, int] = {}
        self._waited: dict[int, int] = {}
        self._watch([os.getpid()])

    def _watch(self, pids: Iterable[int]) -> None:
        for pid in pids:
            delay = _run_delay_ns(pid)
            if delay is not None:
                self._waited[pid] = delay - self._first.setdefault(pid, delay)

    def elapsed_s(self) -> float:
        """Wall time since the start less the longest wait for a CPU of a watched process."""
        self._watch([os.getpid(), *self._pids()])
        return time.monotonic() - self._start - max(self._waited.values(), default=0) / 1e9

    def expired(self) -> bool:
        return self.elapsed_s() > self.budget_s

    def __str__(self) -> str:
        return (f"{self.budget_s:.0f} s of run time ({time.monotonic() - self._start:.0f} s wall, "
                f"{max(self._waited.values(), default=0) / 1e9:.0f} s of it waiting for a CPU)")


def run(args: list[str], budget_s: float, **popen) -> subprocess.CompletedProcess:
    """``subprocess.run(args, capture_output=True, text=True)`` with ``budget_s`` of the run
    time of the command and its children instead of a wall-clock timeout; killed past it."""
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        proc = subprocess.Popen(args, stdout=out, stderr=err, **popen)
        deadline = ProgressDeadline(budget_s, lambda: process_tree(proc.pid))
        while proc.poll() is None and not deadline.expired():
            time.sleep(0.05)
        if proc.poll() is None:
            proc.kill()
            proc.wait()
            out.seek(0)
            raise AssertionError(f"{' '.join(args)} not done after {deadline}:\n"
                                 + out.read().decode(errors="replace")[-3000:])
        out.seek(0)
        err.seek(0)
        return subprocess.CompletedProcess(args, proc.returncode, out.read().decode(errors="replace"),
                                           err.read().decode(errors="replace"))
