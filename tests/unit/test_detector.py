"""The library slip detector (lib/detector.py) without the node graph."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from slipstack.lib.detector import FT_TESTS, Detector, DetectorSettings, PadContact
from slipstack.lib.errors import ConfigError
from slipstack.lib.material import Material
from slipstack.lib.slip_tests import SLIP_TESTS
from slipstack.nodes.material_param import resolve_material
from slipstack.nodes.slip_detector import SlipDetector, SlipDetectorParams

ROWS = COLS = 16
PITCH_M = 1.25e-3
MU, DELTA, GAMMA_RELEASE = 0.45, 0.1, 0.76
SETTINGS = DetectorSettings(mu=MU, delta=DELTA, gamma_release=GAMMA_RELEASE, onset_frames=1)


def pressed(f_x_n: float, f_n: float = 10.0, status: str = "ok") -> PadContact:
    """A flat pad pressed evenly with ``f_n`` N and pulled along x with ``f_x_n`` N."""
    phi = np.full(ROWS * COLS, f_n / (ROWS * COLS))
    return PadContact(f_n=f_n, f_t=np.array([f_x_n, 0.0]), tau=0.0, phi=phi, rows=ROWS, cols=COLS,
                      pitch_m=PITCH_M, status=status)


def test_node_defaults_are_the_material_defaults() -> None:
    """No material file: the shipped rubber's thresholds; online calibration only when asked."""
    rubber = resolve_material("rubber")
    assert SlipDetector().detector.settings == DetectorSettings.from_material(rubber)
    online = SlipDetector(SlipDetectorParams(calibrate="online")).detector.settings
    assert online == DetectorSettings.from_material(rubber, calibrate_from=rubber)
    assert set(FT_TESTS) < set(SLIP_TESTS) and online.also == FT_TESTS
    # the shipped files carry the rig's F/T noise (identify on their ramps), so the default guards too
    for name in ("rubber", "coulomb", "weakening"):
        m = resolve_material(name)
        assert m.force_noise_n == pytest.approx(0.01, rel=0.1) and m.torque_noise_nm == pytest.approx(5e-5, rel=0.1)
    assert SlipDetector().detector.settings.force_noise_n == rubber.force_noise_n


def test_a_pulled_pad_slips_latches_through_a_stale_frame_and_releases_after_the_dwell() -> None:
    det = Detector(SETTINGS)
    ms = 1_000_000
    # γ of a pure pull on an even pressure is |f_t| / (μ f_n) = 1 / 4.5
    v = det.step(pressed(1.0), 0)
    assert (v.state, v.slipping, v.status, v.method) == ("stick", False, "ok", "exact")
    assert v.gamma == pytest.approx(1.0 / 4.5, abs=1e-6) and v.margin == pytest.approx(1.0 - v.gamma)
    assert list(v.verdicts) == ["exact", *FT_TESTS] and all(stick for stick, _ in v.verdicts.values())
    # 4.4 N: γ = 0.978 >= 1 − δ: translation slip, and every side test fails too
    v = det.step(pressed(4.4), 1 * ms)
    assert (v.state, v.kind, v.slipping, v.status) == ("translation", "translation", True, "ok")
    assert v.gamma == pytest.approx(4.4 / 4.5, abs=1e-6)
    assert not any(stick for stick, _ in v.verdicts.values())
    # a stale wrench says nothing new: the latch holds, the status says why
    v = det.step(pressed(1.0, status="stale"), 2 * ms)
    assert (v.state, v.slipping, v.status) == ("translation", True, "stale")
    # valid and well below the release level: released only after 20 ms of such frames
    assert det.step(pressed(1.0), 3 * ms).slipping
    assert det.step(pressed(1.0), 22 * ms).slipping
    v = det.step(pressed(1.0), 23 * ms)
    assert (v.state, v.slipping) == ("stick", False)


def test_lost_contact_clears_the_latch() -> None:
    det = Detector(SETTINGS)
    assert det.step(pressed(4.4), 0).slipping
    v = det.step(pressed(0.0, f_n=0.0, status="no_contact"), 1_000_000)
    assert (v.state, v.slipping, v.status) == ("no-contact", False, "no_contact")


def test_a_tactile_test_without_a_pressure_frame_is_not_valid_an_ft_test_is() -> None:
    wrench_only = PadContact(f_n=10.0, f_t=np.array([1.0, 0.0]), tau=0.0)
    v = Detector(SETTINGS).step(wrench_only, 0)
    assert (v.status, v.state) == ("tactile_none", "stick")
    ft = Detector(DetectorSettings(mu=MU, delta=DELTA, gamma_release=GAMMA_RELEASE, method="coulomb",
                                   beta_m=0.003)).step(wrench_only, 0)
    assert (ft.status, ft.method) == ("ok", "coulomb")
    assert ft.gamma == pytest.approx(1.0 / 4.5)


