"""Kill processes of the running stack mid-disturbance and measure the recovery.

Runs a paper scene (default fig15, extended to ``--duration``) in real time with every
process real and, every ``--every`` seconds, SIGKILLs one of: the tactile driver, the
F/T driver, the control container (fusion, COR estimator, slip detector and grip
controller). For each kill it reports, from the run's recording (CLOCK_MONOTONIC
stamps, the same clock as this script):

- *respawn*: kill → the new process is alive (the launcher's restart);
- *recovery*: the new process is alive → the first grip command on valid data
  (reason other than ``fail-safe``) — the target is ≤ 500 ms;
- the grip before the kill and the lowest grip commanded until the recovery (the
  contract: never lower, docs/safety.md), and the slip added over that window.

``--hogs N`` runs N busy-loop processes beside the stack (a loaded machine)::

    .venv/bin/python tests/bench/bench_chaos.py --hogs 2
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import signal
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _versions import print_versions  # noqa: E402
from _stack import StackRun, free_udp_port, long_scene, pid_alive  # noqa: E402

from slipstack.messages import decode  # noqa: E402
from slipstack.nodes.recording.bag_io import read_recording  # noqa: E402

TARGETS = {"tactile_driver": "tactile_driver", "ft_driver": "ft_driver", "control": "grip_controller"}


def _hog() -> None:
    while True:
        pass


def _pid(graph_path: Path, node: str) -> int | None:
    try:
        return json.loads(graph_path.read_text())["nodes"][node].get("pid")
    except (FileNotFoundError, ValueError, KeyError):
        return None


def _wait_new_pid(graph_path: Path, node: str, old: int, timeout_s: float = 30.0) -> int | None:
    """Monotonic ns at which ``node`` runs in a new live process (None: not in time)."""
    end = time.monotonic() + timeout_s
    while time.monotonic() < end:
        pid = _pid(graph_path, node)
        if pid and pid != old and pid_alive(pid):
            return time.monotonic_ns()
        time.sleep(0.005)
    return None


def _analyse(recording: Path, kills: list[dict]) -> list[dict]:
    cmds, truth = [], []
    for frame in read_recording(recording, ["grip/command", "rig/truth"]):
        msg = decode(frame.payload)
        (cmds if frame.topic == "grip/command" else truth).append(msg)
    for k in kills:
        before = [c for c in cmds if c.header.pub_ns < k["kill_ns"]]
        after = [c for c in cmds if c.header.pub_ns >= k["kill_ns"]]
        back = k.get("return_ns")
        valid = next((c for c in after if back and c.header.pub_ns >= back and c.reason != "fail-safe"), None)
        k["recovery_ms"] = (valid.header.pub_ns - back) / 1e6 if valid else float("nan")
        window_end = valid.header.pub_ns if valid else k["kill_ns"] + 2_000_000_000
        window = [c.f_n_desired for c in after if c.header.pub_ns <= window_end]
        k["grip_before_n"] = before[-1].f_n_desired if before else float("nan")
        k["lowest_until_recovery_n"] = min(window) if window else float("nan")
        slid = [t.slip_distance_m for t in truth if k["kill_ns"] <= t.header.stamp_ns <= window_end + 500_000_000]
        k["slip_added_mm"] = (slid[-1] - slid[0]) * 1e3 if len(slid) > 1 else 0.0
    return kills


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", default="fig15", help="paper scene to run (default fig15)")
    ap.add_argument("--duration", type=float, default=24.0, help="scene length, s (its disturbance repeats)")
    ap.add_argument("--every", type=float, default=3.0, help="seconds between kills")
    ap.add_argument("--hogs", type=int, default=0, help="busy-loop processes beside the stack")
    args = ap.parse_args()
    print_versions()

    hogs = [multiprocessing.Process(target=_hog, daemon=True) for _ in range(args.hogs)]
    for h in hogs:
        h.start()
    try:
        with tempfile.TemporaryDirectory(prefix="ssc-", dir="/tmp") as tmp:
            tmp = Path(tmp)
            scene = long_scene(args.scene, args.duration, tmp / "scene.toml")
            rec = tmp / "chaos.mcap"
            (tmp / "root").mkdir(mode=0o700)
            with StackRun([args.scene, f"scene:={scene}", f"recording:={rec}", f"rdt_port:={free_udp_port()}"],
                          run_root=tmp / "root") as run:
                run.wait_running()
                graph_path = run.run_root / "current" / "graph.json"
                kills = []
                order = list(TARGETS.items())
                n_kills = int((args.duration - 4.0) // args.every)
                for i in range(n_kills):
                    time.sleep(args.every)
                    label, node = order[i % len(order)]
                    old = _pid(graph_path, node)
                    if not old or not pid_alive(old):
                        continue
                    kill_ns = time.monotonic_ns()
                    os.kill(old, signal.SIGKILL)
                    back = _wait_new_pid(graph_path, node, old)
                    kills.append({"process": label, "kill_ns": kill_ns, "return_ns": back,
                                  "respawn_ms": (back - kill_ns) / 1e6 if back else float("nan")})
                    print(f"killed {label} at +{(i + 1) * args.every:.0f} s; back after "
                          f"{kills[-1]['respawn_ms']:.0f} ms", flush=True)
                while run.running():
                    time.sleep(0.2)
                log = run.log()
            results = _analyse(rec, kills)
    finally:
        for h in hogs:
            h.terminate()
    load = os.getloadavg()
    print(f"\nscene {args.scene} ({args.duration:g} s), {args.hogs} CPU hogs, load average {load[0]:.1f}")
    print(f"{'process':<16}{'respawn ms':>12}{'recovery ms':>13}{'grip before N':>15}{'lowest N':>10}{'slip mm':>9}")
    for k in results:
        print(f"{k['process']:<16}{k['respawn_ms']:>12.0f}{k['recovery_ms']:>13.0f}{k['grip_before_n']:>15.2f}"
              f"{k['lowest_until_recovery_n']:>10.2f}{k['slip_added_mm']:>9.3f}")
    for label in TARGETS:
        rec_ms = [k["recovery_ms"] for k in results if k["process"] == label]
        resp_ms = [k["respawn_ms"] for k in results if k["process"] == label]
        if rec_ms:
            print(f"{label}: median respawn {statistics.median(resp_ms):.0f} ms, "
                  f"median recovery {statistics.median(rec_ms):.0f} ms over {len(rec_ms)} kills")
    summary = [line for line in log.splitlines() if "[monitor]" in line and "STATUS" not in line]
    print("\n".join(summary[-8:]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
