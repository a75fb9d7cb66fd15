"""The slip detector node on hand-made frames through fusion and the in-process executor:
what it says on ``diagnostics`` when its deciding test cannot compute (docs/safety.md)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sensor_frames import MS, PITCH_M, tactile, wrench

import slipstack.launch
from slipstack.nodes.fusion import Fusion
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from slipstack.nodes.slip_detector import SlipDetector, SlipDetectorParams


def test_a_verdict_the_solver_could_not_compute_is_counted_by_its_status_and_not_ok():
    # The paper's fixed-gain COR iteration on two equal taxels two columns apart, pulled along
    # the line through them, fails (singular from a cold start, diverged when warm-started from
    # the contact before). The well-posed contact before it is not counted.
    detector = SlipDetector(SlipDetectorParams(method="tactile_cor", mu=0.5, also=[]))
    ex = InProcessExecutor([Fusion(), detector], diagnostics_period_s=0.001)
    pair = np.zeros(256, np.float32)
    pair[5 * 16 + 5] = pair[5 * 16 + 7] = 100.0 / PITCH_M**2  # 100 N each
    ex.feed([tactile(0, 4.0), wrench(1, 4.0, 0.2), wrench(2, 4.0, 0.2),
             tactile(10, 0.0, pressure_pa=pair), wrench(11, 200.0, 5.0), wrench(12, 200.0, 50.0)])
    ex.run(until_ns=15 * MS)
    well_posed, failed = ex.published["slip"][:2], ex.published["slip"][2:]
    assert [s.status for s in well_posed] == ["ok", "ok"]
    assert len(failed) == 2 and failed[0].status in ("singular", "diverged", "max_iter")
    assert failed[1].status == failed[0].status  # never "ok": the controller holds
    counters = [d for d in ex.published["diagnostics"] if d.node == "slip_detector"][-1].counters
    assert {k: v for k, v in counters.items() if k.startswith("slip.")} == {f"slip.{failed[0].status}": 2}


def test_a_tactile_test_on_a_stack_without_tactile_says_which_test_to_use():
    """``slipstack launch tactile:=false`` keeps the default ``method = exact``: every verdict
    is ``tactile_off`` and the grip holds (safe), and the detector says once, on
    ``diagnostics`` and in the log, that the test needs the pad and which F/T test to pick."""
    from slipstack.nodes.fusion import FusionParams

    detector = SlipDetector(SlipDetectorParams(method="exact", mu=0.5))
    ex = InProcessExecutor([Fusion(FusionParams(use_tactile=False)), detector], diagnostics_period_s=0.001)
    ex.feed([wrench(k, 4.0, 0.2) for k in range(1, 6)])
    ex.run(until_ns=10 * MS)
    assert {s.status for s in ex.published["slip"]} == {"tactile_off"}
    last = [d for d in ex.published["diagnostics"] if d.node == "slip_detector"][-1]
    assert "needs the tactile pad" in last.last_error and "method:=coulomb" in last.last_error, last.last_error
    said = [line for line in ex.logs if "needs the tactile pad" in line]
    assert len(said) == 1, said  # once, not per contact


def test_an_ft_test_with_beta_on_a_stack_without_tactile_and_without_beta_says_to_set_it():
    """``slipstack launch tactile:=false method:=linear_ls`` leaves beta_m at 0 (β from the
    pressure frames, and there are none): no verdict is valid, resting or loaded, and the
    detector says once to set beta_m (a verdict said ``ok`` at rest and ``invalid_input``
    under load, with nothing on ``diagnostics``)."""
    from slipstack.nodes.fusion import FusionParams

    detector = SlipDetector(SlipDetectorParams(method="linear_ls", material="rubber"))
    ex = InProcessExecutor([Fusion(FusionParams(use_tactile=False)), detector], diagnostics_period_s=0.001)
    ex.feed([wrench(1, 4.0, 0.0), wrench(2, 4.0, 0.0)] + [wrench(k, 4.0, 0.2) for k in range(3, 6)])
    ex.run(until_ns=10 * MS)
    assert {s.status for s in ex.published["slip"]} == {"tactile_off"}
    last = [d for d in ex.published["diagnostics"] if d.node == "slip_detector"][-1]
    assert "beta_m:=" in last.last_error and "0.00131 m" in last.last_error, last.last_error
    assert len([line for line in ex.logs if "beta_m:=" in line]) == 1, ex.logs


def _run_with(params: SlipDetectorParams, loads: list[float]) -> InProcessExecutor:
    """A flat pad pressed with 4 N (a pressure frame every 5 ms) and pulled with ``loads`` (N),
    one per ms, through fusion, the detector (``params``) and the monitor; the executor, running."""
    from slipstack.nodes.monitor import Monitor

    ex = InProcessExecutor([Fusion(), SlipDetector(params), Monitor()], diagnostics_period_s=0.001)
    ex.feed([tactile(k, 4.0) for k in range(0, len(loads), 5)] + [wrench(k + 1, 4.0, f) for k, f in enumerate(loads)])
    ex.run(until_ns=(len(loads) + 5) * MS)
    return ex


def test_without_a_material_file_it_says_so_at_start_on_diagnostics_live_and_in_the_summary():
    """The default (material = ""): the shipped rubber, and every place a user looks says
    the detector is uncalibrated and what it costs; with a file, none of that."""
    ex = _run_with(SlipDetectorParams(), [0.2] * 10)
    start = [line for line in ex.logs if "uncalibrated: no material file, the shipped rubber" in line]
    assert len(start) == 1 and "slipstack identify" in start[0] and "flagged early, or late" in start[0], ex.logs
    last = [d for d in ex.published["diagnostics"] if d.node == "slip_detector"][-1]
    assert last.status.startswith("uncalibrated: no material file"), last.status
    ex.stop()
    summary = [line for line in ex.logs if line.startswith("[monitor] detector: uncalibrated: no material file")]
    assert summary and len(summary[0]) <= 100, ex.logs

    ex = _run_with(SlipDetectorParams(material="rubber"), [0.2] * 10)
    ex.stop()
    assert not [line for line in ex.logs if "uncalibrated" in line]
    assert [d for d in ex.published["diagnostics"] if d.node == "slip_detector"][-1].status == "ok"


def test_online_calibration_says_what_it_learned():
    """No file, calibrate online, a pull beyond the default's μ (γ 1.1 of its capacity):
    μ rises to what the contact carried; a log line and the status say so."""
    ex = _run_with(SlipDetectorParams(calibrate="online"), [0.2 * k for k in range(10)] + [4.0 * 0.4527 * 1.1] * 40)
    learned = [line for line in ex.logs if "calibrated online from 0 confirmed slip(s) and the loads carried" in line]
    assert learned, ex.logs
    last = [d for d in ex.published["diagnostics"] if d.node == "slip_detector"][-1]
    assert last.status.startswith("calibrated-online:") and "mu 0.49" in last.status, last.status


def test_online_calibration_from_an_identified_file_learns_a_slip_and_loses_no_verdict(tmp_path):
    """A file as ``identify`` writes it (each onset with its load path and pressure spread),
    calibrate online, a pull past μ held 100 ms then let go: the confirmed slip is learned,
    every wrench gets its verdict, no handler error (it raised there, and the verdict that
    ended the slip was lost)."""
    from dataclasses import replace

    from slipstack.lib.material import material_toml
    from slipstack.nodes.material_param import resolve_material

    path = tmp_path / "identified.toml"
    path.write_text(material_toml(replace(resolve_material("rubber"), onset_gamma=(0.97, 0.98, 0.81),
                                          onset_path=(0.02, 0.99, 0.34), onset_spread=(0.05, 0.38, 0.39))))
    loads = [0.2 * k for k in range(10)] + [4.0 * 0.4527 * 1.05] * 100 + [0.2] * 40
    ex = _run_with(SlipDetectorParams(material=str(path), calibrate="online"), loads)
    last = [d for d in ex.published["diagnostics"] if d.node == "slip_detector"][-1]
    assert last.counters.get("handler_errors", 0) == 0, last.last_error
    assert last.status.startswith("calibrated-online:") and "1 confirmed slip" in last.status, last.status
    assert len(ex.published["slip"]) == len(loads)


def test_a_pool_that_does_not_divide_the_pad_judges_it_unpooled_and_says_so():
    """``pool`` 3 on the 16×16 pad (``slipstack param set slip_detector pool 3``; the pad is
    known only from its frames): every contact gets the verdict of the full resolution, and
    the detector says once, on ``diagnostics`` and in the log, which pools fit (it raised on
    every contact: every verdict lost, the F/T tests' too)."""
    loads = [0.2 * k for k in range(10)] + [4.0 * 0.4527 * 1.1] * 30
    for method in ("exact", "coulomb"):
        plain = _run_with(SlipDetectorParams(method=method, material="rubber"), loads).published["slip"]
        ex = _run_with(SlipDetectorParams(method=method, material="rubber", pool=3), loads)
        last = [d for d in ex.published["diagnostics"] if d.node == "slip_detector"][-1]
        assert last.counters.get("handler_errors", 0) == 0, last.last_error
        slips = ex.published["slip"]
        assert [(s.state, s.status) for s in slips] == [(s.state, s.status) for s in plain]
        assert np.allclose([s.gamma for s in slips], [s.gamma for s in plain], rtol=1e-9, atol=1e-12)
        assert "pool 3 does not divide the pad's 16x16" in last.last_error, last.last_error
        assert len([line for line in ex.logs if "pool 3 does not divide" in line]) == 1, ex.logs


def test_a_delta_given_with_the_band_of_each_load_path_is_refused_not_ignored(tmp_path):
    """``delta:=0.3`` with a file that identified load paths and the default ``band`` path:
    the band of each load path would be used and the given delta never (a pull got 0.05),
    so the detector refuses it and says what to give; with ``band:=fixed``, or a file
    without load paths, the given delta is the band of every load."""
    import pytest
    from dataclasses import replace

    from slipstack.lib.errors import ConfigError
    from slipstack.lib.material import material_toml
    from slipstack.nodes.material_param import resolve_material

    path = tmp_path / "identified.toml"
    path.write_text(material_toml(replace(resolve_material("rubber"), onset_gamma=(0.97, 0.98, 0.81),
                                          onset_path=(0.02, 0.99, 0.34), onset_spread=(0.05, 0.38, 0.39))))
    with pytest.raises(ConfigError, match=r"delta := 0\.3 .*band:=fixed"):
        SlipDetectorParams(material=str(path), delta=0.3)
    for params in (SlipDetectorParams(material=str(path), delta=0.3, band="fixed"),
                   SlipDetectorParams(material="rubber", delta=0.3)):
        slips = _run_with(params, [0.2 * k for k in range(10)] + [4.0 * 0.4527 * 0.75] * 5).published["slip"]
        assert slips[-1].state == "translation", params  # γ 0.75 is in the band 1 - 0.3


def test_a_release_time_that_is_no_time_is_a_config_error_naming_it():
    """``release_ms`` nan or inf (``param set``, a launch file) is refused naming the parameter
    (the node raised ValueError / OverflowError converting it to ns), as a negative one is."""
    import pytest

    from slipstack.lib.errors import ConfigError

    for bad in (math.nan, math.inf, -1.0):
        with pytest.raises(ConfigError, match=r"release_ms must be a time >= 0 ms"):
            SlipDetector(SlipDetectorParams(release_ms=bad))


def test_a_material_written_by_identify_force_is_reported_as_refused(tmp_path):
    from dataclasses import replace

    from slipstack.lib.material import material_toml
    from slipstack.nodes.material_param import resolve_material

    path = tmp_path / "forced.toml"
    path.write_text(material_toml(replace(resolve_material("rubber"), refused="the band would be its cap")))
    ex = _run_with(SlipDetectorParams(material=str(path)), [0.2] * 5)
    last = [d for d in ex.published["diagnostics"] if d.node == "slip_detector"][-1]
    assert last.status.startswith("refused-material: ") and "identify --force" in last.status, last.status
    assert any("identify refused it: the band would be its cap" in line for line in ex.logs), ex.logs


def _noisy_press(material: str) -> InProcessExecutor:
    """The real fusion, slip detector and grip controller while a finger presses 0 -> 5 N in
    300 ms, holds, and lets go to 0.12 N from 400 to 500 ms, with no tangential load but the
    F/T's noise (0.01 N, 20 uN·m), on the pad's centre taxel first (a one-taxel pressure
    frame: torsional capacity 0)."""
    from slipstack.nodes.grip_controller import GripController, GripControllerParams
    rng = np.random.default_rng(3)
    events = []
    for k in range(1, 560):
        f_n = 5.0 * min(k / 300.0, 1.0) if k < 400 else max(5.0 - 4.88 * (k - 400) / 100.0, 0.12)
        events.append(wrench(k, f_n, float(rng.normal(0.0, 0.01)), seq=k, tau=float(rng.normal(0.0, 2e-5))))
        if k % 4 == 0:
            p = np.zeros(256, dtype=np.float32)
            if k < 40:
                p[8 * 16 + 8] = f_n / PITCH_M**2
            else:
                p[:] = tactile(k, f_n)[2].pressure_pa
            events.append(tactile(k, f_n, seq=k, pressure_pa=p))
    ex = InProcessExecutor([Fusion(), SlipDetector(SlipDetectorParams(material=material)),
                            GripController(GripControllerParams(law="exact", material=material))],
                           diagnostics_period_s=0.001)
    ex.feed(sorted(events, key=lambda e: e[0]))
    ex.run(until_ns=580 * MS)
    return ex


def test_a_press_below_the_ft_noise_is_not_judged_and_the_grip_is_held(tmp_path):
    """A material that knows its F/T's noise (identify measures it): verdicts on a capacity
    under 10 times that noise say ``below_noise``, raise no flag, and the grip controller
    does not start on them (docs/safety.md clause 4: it waits for trusted data) and, once
    started, holds the grip on them (fail-safe, never lower) when the finger lets go; the
    detector's ``diagnostics`` say so while it lasts and count those verdicts. Without the noise in the file the same
    press is judged: a one-taxel frame twisted by noise reads gamma = inf, a flag."""
    from slipstack.lib.material import load_material, material_toml
    from dataclasses import replace
    rubber = load_material(Path(slipstack.launch.__file__).parent / "materials" / "rubber.toml")
    quiet, plain = tmp_path / "quiet.toml", tmp_path / "plain.toml"
    quiet.write_text(material_toml(replace(rubber, force_noise_n=0.01, torque_noise_nm=2e-5)))
    plain.write_text(material_toml(replace(rubber, force_noise_n=math.nan, torque_noise_nm=math.nan)))
    ex = _noisy_press(str(quiet))
    slips = ex.published["slip"]
    below = [s for s in slips if s.status == "below_noise"]
    assert below and all(s.f_n < 0.25 or s.header.stamp_ns <= 40 * MS for s in below)  # one taxel, or let go
    assert any(s.header.stamp_ns > 400 * MS for s in below)
    assert not any(s.state not in ("stick", "no-contact") for s in slips)
    cmds = ex.published["grip/command"]
    held = [c for c in cmds if c.header.sources.get("slip") in {s.header.stamp_ns for s in below}]
    assert cmds[0].header.stamp_ns >= 40 * MS  # no command on the first touch's untrusted verdicts
    assert held and all(c.reason == "fail-safe" for c in held)
    assert all(b.f_n_desired >= a.f_n_desired - 1e-12 for a, b in zip(cmds, cmds[1:]) if b.reason == "fail-safe")
    diagnostics = [d for d in ex.published["diagnostics"] if d.node == "slip_detector"]
    assert any(d.status.startswith("below-noise: ") and "the grip is held" in d.status for d in diagnostics)
    assert diagnostics[-1].counters["slip.below_noise"] == len(below)
    assert any(d.status == "ok" and d.header.stamp_ns < 400 * MS for d in diagnostics)
    assert any(s.state not in ("stick", "no-contact") for s in _noisy_press(str(plain)).published["slip"])
