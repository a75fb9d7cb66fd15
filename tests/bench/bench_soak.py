"""Soak: the whole stack for a long time at the paper rates, with monitor and recorder.

Launches the default scene, its disturbance repeated for ``--minutes``, at F/T 1 kHz
and tactile 500 Hz, with the monitor and the recorder (writing to a temporary file),
and samples every process's resident memory (``VmRSS``) every ``--interval`` seconds.
Reports per process the RSS at start and end and the least-squares slope in MB/h over
the second half of the run (the first half includes warm-up: caches, numba, buffers
filling to their bound). A process whose memory is bounded shows a slope near zero::

    .venv/bin/python tests/bench/bench_soak.py --minutes 30
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _versions import print_versions  # noqa: E402
from _stack import StackRun, free_udp_port, long_scene, pid_alive  # noqa: E402


def rss_mb(pid: int) -> float:
    """Resident memory of ``pid`` in MB (NaN once it is gone)."""
    try:
        with open(f"/proc/{pid}/status") as fh:
            for line in fh:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return float("nan")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--minutes", type=float, default=30.0, help="length of the soak (min)")
    ap.add_argument("--interval", type=float, default=10.0, help="seconds between memory samples")
    ap.add_argument("--scene", default="default", help="scene whose disturbance repeats")
    args = ap.parse_args()
    print_versions()
    duration_s = args.minutes * 60.0
    with tempfile.TemporaryDirectory(prefix="sss-", dir="/tmp") as tmp:
        tmp = Path(tmp)
        (tmp / "root").mkdir(mode=0o700)
        scene = long_scene(args.scene, duration_s, tmp / "scene.toml")
        launch = ["default", f"scene:={scene}", "ft_rate_hz:=1000", "tactile_rate_hz:=500",
                  f"recording:={tmp / 'soak.mcap'}", f"rdt_port:={free_udp_port()}"]
        with StackRun(launch, run_root=tmp / "root") as run:
            run.wait_running()
            pids = run.node_pids
            t0 = time.monotonic()
            times: list[float] = []
            samples: dict[str, list[float]] = {name: [] for name in pids}
            while run.running() and time.monotonic() - t0 < duration_s:
                times.append(time.monotonic() - t0)
                for name, pid in pids.items():
                    samples[name].append(rss_mb(pid))
                minutes = times[-1] / 60.0
                print(f"\r{minutes:5.1f} / {args.minutes:g} min  "
                      + "  ".join(f"{n.split(' ')[0]} {v[-1]:.0f} MB" for n, v in samples.items()),
                      end="", flush=True)
                time.sleep(args.interval)
            print()
            recording_mb = (tmp / "soak.mcap").stat().st_size / 1e6 if (tmp / "soak.mcap").exists() else 0.0
            lost = [n for n, pid in pids.items() if not pid_alive(pid)]
    t = np.array(times) / 3600.0
    half = len(t) // 2
    print(f"\nsoak {args.minutes:g} min at F/T 1 kHz, tactile 500 Hz; load average {os.getloadavg()[0]:.1f}; "
          f"recording {recording_mb:.0f} MB; processes gone before the end: {lost or 'none'}")
    print(f"{'process':<48}{'start MB':>10}{'end MB':>10}{'slope MB/h (2nd half)':>24}")
    for name, values in samples.items():
        v = np.array(values)
        ok = np.isfinite(v[half:])
        slope = np.polyfit(t[half:][ok], v[half:][ok], 1)[0] if ok.sum() >= 3 else float("nan")
        print(f"{name:<48}{v[0]:>10.1f}{v[np.isfinite(v)][-1]:>10.1f}{slope:>24.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
