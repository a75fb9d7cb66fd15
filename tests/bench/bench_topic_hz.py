"""``topic hz`` (and ``topic echo``) on the 1 kHz demo topic: reported rate and CPU cost.

Launches the demo graph (source → relay → sink) with the real launcher in a private
run root, then runs ``slipstack topic hz ft/wrench`` for ``--duration`` seconds and
reads the tool's CPU time (utime + stime from ``/proc/<pid>/stat``) over the steady
part of the run (after the first ``--settle`` seconds of imports and connecting).
The same is measured for ``topic echo ft/wrench > /dev/null`` (the YAML printer).

More in docs/modules.md, `tests/bench/bench_topic_hz.py`.
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from _versions import print_versions

import numpy as np

CLK_TCK = os.sysconf("SC_CLK_TCK")


def cpu_s(pid: int) -> float:
    """User + system CPU seconds of ``pid`` so far."""
    with open(f"/proc/{pid}/stat") as fh:
        fields = fh.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK  # utime, stime (fields 14, 15)


def measure(cmd: list[str], env: dict[str, str], duration: float, settle: float, stdout: int | None) -> tuple[float, str]:
    """Run ``cmd`` for ``duration`` s; returns (steady CPU fraction of one core, its stdout)."""
    with tempfile.TemporaryFile("w+") as out:
        proc = subprocess.Popen(cmd, env=env, stdout=stdout if stdout is not None else out, text=True)
        time.sleep(settle)
        c0, t0 = cpu_s(proc.pid), time.monotonic()
        time.sleep(duration - settle)
        c1, t1 = cpu_s(proc.pid), time.monotonic()
        proc.send_signal(signal.SIGINT)
        proc.wait(10)
        out.seek(0)
        return (c1 - c0) / (t1 - t0), out.read()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--duration", type=float, default=12.0, help="seconds each tool runs (default 12)")
    ap.add_argument("--settle", type=float, default=2.0, help="seconds left out of the CPU figure (default 2)")
    ap.add_argument("--window", type=int, default=1000, help="hz window in messages (default 1000)")
    args = ap.parse_args()
    print_versions()
    with tempfile.TemporaryDirectory(prefix="bh-", dir="/tmp") as root:
        env = dict(os.environ, SLIPSTACK_RUN_ROOT=root, PYTHONUNBUFFERED="1")
        cli = [sys.executable, "-m", "slipstack.launch.cli"]
        launcher = subprocess.Popen([*cli, "launch", "demo"], env=env, stdout=subprocess.DEVNULL,
                                    stderr=subprocess.DEVNULL)
        try:
            graph = Path(root) / "current" / "graph.json"
            deadline = time.monotonic() + 60
            while not graph.exists():
                if time.monotonic() > deadline or launcher.poll() is not None:
                    sys.exit("the demo graph did not start")
                time.sleep(0.1)
            time.sleep(1.0)
            rows = []
            for label, extra in (("hz (receive times)", []), ("hz --use-stamps", ["--use-stamps"])):
                cpu, out = measure([*cli, "topic", "hz", "ft/wrench", "--window", str(args.window), *extra],
                                   env, args.duration, args.settle, None)
                rates = np.array([float(r) for r in re.findall(r"average rate: ([0-9.]+)", out)][1:])
                rows.append((label, f"{np.median(rates):.2f}", f"{rates.min():.2f} – {rates.max():.2f}", cpu))
            cpu, _ = measure([*cli, "topic", "echo", "ft/wrench"], env, args.duration, args.settle,
                             subprocess.DEVNULL)
            rows.append(("echo > /dev/null", "", "", cpu))
        finally:
            launcher.send_signal(signal.SIGINT)
            launcher.wait(15)
    print("| tool | median rate Hz | rate range Hz | CPU (one core) |\n| --- | ---: | ---: | ---: |")
    for label, med, rng, cpu in rows:
        print(f"| {label} | {med} | {rng} | {100 * cpu:.1f} % |")
    print(f"\nwindow {args.window}, {args.duration:g} s per tool, CPU over the last {args.duration - args.settle:g} s; "
          f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")


if __name__ == "__main__":
    main()
