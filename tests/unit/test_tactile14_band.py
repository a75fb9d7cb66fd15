"""Law (14)'s onset band, release level and no-COR hold, inside the law (lib/grip_laws.py).

Hand-checked numbers: μ = σ = 0.5, Σ|p_i − p_c| = 0.08 m, N_A = 10 taxels, so the lever
σ μ Σ|p_i − p_c| = 0.02 m and every 0.001 N·m of excess torque costs 0.05 N per taxel,
0.5 N in total. T(p_c) = 0.06 N·m; δ = 0.2 (level 0.8 T = 0.048 N·m while the detector
reports stick); γ_release = 0.7 (level 0.7 T = 0.042 N·m while it reports slip).
"""

from __future__ import annotations

import dataclasses
import math

import pytest

from slipstack.lib.errors import ConfigError
from slipstack.lib.grip_laws import GripInput, GripReason, Tactile14Law, make_law
from slipstack.lib.material import detector_thresholds
from slipstack.nodes.grip_controller import GripController, GripControllerParams
from slipstack.nodes.material_param import resolve_material

LAW = Tactile14Law(mu=0.5, sigma=0.5, delta=0.2, gamma_release=0.7, f_nom_n=1.0, f_max_n=30.0)
BELOW_T = GripInput(f_n=5.0, n_c=0.05, t_c=0.06, sum_dist_m=0.08, n_contact=10, cor_case="rotation",
                    slip_state="stick")


def test_onset_band_fails_test_11_below_the_capacity() -> None:
    # |n| = 0.05 < T = 0.06, but > 0.8 T = 0.048: excess 0.002 N·m -> 0.1 N per taxel, 1 N in total
    d = LAW.decide(BELOW_T)
    assert (d.f_n_desired, d.reason) == (pytest.approx(6.0), GripReason.SLIP)
    # the paper's plain test (the defaults δ = 0, γ_release = 1) holds at the same load
    plain = Tactile14Law(mu=0.5, sigma=0.5, f_nom_n=1.0, f_max_n=30.0)
    assert plain.decide(BELOW_T).f_n_desired == pytest.approx(5.0)


@pytest.mark.parametrize(("state", "expected_n"), [
    ("stick", 5.0),  # |n| = 0.045 < 0.048: (11) holds inside the band, hold 5 N
    ("no-contact", 5.0),  # not slipping: the onset band applies
    ("translation", 6.5),  # latched: level 0.042, excess 0.003 N·m -> 0.15 N/taxel, 1.5 N
    ("rotation", 6.5),
    ("combined", 6.5),
])
def test_release_level_applies_while_the_detector_reports_slip(state: str, expected_n: float) -> None:
    inp = dataclasses.replace(BELOW_T, n_c=-0.045, slip_state=state)  # either sense of rotation
    assert LAW.decide(inp).f_n_desired == pytest.approx(expected_n)


def test_on_taxel_cor_is_a_rotation_case() -> None:
    assert LAW.decide(dataclasses.replace(BELOW_T, cor_case="on-taxel")).f_n_desired == pytest.approx(6.0)


@pytest.mark.parametrize("case", ["translation", "none"])
def test_without_a_cor_of_rotation_the_law_holds_and_needs_only_f_n(case: str) -> None:
    # (11) cannot fail by rotation: the torque inputs are not read, even when unknown
    blind = GripInput(f_n=5.0, cor_case=case, slip_state="translation")  # n_c, t_c, sum_dist_m NaN
    d = LAW.decide(blind, dt_s=0.5)
    assert (d.f_n_desired, d.reason) == (5.0, GripReason.SLIP)
    decaying = Tactile14Law(decay_n_per_s=2.0, f_nom_n=1.0, f_max_n=30.0)
    assert decaying.decide(blind, dt_s=0.5).f_n_desired == pytest.approx(4.0)  # 5 − 2 N/s · 0.5 s
    assert LAW.decide(dataclasses.replace(blind, f_n=math.nan)).reason is GripReason.FAIL_SAFE


def test_a_rotation_case_with_an_unknown_capacity_is_fail_safe() -> None:
    d = LAW.decide(dataclasses.replace(BELOW_T, t_c=math.nan))
    assert (d.f_n_desired, d.reason) == (30.0, GripReason.FAIL_SAFE)
    assert "t_c" in d.detail


@pytest.mark.parametrize(("field", "value"), [("delta", 1.0), ("delta", -0.1), ("gamma_release", 0.0),
                                              ("gamma_release", 1.5), ("delta", math.nan)])
def test_band_parameters_out_of_range_are_config_errors(field: str, value: float) -> None:
    with pytest.raises(ConfigError, match=field):
        make_law("tactile14", f_nom_n=1.0, f_max_n=30.0, **{field: value})


def test_controller_gives_the_law_the_materials_band() -> None:
    law = GripController(GripControllerParams(law="tactile14")).law
    thresholds = detector_thresholds(resolve_material("rubber"))
    assert (law.delta, law.gamma_release) == (thresholds.delta, thresholds.gamma_release)
    assert 0.0 < law.delta < 1.0 and law.gamma_release < 1.0  # a real band, not the plain test
