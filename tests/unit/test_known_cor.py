"""Test (11) about a known pivot (lib/known_cor.py) through the detector and its node."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slipstack.lib.detector import Detector, DetectorSettings, PadContact
from slipstack.lib.errors import ConfigError
from slipstack.lib.known_cor import KNOWN_COR_METHOD
from slipstack.nodes.slip_detector import SlipDetector, SlipDetectorParams

PIVOT_M = (0.005, 0.005)  # on the taxel at (+5 mm, +5 mm) of a 2 x 2 pad with a 10 mm pitch


def two_by_two(tau_nm: float, f_x_n: float = 1.0, phi=(1.0, 1.0, 1.0, 1.0)) -> PadContact:
    return PadContact(f_n=float(sum(phi)), f_t=np.array([f_x_n, 0.0]), tau=tau_nm, phi=np.array(phi), rows=2,
                      cols=2, pitch_m=0.01)


def detector(delta: float = 0.1) -> Detector:
    """One frame in the band raises the flag (``onset_frames`` 1), so each step is judged alone."""
    return Detector(DetectorSettings(mu=0.5, delta=delta, gamma_release=0.76, method=KNOWN_COR_METHOD,
                                     also=(), known_cor_m=PIVOT_M, onset_frames=1))


def test_the_load_factor_about_the_pivot_is_the_hand_computed_one():
    # Taxels at (±5, ±5) mm, 1 N each. About the pivot (5, 5) mm their distances are 0, 10, 10
    # and 10√2 mm: T = μ Σ φ_i |p_i − p_c| = 0.5 · 1 N · 34.142 mm = 17.071 N·mm.
    # f_t = (1, 0) N acts at the origin: n = τ + f_tx·p_cy − f_ty·p_cx = τ + 5 N·mm.
    v = detector().step(two_by_two(0.010), 0)
    assert v.gamma == pytest.approx(15.0 / 17.0711, rel=1e-4)  # 0.8787
    assert (v.state, v.kind, v.status, v.method, v.p_c) == ("stick", "stick", "ok", KNOWN_COR_METHOD, PIVOT_M)
    v = detector().step(two_by_two(0.013), 0)
    assert v.gamma == pytest.approx(18.0 / 17.0711, rel=1e-4)  # 1.0544: (11) fails
    assert (v.state, v.slipping, v.kind) == ("rotation", True, "rotation")


def test_a_torque_that_the_pivot_cancels_is_no_load_and_the_estimated_cor_disagrees():
    # τ = −5 N·mm exactly cancels the moment of f_t about the pivot: nothing loads the contact there.
    v = detector(delta=0.0).step(two_by_two(-0.005), 0)
    assert (v.gamma, v.state, v.status) == (0.0, "stick", "ok")
    free = Detector(DetectorSettings(mu=0.5, delta=0.0, gamma_release=0.76, method="exact", also=()))
    assert free.step(two_by_two(-0.005), 0).gamma > 0.2  # a free object would feel that load


def test_all_pressure_on_the_pivot_cannot_resist_a_torque_about_it():
    v = detector().step(two_by_two(0.01, phi=(0.0, 0.0, 0.0, 4.0)), 0)
    assert v.gamma == math.inf and v.slipping


def test_without_a_pressure_frame_or_with_bad_numbers_the_verdict_is_not_valid():
    det = detector()
    no_frame = PadContact(f_n=4.0, f_t=np.array([1.0, 0.0]), tau=0.01, rows=2, cols=2, pitch_m=0.01)
    assert det.step(no_frame, 0).status == "tactile_none"
    assert det.step(two_by_two(math.nan), 1).status != "ok"


@pytest.mark.parametrize("settings", [
    {"method": KNOWN_COR_METHOD},  # no pivot
    {"method": "exact", "known_cor_m": PIVOT_M},  # a pivot the method would ignore
    {"method": KNOWN_COR_METHOD, "known_cor_m": (0.005, math.nan)},
])
def test_a_known_cor_goes_with_its_method_only(settings):
    with pytest.raises(ConfigError, match="known COR"):
        Detector(DetectorSettings(mu=0.5, delta=0.1, gamma_release=0.76, **settings))


def test_the_node_takes_the_pivot_as_two_coordinates():
    node = SlipDetector(SlipDetectorParams(method=KNOWN_COR_METHOD, known_cor_x_m=0.004, known_cor_y_m=0.002))
    assert node.detector.settings.known_cor_m == (0.004, 0.002)
    with pytest.raises(ConfigError, match="known COR"):
        SlipDetector(SlipDetectorParams(method=KNOWN_COR_METHOD, known_cor_x_m=0.004))