@pytest.mark.parametrize("method", ["decoupled", "linear_ls", "elliptic_ls"])
def test_an_ft_test_with_beta_from_tactile_needs_the_pressure_frame_as_a_tactile_test_does(method: str) -> None:
    """beta_m 0 (the launch files' default): β is β_s of each pressure frame, so without one
    the test has no verdict, loaded or not, and says why as a tactile test does (it said
    ``invalid_input`` when loaded and ``ok`` when not: a run that never judged a load looked
    healthy); with β given, or for the Coulomb test, which needs none, the verdict is valid."""
    settings = DetectorSettings(mu=MU, delta=DELTA, gamma_release=GAMMA_RELEASE, method=method)
    for f_x in (0.0, 1.0):
        v = Detector(settings).step(PadContact(f_n=10.0, f_t=np.array([f_x, 0.0]), tau=0.0), 0)
        assert (v.status, v.state) == ("tactile_none", "stick"), f_x
    wrench_only = PadContact(f_n=10.0, f_t=np.array([1.0, 0.0]), tau=1e-3)
    for given in (replace(settings, beta_m=0.003), replace(settings, method="coulomb")):
        assert Detector(given).step(wrench_only, 0).status == "ok", given


@pytest.mark.parametrize("bad", [{"method": "magic"}, {"also": ("coulomb", "magic")}, {"delta": 1.0},
                                 {"gamma_release": 0.0}, {"mu": 0.0}, {"beta_m": -1.0}, {"pool": 0}])
def test_bad_settings_are_config_errors(bad: dict) -> None:
    with pytest.raises(ConfigError):
        Detector(DetectorSettings(**{"mu": MU, "delta": DELTA, "gamma_release": GAMMA_RELEASE, **bad}))


def test_a_pull_held_on_a_flat_pad_is_quiet_and_the_same_load_on_a_curved_tip_is_flagged() -> None:
    """The band of the load's own path and pressure spread (lib/onset_band.py): the material's
    pulls on a flat pad let go at 0.99, a force off a curved tip's centre at 0.81. A pull held
    at γ 0.95 on the flat pad is not at its limit; on a curved tip (no pull identified there)
    the band falls back to the lowest onset and flags it."""
    material = Material("m", mu_s=MU, mu_d=0.36, beta_s_m=1.3e-3, beta_d_m=1.07e-3, gamma_noise_stick=0.005,
                        gamma_noise_slide=0.005, onset_gamma=(0.99, 0.99, 0.81), onset_path=(0.0, 0.01, 0.34),
                        onset_spread=(0.05, 0.05, 0.39))
    settings = DetectorSettings.from_material(material, onset_frames=1)
    flat = Detector(settings)
    assert not any(flat.step(pressed(0.95 * 4.5), k * 1_000_000).slipping for k in range(50))
    assert flat.step(pressed(0.99 * 4.5), 50_000_000).slipping
    r = np.hypot(*(np.indices((ROWS, COLS)) - 7.5)) * PITCH_M  # a Hertzian tip of radius 5 mm
    phi = np.sqrt(np.clip(1.0 - (r / 5e-3) ** 2, 0.0, None)).ravel()
    tip = PadContact(f_n=10.0, f_t=np.array([0.95 * 4.5, 0.0]), tau=0.0, phi=10.0 * phi / phi.sum(), rows=ROWS,
                     cols=COLS, pitch_m=PITCH_M)
    assert Detector(settings).step(tip, 0).slipping


def test_a_capacity_under_ten_times_the_ft_noise_is_not_judged_and_keeps_the_latch() -> None:
    """Noise 0.01 N, 20 µN·m: μ f_n = 0.45 × 0.2 = 0.09 N < 0.1 N is not judged (a pull of
    0.2 N would read γ 2.2); at 0.23 N (0.1035 N) it is. A one-taxel frame has no torsional
    capacity (β_s 0): any torque reads γ = inf without the guard, ``below_noise`` with it.
    A latched slip stays latched through such frames (an invalid verdict never releases)."""
    ms = 1_000_000
    quiet = DetectorSettings(mu=MU, delta=DELTA, gamma_release=GAMMA_RELEASE, onset_frames=1,
                             force_noise_n=0.01, torque_noise_nm=2e-5)
    det = Detector(quiet)
    v = det.step(pressed(0.2, f_n=0.2), 0, tactile_frame=0)
    assert (v.status, v.slipping) == ("below_noise", False)
    v = det.step(pressed(0.01, f_n=0.23), 1 * ms, tactile_frame=1)
    assert (v.status, v.slipping) == ("ok", False) and v.gamma == pytest.approx(0.01 / (MU * 0.23), rel=1e-6)
    phi = np.zeros(ROWS * COLS)
    phi[8 * COLS + 8] = 1.0
    one_taxel = PadContact(f_n=5.0, f_t=np.zeros(2), tau=1e-4, phi=phi, rows=ROWS, cols=COLS, pitch_m=PITCH_M,
                           status="ok")
    assert Detector(SETTINGS).step(one_taxel, 0).slipping  # judged: γ = inf
    assert det.step(one_taxel, 2 * ms, tactile_frame=2).status == "below_noise"
    assert det.step(pressed(4.4), 3 * ms, tactile_frame=3).slipping
    v = det.step(pressed(0.0, f_n=0.1), 40 * ms, tactile_frame=4)
    assert (v.status, v.slipping) == ("below_noise", True)
