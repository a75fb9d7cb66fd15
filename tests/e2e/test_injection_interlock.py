"""Only the graph's own nodes publish grip commands and slip verdicts (issue 29, item 8).

Fig. 15 in real time with its default arguments: ``slipstack topic pub grip/command`` is
refused with what to do, and a slip verdict a local process sends to the controller's
injection endpoint never reaches it; the object holds. A launch file that allows both
(``allow_inject``) takes a manual command from a tool and names the tool, and the
controller holds on an injected "ok" verdict instead of trusting it.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import zmq

from slipstack.lib.toml_file import resolve_path
from slipstack.messages import Header, Slip, decode, encode
from slipstack.nodes.recording.bag_io import read_recording

from .conftest import ended_by_its_check

pytestmark = pytest.mark.e2e

FORGED_OK = "{status: ok, state: stick, method: exact, gamma: 0.0, margin: 1.0, f_n: 0.5}"


def _truth(recording: Path) -> tuple[float, float]:
    """(slid mm, turned deg) over the run, from the recorded ``rig/truth``."""
    truth = [decode(f.payload) for f in read_recording(recording, ["rig/truth"])]
    assert truth, "no rig/truth recorded"
    return (max(t.slip_distance_m for t in truth) * 1e3,
            max(abs(t.slip_angle_rad) for t in truth) * 180 / np.pi)


def test_by_default_tools_cannot_command_the_grip_or_judge_slip(launch, run_root):
    recording, summary = run_root / "run.mcap", run_root / "summary.json"
    g = launch("fig15", f"recording:={recording}", f"summary:={summary}")  # default arguments otherwise
    nodes = g.wait_ready(timeout=120)["nodes"]
    time.sleep(4.0)  # into the disturbance: the grip is well above 2 N
    pub = g.cli("topic", "pub", "grip/command", "{f_n_desired: 2.0, law: manual}", "--rate", "50", "--times", "50")
    assert pub.returncode != 0, pub.stdout + pub.stderr
    assert "refuses grip/command" in pub.stderr and 'allow_inject = ["grip/command"]' in pub.stderr, pub.stderr
    # a local process that writes to the controller's injection endpoint itself (it takes contact, cor)
    ctx = zmq.Context()
    try:
        intruder = ctx.socket(zmq.PUB)
        intruder.connect(next(iter(nodes["grip_controller"]["inject"].values())))
        time.sleep(0.3)
        for k in range(200):
            now = time.monotonic_ns()
            verdict = Slip(status="ok", state="stick", method="exact", gamma=0.0, margin=1.0, f_n=0.5,
                           header=Header(now, k, now, {}))
            intruder.send_multipart([b"slip", encode(verdict), b"intruder"])
            time.sleep(0.005)
    finally:
        ctx.destroy(linger=0)
    ended_by_its_check(g)
    slid_mm, turned_deg = _truth(recording)
    assert slid_mm < 0.1 and turned_deg < 0.1, (slid_mm, turned_deg)
    assert json.loads(summary.read_text())["injected"] == {"grip_commands": 0, "slip_verdicts": 0,
                                                          "finger_reports": 0}


def test_a_launch_that_allows_injection_names_the_sender_and_never_trusts_a_verdict(launch, run_root):
    launch_file = run_root / "manual.toml"
    launch_file.write_text('[launch]\nextends = "fig15.toml"\nallow_inject = ["grip/command", "slip"]\n')
    recording, summary = run_root / "run.mcap", run_root / "summary.json"
    scene = run_root / "fig15_30s.toml"  # room for the tools to join on a busy machine
    scene.write_text(resolve_path("fig15", Path.cwd(), "scenes").read_text().replace("duration_s = 12.0",
                                                                                    "duration_s = 30.0", 1))
    g = launch(str(launch_file), f"scene:={scene}", f"recording:={recording}", f"summary:={summary}")
    g.wait_ready(timeout=120)
    time.sleep(4.0)
    tools = [subprocess.Popen([sys.executable, "-m", "slipstack.launch.cli", "topic", "pub", *args, "--wait", "20"],
                              env=g.env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for args in (["slip", FORGED_OK, "--rate", "100", "--times", "100"],
                          ["grip/command", "{f_n_desired: 19.0, law: manual}", "--once"])]
    for tool in tools:
        out, err = tool.communicate(timeout=60)
        assert tool.returncode == 0 and "joined" not in err, err
    ended_by_its_check(g)
    log = g.log()
    sender = re.search(r"manual grip/command from (topic_pub-\d+): 19\.00 N", log)
    assert sender, log[-3000:]
    reports = [decode(f.payload) for f in read_recording(recording, ["grip/state"])]
    assert any(r.commanded_by == sender.group(1) for r in reports)  # the finger says who commanded it
    s = json.loads(summary.read_text())
    # each wake-up hands the controller the newest injected verdict only (a latest-value input)
    assert s["injected"]["grip_commands"] == 1 and s["injected"]["slip_verdicts"] >= 1, s["injected"]
    assert "injected by tools: 1 grip commands" in log  # on the HEALTH line
    slid_mm, turned_deg = _truth(recording)
    assert slid_mm < 0.1 and turned_deg < 0.1, (slid_mm, turned_deg)
