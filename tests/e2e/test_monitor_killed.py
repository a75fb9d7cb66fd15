"""A monitor killed mid-run comes back, and the run's summary is still the whole run's:
the launch writes it from the recording (the monitor alone would sum up only the time
since it came back, and a monitor that stayed dead left no summary and no check)."""

from __future__ import annotations

import json
import os
import signal
import time

import pytest

from slipstack.nodes.recording.bag_io import read_recording

from .conftest import pid_alive

pytestmark = pytest.mark.e2e


def test_a_killed_monitor_respawns_and_the_summary_covers_the_whole_run(launch, run_root):
    recording, summary = run_root / "fig15.mcap", run_root / "fig15.json"
    g = launch("fig15", f"recording:={recording}", f"summary:={summary}")
    graph = g.wait_ready(timeout=120)
    monitor = graph["nodes"]["monitor"]["pid"]
    time.sleep(4.0)  # into the scene
    os.kill(monitor, signal.SIGKILL)
    deadline = time.monotonic() + 60
    while not ((pid := g.graph()["nodes"]["monitor"].get("pid")) and pid != monitor and pid_alive(pid)):
        assert time.monotonic() < deadline, g.log()[-3000:]
        time.sleep(0.05)
    g.proc.wait(180)
    log = g.log()
    assert "the run's summary from the recording" in log, log[-3000:]
    s = json.loads(summary.read_text())
    commands = sum(1 for _ in read_recording(recording, ["grip/command"]))
    assert s["grip_commands"] == commands, (s["grip_commands"], commands)  # the whole run, not since the restart
    assert s["slip_distance_mm"] < 0.5 and abs(s["slip_angle_deg"]) < 0.5, s
    assert "no check.json" not in log  # the check judged the run (pass or fail: the machine may be busy)
    assert "[monitor, from the recording] ==== slipstack run summary ====" in log
