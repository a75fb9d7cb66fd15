"""The library slip detector (lib/detector.py) without the node graph."""

from __future__ import annotations


import numpy as np
import pytest

from slipstack.lib.detector import FT_TESTS, Detector, DetectorSettings, PadContact
from slipstack.lib.errors import ConfigError
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


@pytest.mark.parametrize("bad", [{"method": "magic"}, {"also": ("coulomb", "magic")}, {"delta": 1.0},
                                 {"gamma_release": 0.0}, {"mu": 0.0}, {"beta_m": -1.0}, {"pool": 0}])
def test_bad_settings_are_config_errors(bad: dict) -> None:
    with pytest.raises(ConfigError):
        Detector(DetectorSettings(**{"mu": MU, "delta": DELTA, "gamma_release": GAMMA_RELEASE, **bad}))
