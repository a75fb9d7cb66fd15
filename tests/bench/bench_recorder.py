"""How fast the recorder writes a backlog: the bound on its drain at the end of a launch.

A publisher sends ``--frames`` frames of the default recording's mix (the topics and sizes of
``tests/isolation/golden/tactile14.mcap``, cycled, with fresh headers) into the recorder's SUB
socket while the recorder does not read (as when it waited for a CPU core); then the recorder
(``BusRecorder``, the recorder node's own code) writes them all. Prints frames/s and MB/s over
wall and CPU time, and what that makes of the largest backlog the launch waits for: the
recorder's queue (``RCVHWM`` frames per publisher) for each of the default graph's publishers.

    python tests/bench/bench_recorder.py --frames 100000
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

import zmq

from slipstack.messages.frame import restamp
from slipstack.nodes.recording.bag_io import RecordingWriter, read_recording
from slipstack.nodes.recording.recorder import RCVHWM, BusRecorder

GOLDEN = Path(__file__).resolve().parents[1] / "isolation" / "golden" / "tactile14.mcap"
DEFAULT_PUBLISHERS = 7  # rig, ft_driver, tactile_driver, fusion, cor_estimator, slip_detector, grip_controller


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--frames", type=int, default=100_000, help="frames in the backlog (default 100000)")
    args = p.parse_args()
    mix = [(f.topic, f.payload) for f in read_recording(GOLDEN) if f.topic != "contact"]
    with tempfile.TemporaryDirectory(prefix="sbrec-", dir="/tmp") as tmp:
        endpoint = f"ipc://{tmp}/pub"
        ctx = zmq.Context.instance()
        pub = ctx.socket(zmq.XPUB)
        pub.setsockopt(zmq.SNDHWM, 0)
        pub.bind(endpoint)
        Path(tmp, "graph.json").write_text(json.dumps({"nodes": {"src": {
            "pub": endpoint, "outputs": sorted({t for t, _ in mix} | {"diagnostics"})}}}))
        writer = RecordingWriter(Path(tmp) / "out.mcap", wall_minus_monotonic_ns=0)
        bus = BusRecorder(writer, [], run_dir=Path(tmp))
        bus.refresh()
        pub.recv()  # the recorder's subscription
        now = time.monotonic_ns()
        sent_bytes = 0
        for k in range(args.frames):
            topic, payload = mix[k % len(mix)]
            frame = restamp(payload, now - 1)
            pub.send_multipart([topic.encode(), frame])
            sent_bytes += len(frame)
        time.sleep(1.0)  # ZeroMQ moves them into the recorder's queue
        wall0, cpu0 = time.perf_counter(), time.process_time()
        written = 0
        while written < args.frames:
            written += bus.drain()
        loss = bus.close()
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        size = os.path.getsize(Path(tmp) / "out.mcap")
    rate = written / wall
    print(f"wrote {written} frames ({sent_bytes / 1e6:.1f} MB of frames, {size / 1e6:.1f} MB of file) in "
          f"{wall:.2f} s wall, {cpu:.2f} s CPU: {rate:.0f} frames/s, {sent_bytes / 1e6 / wall:.1f} MB/s; missing "
          f"{sum(v['missing'] for v in loss.values())}")
    full = RCVHWM * DEFAULT_PUBLISHERS
    print(f"the recorder's whole queue ({RCVHWM} frames for each of {DEFAULT_PUBLISHERS} publishers, {full}) "
          f"would take {full / rate:.0f} s at this rate; load {' '.join(open('/proc/loadavg').read().split()[:3])}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
