"""A recording whose file cannot grow (a full disk): the writer never raises, and what is in the
file plus what it counts as not written is every frame it was given, per topic, exactly.

The file is stopped from growing by the kernel itself: a child process with ``RLIMIT_FSIZE``
(writes past it fail with EFBIG, the way a full disk fails them with ENOSPC)."""

from __future__ import annotations

import json
import subprocess
import sys

from slipstack.nodes.recording.bag_io import read_recording, recording_info

LIMIT_BYTES = 96 * 1024
CHILD = r"""
import json, resource, signal, sys
import numpy as np
from slipstack.messages import Header, TactileFrame, Wrench, encode
from slipstack.nodes.recording.bag_io import RecordingWriter
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG instead of a kill
resource.setrlimit(resource.RLIMIT_FSIZE, (int(sys.argv[2]), int(sys.argv[2])))
rng = np.random.default_rng(3)
w = RecordingWriter(sys.argv[1], chunk_size=16 * 1024, wall_minus_monotonic_ns=0)
given = {"ft/wrench": 0, "tactile/frame": 0}
for k in range(3000):
    stamp = 1_000_000 * (k + 1)
    w.write("ft/wrench", encode(Wrench(force=rng.normal(size=3), header=Header(stamp, k, stamp, {}))), stamp)
    given["ft/wrench"] += 1
    if k % 4 == 0:
        frame = TactileFrame(rows=8, cols=8, pitch_m=1e-3, pressure_pa=(rng.random(64) * 1e4).astype("<f4"),
                             saturated=np.zeros(64, bool), dead=np.zeros(64, bool),
                             header=Header(stamp, k // 4, stamp, {}))
        w.write("tactile/frame", encode(frame), stamp)
        given["tactile/frame"] += 1
w.close()
print(json.dumps({"given": given, "counts": dict(w.counts), "not_written": dict(w.not_written),
                  "error": w.error.strerror if w.error else None}))
"""


def test_a_file_that_cannot_grow_keeps_whole_chunks_and_counts_the_rest(tmp_path):
    path = tmp_path / "full.mcap"
    out = subprocess.run([sys.executable, "-c", CHILD, str(path), str(LIMIT_BYTES)], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr  # the writer never raised
    report = json.loads(out.stdout)
    assert report["error"] == "File too large", report
    in_file: dict[str, int] = {}
    for frame in read_recording(path):
        in_file[frame.topic] = in_file.get(frame.topic, 0) + 1
    for topic, given in report["given"].items():
        assert in_file.get(topic, 0) == report["counts"].get(topic, 0), (topic, in_file, report)
        assert report["counts"].get(topic, 0) + report["not_written"][topic] == given, (topic, report)
        assert report["not_written"][topic] > 0, report  # the file really was cut
    assert in_file["ft/wrench"] > 100  # and kept what fitted
    assert not recording_info(path).finished
