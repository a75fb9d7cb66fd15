"""The real multi-process stack on paper scenes: processes, sockets, emulated devices.

Each run launches ``slipstack launch figN`` (rig with device emulators, drivers,
fusion, detector, controller, monitor) and reads the monitor's summary, which is
computed from ``rig/truth`` (the plant's ground truth) and ``slip`` (the verdicts).
"""

from __future__ import annotations

import json

import pytest

pytestmark = pytest.mark.e2e

SCENES = ["fig10", "fig11", "fig12", "fig15"]


def _run(launch, run_root, scene: str, controller: bool) -> dict:
    summary = run_root / f"{scene}-{controller}.json"
    g = launch(scene, f"controller:={str(controller).lower()}", "record:=false", f"summary:={summary}")
    code = g.proc.wait(120)
    assert code == 0, g.log()
    assert summary.exists(), g.log()
    return json.loads(summary.read_text())


@pytest.mark.parametrize("scene", SCENES)
def test_controller_holds_the_object(launch, run_root, scene):
    s = _run(launch, run_root, scene, controller=True)
    assert s["slip_distance_mm"] < 0.5, s
    assert abs(s["slip_angle_deg"]) < 0.5, s
    assert s["grip_command_peak_n"] > 2.0, s  # it had to squeeze harder than the initial grip


@pytest.mark.parametrize("scene", SCENES)
def test_without_controller_every_gross_slip_episode_is_flagged(launch, run_root, scene):
    s = _run(launch, run_root, scene, controller=False)
    assert s["true_episodes"] >= 1, s  # the scene does make the object slip
    assert s["missed_episodes"] == 0 and s["detected_episodes"] == s["true_episodes"], s
