"""The shipped gripper's pivot and slide (``slipstack launch gripper scene:=grasp_pivot goal:=pivot``,
``scene:=grasp_slide goal:=slide``), every other argument its default, in lock-step: the check
judges the object's motion against the commanded goal, measured here from the recorded truth."""

from __future__ import annotations

import json
import math

import pytest

from slipstack.messages import decode
from slipstack.nodes.recording.bag_io import read_recording

pytestmark = pytest.mark.e2e


def _run(launch, run_root, *args: str) -> tuple[int, str, dict]:
    """The launch's exit code, its output and its JSON summary; ``run_root/run.mcap`` its recording."""
    summary = run_root / "summary.json"
    g = launch("gripper", *args, f"summary:={summary}", f"recording:={run_root / 'run.mcap'}", "--lockstep")
    code = g.wait_exit(120)  # lock-step: about 7 s of CPU for the 8.5 s scene
    return code, g.log(), json.loads(summary.read_text())


def _truth_motion(recording, mode: str) -> float:
    """The object's turn (deg) or displacement (mm) from the goal to the end, from the recorded truth."""
    frames = list(read_recording(recording))
    (goal,) = [decode(f.payload) for f in frames if f.topic == "grasp/goal"]
    truth = [decode(f.payload) for f in frames if f.topic == "rig/truth"]
    at = [m for m in truth if m.header.stamp_ns <= goal.header.stamp_ns][-1]
    end = truth[-1]
    if mode == "pivot":
        return abs(math.degrees(end.theta - at.theta))
    return 1e3 * math.hypot(end.x - at.x, end.y - at.y)


@pytest.mark.parametrize("scene, mode, target", [("grasp_pivot", "pivot", 30.0), ("grasp_slide", "slide", 20.0)])
def test_a_commanded_pivot_or_slide_passes_the_check_of_the_shipped_gripper(scene, mode, target, launch, run_root):
    code, log, s = _run(launch, run_root, f"scene:={scene}", f"goal:={mode}")
    assert code == 0 and "[launch] check passed" in log, log[-3000:]
    (leg,) = [leg for leg in s["goals"] if leg["mode"] == mode]
    truth = _truth_motion(run_root / "run.mcap", mode)
    assert abs(truth - target) <= 2.0, truth  # the bench's limits: 2 deg, 2 mm (tests/bench/bench_gripper.py)
    assert leg["moved"] == pytest.approx(truth, abs=0.05), (leg, truth)  # one truth sample's motion apart at most
    assert f"[monitor] goal: {mode} {target:g} " in log and ": as commanded" in log, log[-3000:]


def test_a_pivot_past_where_the_bar_can_turn_fails_the_check(launch, run_root):
    """150 deg: the bar starts 30 deg above horizontal and its weight turns it at most to hanging
    (120 deg), so the grasp cannot reach the angle: the check fails on the goal, not on the hold."""
    code, log, s = _run(launch, run_root, "scene:=grasp_pivot", "goal:=pivot", "angle_deg:=150")
    truth = _truth_motion(run_root / "run.mcap", "pivot")
    assert truth < 148.0, truth
    failed = next(line for line in log.splitlines() if "CHECK FAILED" in line)
    assert code == 1 and failed.startswith("[launch] CHECK FAILED: pivot 150 deg at 1.5 s: turned "), log[-3000:]
    assert s["goals"][0]["moved"] == pytest.approx(truth, abs=0.05)
