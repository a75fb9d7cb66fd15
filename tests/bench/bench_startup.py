"""Start-up: from ``slipstack launch`` to the stack's first grip command, quiet or beside busy loops.

More in docs/modules.md, `tests/bench/bench_startup.py`.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import datetime
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from _versions import print_versions  # noqa: E402
from _stack import StackRun, _proc_cpu_ticks, free_udp_port, long_scene  # noqa: E402
from progress_deadline import process_tree  # noqa: E402

from slipstack.messages import decode  # noqa: E402
from slipstack.nodes.recording.bag_io import read_recording  # noqa: E402

SCENE_S = 2.0


def _ready_s(log_file: Path, t0_ns: int) -> float:
    """Seconds from ``t0_ns`` (wall) to the launcher's ``nodes ready`` line in its log file."""
    for line in log_file.read_text(errors="replace").splitlines():
        if line[24:].startswith("[launch]") and " nodes ready" in line:
            return datetime.fromisoformat(line[:23]).timestamp() - t0_ns / 1e9
    return float("nan")


def _tree_cpu_s(pid: int) -> float:
    return sum(t for p in process_tree(pid) if (t := _proc_cpu_ticks(p)) is not None) / os.sysconf("SC_CLK_TCK")


def one_run(folder: Path) -> tuple[float, float, float, float]:
    """(s to every node ready, to the first grip command, to the first on valid data, and the CPU
    the launch's processes had used by then) of one launch."""
    scene = long_scene("default", SCENE_S, folder / "scene.toml")
    recording = folder / "r.mcap"
    t0 = time.time_ns()
    with StackRun([f"scene:={scene}", f"recording:={recording}", "record_topics:=[grip/command]",
                   "check:=false", f"rdt_port:={free_udp_port()}"]) as run:
        cpu = []  # (wall ns, CPU s of the launcher and its processes), every 20 ms
        while run.proc.poll() is None:
            cpu.append((time.time_ns(), _tree_cpu_s(run.proc.pid)))
            time.sleep(0.02)
        if run.proc.returncode != 0:
            raise RuntimeError(f"launch failed:\n{run.log()[-3000:]}")
    commands = list(read_recording(recording, ["grip/command"]))
    valid = [f for f in commands if decode(f.payload).reason != "fail-safe"]
    if not valid:
        raise RuntimeError("no grip command on valid data recorded")
    cpu_then = max((c for t, c in cpu if t <= valid[0].log_time_ns), default=float("nan"))
    return (_ready_s(recording.with_suffix(".log"), t0), (commands[0].log_time_ns - t0) / 1e9,
            (valid[0].log_time_ns - t0) / 1e9, cpu_then)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=5, help="launches (default 5)")
    ap.add_argument("--hogs", type=int, default=0, help="`python3 -c 'while True: pass'` processes beside it")
    args = ap.parse_args()
    print_versions()
    hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.hogs)]
    rows = []
    try:
        for k in range(args.runs):
            with tempfile.TemporaryDirectory(prefix="ssb-", dir="/tmp") as d:
                rows.append(one_run(Path(d)))
            print(f"run {k + 1}/{args.runs}: nodes ready {rows[-1][0]:.2f} s, first grip command {rows[-1][1]:.2f} s, "
                  f"on valid data {rows[-1][2]:.2f} s, {rows[-1][3]:.2f} s CPU by then; "
                  f"load average {os.getloadavg()[0]:.1f}", flush=True)
    finally:
        for h in hogs:
            h.kill()
            h.wait()
    cells = [f"{statistics.median(c):.2f} s ({min(c):.2f}-{max(c):.2f})" for c in zip(*rows)]
    print(f"launch -> nodes ready {cells[0]}; -> first grip command {cells[1]}; -> on valid data {cells[2]}, "
          f"CPU by then {cells[3]} (median, min-max of {args.runs}); {args.hogs} busy loops beside it")
    return 0


if __name__ == "__main__":
    sys.exit(main())
