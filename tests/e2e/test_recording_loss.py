"""A recorder far behind at the end of a run is not killed while it writes, and its file and the
run's summary count every frame it misses, exactly (docs/safety.md, "Recordings").

fig15 runs in real time with its recorder (the default) frozen from the start until the launch
waits for it at the end: its queue overflows, so frames are lost. The truth is what the F/T
driver itself says it published, read by this test from the bus on a socket of its own."""

from __future__ import annotations

import json
import os
import signal
import time

import pytest
import zmq

from slipstack.messages import Diagnostics, decode
from slipstack.nodes.recording.bag_io import read_recording, recording_info

from .conftest import pid_alive

pytestmark = pytest.mark.e2e


def test_a_frozen_recorder_writes_what_it_holds_and_counts_what_it_missed(launch, run_root):
    recording, summary = run_root / "late.mcap", run_root / "late.json"
    # check:=false: a recorder frozen for the whole scene goes silent, which the check fails by design;
    # tests/e2e/test_stack.py runs fig15's default check
    g = launch("fig15", f"recording:={recording}", f"summary:={summary}", "check:=false")
    graph = g.wait_ready(timeout=120)
    recorder = graph["nodes"]["recorder"]["pid"]
    os.kill(recorder, signal.SIGSTOP)
    tap = zmq.Context.instance().socket(zmq.SUB)
    tap.connect(graph["nodes"]["ft_driver"]["pub"])
    tap.setsockopt(zmq.SUBSCRIBE, b"diagnostics")
    published = 0
    try:
        deadline = time.monotonic() + 180
        while "waiting for recorder" not in g.log():
            assert time.monotonic() < deadline and g.proc.poll() is None, g.log()[-3000:]
            if tap.poll(100):
                msg = decode(tap.recv_multipart()[1], Diagnostics)
                published = max(published, msg.counters.get("out.ft/wrench.published", 0))
        while tap.poll(500):  # the driver's last diagnostics, sent as it stopped
            msg = decode(tap.recv_multipart()[1], Diagnostics)
            published = max(published, msg.counters.get("out.ft/wrench.published", 0))
    finally:
        if pid_alive(recorder):
            os.kill(recorder, signal.SIGCONT)
        tap.close(linger=0)
    assert g.proc.wait(120) == 0, g.log()[-3000:]
    info = recording_info(recording)
    assert info.finished, g.log()[-3000:]  # not killed
    in_file = sum(1 for _ in read_recording(recording, ["ft/wrench"]))
    wrench = info.topics["ft/wrench"]
    assert published > 2000 and wrench.loss["exact"], (published, wrench, g.log()[-4000:])
    assert in_file + wrench.missing == published, (in_file, wrench, published)
    assert wrench.missing > 0  # the frozen recorder's queue overflowed: the count is not vacuous
    assert json.loads(summary.read_text())["recording_loss"]["ft/wrench"]["missing"] == wrench.missing
    assert f"ft/wrench {wrench.missing} of {published}" in g.log()
