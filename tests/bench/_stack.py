"""Launch the real slipstack graph from a benchmark, attach to it, measure its processes.

Reusable by any bench that needs the full multi-process stack:

More in docs/modules.md, `tests/bench/_stack.py`.
"""

from __future__ import annotations

import json
import math
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from slipstack.lib.toml_file import resolve_path

__all__ = ["long_scene", "free_udp_port", "StackRun", "ProcSampler", "CpuShare", "pid_alive"]

_CLK_TCK = os.sysconf("SC_CLK_TCK")


# -- scenes --------------------------------------------------------------------------------
def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v)
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string is a valid TOML basic string
    if isinstance(v, list):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    raise TypeError(f"cannot write {type(v).__name__} to TOML")


def _toml_dump(data: dict[str, Any], prefix: str = "") -> str:
    """TOML text of ``data`` (scalars, lists of scalars, tables, arrays of tables)."""
    lines, tables, arrays = [], [], []
    for k, v in data.items():
        if isinstance(v, dict):
            tables.append((k, v))
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            arrays.append((k, v))
        else:
            lines.append(f"{k} = {_toml_value(v)}")
    out = "\n".join(lines) + ("\n" if lines else "")
    for k, v in tables:
        out += f"\n[{prefix}{k}]\n" + _toml_dump(v, f"{prefix}{k}.")
    for k, items in arrays:
        for item in items:
            out += f"\n[[{prefix}{k}]]\n" + _toml_dump(item, f"{prefix}{k}.")
    return out


def long_scene(scene: str, duration_s: float, out_path: Path) -> Path:
    """Write ``scene`` (a shipped name or a path) with ``duration_s`` (s) to ``out_path``.

    The disturbance segments are repeated, in order, until they cover ``duration_s``,
    so the slip/stick pattern of the scene keeps coming back instead of the object
    resting once the original profile ends. Returns ``out_path``.
    """
    src = resolve_path(scene, Path.cwd(), "scenes")
    data = tomllib.loads(src.read_text())
    segments = data.get("disturbance", {}).get("segments", [])
    one_pass = sum(float(s.get("duration_s", 0.0)) for s in segments)
    if segments and one_pass > 0:
        data["disturbance"]["segments"] = segments * max(1, math.ceil(duration_s / one_pass))
    data["duration_s"] = float(duration_s)
    data["name"] = f"{data.get('name', src.stem)}-long"
    out_path.write_text(_toml_dump(data))
    return out_path


def free_udp_port() -> int:
    """A UDP port on 127.0.0.1 free right now (for ``rdt_port:=``: the default 49152 is
    shared by every stack on the machine, so two concurrent runs would cross their F/T streams)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


# -- processes -------------------------------------------------------------------------------
def pid_alive(pid: int) -> bool:
    """True if ``pid`` exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[-1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):
        return False


class StackRun:
    """``slipstack launch ARGS`` as a subprocess with its own short run root.

    Use as a context manager: the launch is always stopped on exit. The launcher's
    output goes to ``<run root>/launch.log`` (read with :meth:`log`).
    """

    def __init__(self, args: list[str], *, run_root: Path | None = None) -> None:
        self._tmp = None if run_root else tempfile.TemporaryDirectory(prefix="ssb-", dir="/tmp")
        self.run_root = Path(run_root or self._tmp.name)
        self.env = dict(os.environ, SLIPSTACK_RUN_ROOT=str(self.run_root), PYTHONUNBUFFERED="1")
        self.env.pop("SLIPSTACK_RUN_DIR", None)
        self.log_path = self.run_root / "launch.log"
        self._log = open(self.log_path, "wb")
        self.node_pids: dict[str, int] = {}
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "slipstack.launch.cli", "launch", *args],
            stdout=self._log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL, env=self.env,
            start_new_session=True,  # a Ctrl-C on the bench is handled by us, not by the launcher twice
        )

    def __enter__(self) -> StackRun:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def wait_running(self, timeout_s: float = 90.0) -> dict[str, Any]:
        """Block until ``graph.json`` says ``running``; returns the graph.

        Raises:
            RuntimeError: the launcher exited or the graph is not up in time (log attached).
        """
        path = self.run_root / "current" / "graph.json"
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"launcher exited early ({self.proc.returncode}):\n{self.log()}")
            try:
                graph = json.loads(path.read_text())
            except (FileNotFoundError, json.JSONDecodeError):
                graph = {}
            if graph.get("state") == "running":
                # one entry per process: a container's nodes share a pid
                members: dict[int, list[str]] = {}
                for n, v in graph["nodes"].items():
                    if v.get("pid"):
                        members.setdefault(v["pid"], []).append(n)
                self.node_pids = {
                    (names[0] if len(names) == 1 else f"{graph['nodes'][names[0]]['process']} ({', '.join(names)})"): pid
                    for pid, names in members.items()
                }
                return graph
            time.sleep(0.05)
        raise RuntimeError(f"graph not running after {timeout_s:g} s:\n{self.log()}")

    def running(self) -> bool:
        return self.proc.poll() is None

    def log(self) -> str:
        """What the launcher wrote (it writes the file itself: nothing to flush here)."""
        return self.log_path.read_text(errors="replace")

    def stop(self, timeout_s: float = 15.0) -> list[int]:
        """SIGINT the launcher, wait, escalate; returns node pids still alive (should be [])."""
        if self.proc.poll() is None:
            for sig, wait in ((signal.SIGINT, timeout_s), (signal.SIGTERM, 3.0), (signal.SIGKILL, 3.0)):
                self.proc.send_signal(sig)
                try:
                    self.proc.wait(wait)
                    break
                except subprocess.TimeoutExpired:
                    continue
        deadline = time.monotonic() + 5.0  # children die on the parent-death signal at the latest
        while (left := [p for p in self.node_pids.values() if pid_alive(p)]) and time.monotonic() < deadline:
            time.sleep(0.05)
        if not self._log.closed:
            self._log.close()
        if self._tmp is not None and not left:
            self._tmp.cleanup()
        return left


