"""A monitor that stalls mid-run (SIGSTOP, then SIGCONT: as a monitor starved of CPU beside a
real-time control path) loses the frames its sockets could not hold. Its summary counts what it
saw against what the graph published and says what it did not see; the launch then sums the
run up from the recording, which has every frame. It used to print "no frame lost" and pass
with a third of the commands unjudged."""

from __future__ import annotations

import json
import os
import re
import signal
import time

import pytest

from slipstack.nodes.recording.bag_io import read_recording

from .conftest import ended_by_its_check

pytestmark = pytest.mark.e2e

STALL_S = 6.0  # 3000 grip commands at 500 Hz: more than a stopped process's sockets hold (~1000)


def test_a_stalled_monitor_says_what_it_did_not_see_and_the_run_is_judged_whole(launch, run_root):
    recording, summary = run_root / "run.mcap", run_root / "run.json"
    # duration_s: the default scene cut to 12 s (CI time); every other argument is the default
    g = launch("duration_s:=12", f"recording:={recording}", f"summary:={summary}")
    graph = g.wait_ready(timeout=120)
    monitor = graph["nodes"]["monitor"]["pid"]
    time.sleep(2.0)  # into the scene
    os.kill(monitor, signal.SIGSTOP)
    try:
        time.sleep(STALL_S)
    finally:
        os.kill(monitor, signal.SIGCONT)
    ended_by_its_check(g, timeout=180)
    log = g.log()
    commands = sum(1 for _ in read_recording(recording, ["grip/command"]))
    # the monitor's own summary: what it saw and what it says it did not see add up to what was sent
    seen = int(re.search(r"\[monitor\] control: (\d+) commands", log)[1])
    missed = re.search(r"\[monitor\] HEALTH: monitor missed (\d+) of (\d+) ", log)
    assert missed, log[-3000:]
    with open(log.rsplit("(details: ", 1)[1].split(")", 1)[0]) as fh:  # the run's log file: the long form
        detail = re.search(r"\[monitor\] detail: HEALTH: the monitor did not see (\d+) of (\d+) grip commands",
                           fh.read())
    assert detail and int(detail[1]) > 1000, log[-3000:]  # the stall lost frames: the test's premise
    assert seen + int(detail[1]) == int(detail[2]) == commands, (seen, detail[0], commands)
    # the run's summary, from the recording, judges the whole run
    assert "the monitor did not see every frame (it fell behind) during the run: the run's summary from the " \
           "recording" in log, log[-3000:]
    s = json.loads(summary.read_text())
    assert s["grip_commands"] == commands and s["monitor_unseen"] == {}, (s["grip_commands"], s["monitor_unseen"])
