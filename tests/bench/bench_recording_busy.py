"""Every F/T sample in the recording, or counted missing: a long default run beside busy loops.

More in docs/modules.md, `tests/bench/bench_recording_busy.py`.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import zmq

sys.path.insert(0, str(Path(__file__).resolve().parent))

from _stack import StackRun, free_udp_port, long_scene  # noqa: E402

from slipstack.messages import Diagnostics, decode  # noqa: E402
from slipstack.nodes.recording.bag_io import read_recording, recording_info  # noqa: E402

TOPIC = "ft/wrench"


def _load() -> str:
    return " ".join(Path("/proc/loadavg").read_text().split()[:3])


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__.split("\n\n", 1)[1])
    p.add_argument("--minutes", type=float, default=10.0, help="length of the run (default 10)")
    p.add_argument("--hogs", type=int, default=2, help="busy loops beside it (default 2)")
    args = p.parse_args()
    with tempfile.TemporaryDirectory(prefix="sbbusy-", dir="/tmp") as tmp:
        tmp = Path(tmp)
        scene = long_scene("default", args.minutes * 60, tmp / "long.toml")
        recording, summary = tmp / "run.mcap", tmp / "summary.json"
        hogs = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(args.hogs)]
        load_before = _load()
        published = 0
        t_start = time.monotonic()
        try:
            with StackRun([f"scene:={scene}", f"recording:={recording}", f"summary:={summary}",
                           f"rdt_port:={free_udp_port()}"]) as run:
                graph = run.wait_running(timeout_s=300)
                tap = zmq.Context.instance().socket(zmq.SUB)
                tap.setsockopt(zmq.RCVHWM, 100_000)
                tap.setsockopt(zmq.SUBSCRIBE, b"diagnostics")
                tap.connect(graph["nodes"]["ft_driver"]["pub"])
                while run.running():
                    if tap.poll(200):
                        msg = decode(tap.recv_multipart()[1], Diagnostics)
                        if msg.node == "ft_driver":
                            published = max(published, int(msg.counters.get(f"out.{TOPIC}.published", 0)))
                tap.close(linger=0)
                log = run.log()
        finally:
            for hog in hogs:
                hog.kill()
                hog.wait()
        wall = time.monotonic() - t_start
        load_after = _load()
        in_file = sum(1 for _ in read_recording(recording, [TOPIC]))
        info = recording_info(recording)
        file_missing = info.topics[TOPIC].missing
        summary_loss = json.loads(summary.read_text()).get("recording_loss", {}).get(TOPIC, {})
    behind = len(re.findall(r"\[recorder\] warning: falling behind", log))
    waited = "yes" if "waiting for recorder" in log else "no"
    print(f"## {TOPIC} over a {args.minutes:g}-minute default run beside {args.hogs} busy loops\n")
    print("| published by the driver | in the recording | missing (file) | missing (summary) | exact? "
          "| file + missing = published | recorder fell behind | launch waited for it | wall s |")
    print("|---|---|---|---|---|---|---|---|---|")
    exact = info.topics[TOPIC].loss.get("exact")
    print(f"| {published} | {in_file} | {file_missing} | {summary_loss.get('missing')} | {exact} "
          f"| {in_file + (file_missing or 0) == published} | {behind}x | {waited} | {wall:.0f} |")
    print(f"\nfile finished: {info.finished}; load average before {load_before}, after {load_after}")
    print("\n".join(line for line in log.splitlines() if "[recorder]" in line or "[launch] recording" in line
                    or "HEALTH" in line))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