# -- CPU -------------------------------------------------------------------------------------
def _proc_cpu_ticks(pid: int) -> int | None:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
    except (FileNotFoundError, ProcessLookupError):
        return None
    return int(fields[11]) + int(fields[12])  # utime + stime (fields 14, 15 of stat(5))


def _proc_ctxt(pid: int) -> tuple[int, int]:
    vol = invol = 0
    try:
        with open(f"/proc/{pid}/status") as fh:
            for line in fh:
                if line.startswith("voluntary_ctxt_switches"):
                    vol = int(line.split()[1])
                elif line.startswith("nonvoluntary_ctxt_switches"):
                    invol = int(line.split()[1])
    except (FileNotFoundError, ProcessLookupError):
        pass
    return vol, invol


def _machine_ticks() -> tuple[int, int]:
    """(busy, total) jiffies over all CPUs, from /proc/stat."""
    with open("/proc/stat") as fh:
        v = [int(x) for x in fh.readline().split()[1:]]
    idle = v[3] + (v[4] if len(v) > 4 else 0)  # idle + iowait
    total = sum(v[:8])  # guest time is already in user
    return total - idle, total


def _all_pids() -> list[int]:
    return [int(d) for d in os.listdir("/proc") if d.isdigit()]


def _comm(pid: int) -> str:
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as fh:
            return fh.read().replace(b"\0", b" ").decode(errors="replace").strip()[:60] or "?"
    except OSError:
        return "?"


@dataclass(frozen=True)
class CpuShare:
    """One process's CPU over a window: ``cpu`` in cores (1.0 = one core busy),
    ``nvcsw_per_s`` involuntary context switches per second (preemptions)."""

    name: str
    pid: int
    cpu: float
    nvcsw_per_s: float
    vcsw_per_s: float


class ProcSampler:
    """CPU of named processes, of the machine, and of everything else, over a window.

    ``start()`` then ``stop()``; :attr:`shares`, :attr:`machine_busy` (cores busy,
    all processes), :attr:`others` (top CPU users outside ``pids``; processes that ended
    inside the window are missing there, but not from :attr:`machine_busy`) are filled then.
    """

    def __init__(self, pids: dict[str, int]) -> None:
        self.pids = dict(pids)
        self.shares: list[CpuShare] = []
        self.machine_busy = math.nan
        self.ncpu = os.cpu_count() or 1
        self.loadavg = ""
        self.others: list[tuple[str, float]] = []

    def _snap(self) -> tuple[float, dict[int, int | None], dict[int, tuple[int, int]], tuple[int, int]]:
        every = {p: _proc_cpu_ticks(p) for p in _all_pids()}
        return time.monotonic(), every, {p: _proc_ctxt(p) for p in self.pids.values()}, _machine_ticks()

    def start(self) -> None:
        self._t0, self._cpu0, self._ctx0, self._m0 = self._snap()

    def stop(self) -> None:
        t1, cpu1, ctx1, m1 = self._snap()
        dt = t1 - self._t0
        for name, pid in self.pids.items():
            a, b = self._cpu0.get(pid), cpu1.get(pid)
            cpu = (b - a) / _CLK_TCK / dt if a is not None and b is not None else math.nan
            (v0, n0), (v1, n1) = self._ctx0[pid], ctx1[pid]
            self.shares.append(CpuShare(name, pid, cpu, (n1 - n0) / dt, (v1 - v0) / dt))
        busy0, tot0 = self._m0
        busy1, tot1 = m1
        self.machine_busy = (busy1 - busy0) / max(1, tot1 - tot0) * self.ncpu
        ours = set(self.pids.values())
        other = []
        for pid, b in cpu1.items():
            a = self._cpu0.get(pid, 0)  # a process started during the window: all its CPU is in it
            if pid in ours or a is None or b is None or b <= a:
                continue
            other.append((f"{pid} {_comm(pid)}", (b - a) / _CLK_TCK / dt))
        self.others = sorted(other, key=lambda x: -x[1])
        with open("/proc/loadavg") as fh:
            self.loadavg = " ".join(fh.read().split()[:3])
