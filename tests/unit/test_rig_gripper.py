"""The simulated parallel gripper (lib/rig, docs/math.md §9): two pads on one object, one squeeze."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from slipstack.lib.errors import ConfigError
from slipstack.lib.rig.scene import parse_scene
from slipstack.lib.rig.simulator import Simulator, Truth
from slipstack.lib.samples import FtSample, TactileSample


def gripper_scene(**edits) -> dict:
    d = {
        "seed": 7, "duration_s": 0.6, "sim": {"step_us": 250},
        "object": {"mass_kg": 0.3, "inertia_kgm2": 3e-4, "pose": [0.0, -0.02, 0.0]},
        "contact": {"model": "flat", "footprint": "rect", "half_size_m": [0.006, 0.006],
                    "stiffness_N_per_m3": 2e9, "damping_Ns_per_m3": 2e6},
        "dof": {"free": ["x", "y", "theta"]},
        "finger": {"f_initial_N": 20.0, "f_max_N": 60.0},
        "disturbance": {"damping_Ns_per_m": 0.0, "damping_Nms_per_rad": 0.0},
        "gripper": {"gravity_m_s2": [0.0, -9.81], "weight_on_s": [0.0, 0.2]},
    }
    for key, value in edits.items():
        d.setdefault(key, {}).update(value) if isinstance(value, dict) else d.__setitem__(key, value)
    return d


def run_to_end(d: dict) -> tuple[Simulator, Truth, list]:
    sim = Simulator(parse_scene(d))
    samples = list(sim)
    truths = [s for s in samples if isinstance(s, Truth)]
    return sim, truths[-1], samples


def test_two_equal_pads_carry_the_weight_half_each_mirrored():
    _, last, _ = run_to_end(gripper_scene())
    (f0x, f0y, t0), (f1x, f1y, t1) = last.finger_loads
    weight = 0.3 * 9.81
    assert last.weight == pytest.approx((0.0, -weight))
    assert f0y == pytest.approx(-weight / 2, rel=1e-3) and f1y == pytest.approx(-weight / 2, rel=1e-3)
    assert f0x == pytest.approx(-f1x, abs=1e-6) and t0 == pytest.approx(-t1, abs=1e-9)  # finger 1 sees x and τ mirrored
    assert last.load_force == pytest.approx((f0x - f1x, f0y + f1y))  # both, in finger 0's frame
    assert last.slip_distance_m == 0.0


def test_a_stiffer_pad_carries_more_and_each_f_t_sensor_reads_its_own_finger():
    d = gripper_scene(gripper={"contact": {"model": "hertz", "a_ref_m": 0.004, "f_ref_N": 10.0}})
    sim, last, samples = run_to_end(d)
    (_, f0y, _), (_, f1y, _) = last.finger_loads
    assert f0y + f1y == pytest.approx(-0.3 * 9.81, rel=1e-3)
    assert abs(f0y) > 1.5 * abs(f1y)  # the flat pad has more taxels in contact: the stiffer share
    ft = {s.finger: s for s in samples if isinstance(s, FtSample) and s.stamp_ns == last.stamp_ns}
    for finger, (fx, fy, tau) in enumerate(last.finger_loads):
        mx, my, mt, fn = sim.ft.pad_load(ft[finger].force_n, ft[finger].torque_nm)
        assert (mx, my) == pytest.approx((fx, fy), abs=0.05) and fn == pytest.approx(last.f_n_applied, abs=0.05)
    frames = {s.finger for s in samples if isinstance(s, TactileSample)}
    assert frames == {0, 1}


def test_the_weight_comes_on_during_the_pick_up_and_poured_mass_adds_to_it():
    d = gripper_scene(gripper={"weight_on_s": [0.1, 0.3], "added_mass": [{"at_s": 0.35, "mass_kg": 0.1, "over_s": 0.1}]})
    sim = Simulator(parse_scene(d))
    weights = {}
    for t_ms in (100, 200, 300, 400, 500):
        sim.step_until(t_ms * 1_000_000)
        weights[t_ms] = -sim.truth().weight[1]
    g = 9.81
    assert weights[100] == pytest.approx(0.0, abs=1e-9) and weights[200] == pytest.approx(0.15 * g, rel=0.01)
    assert weights[300] == pytest.approx(0.3 * g, rel=2e-3) and weights[400] == pytest.approx(0.35 * g, rel=0.01)
    assert weights[500] == pytest.approx(0.4 * g) and sim.truth().mass_kg == pytest.approx(0.4)


def test_an_attached_footprint_follows_the_slip_not_the_elastic_twist():
    # a bar's weight twists the pads elastically: the pressure the pads see does not turn with it
    d = gripper_scene(object={"mass_kg": 0.08, "inertia_kgm2": 6e-4, "pose": [0.12, 0.0, 0.0]},
                      contact={"half_size_m": [0.008, 0.003]}, sim={"step_us": 200},
                      gripper={"gravity_m_s2": [-4.905, -8.4957], "weight_on_s": [0.0, 0.3]},
                      finger={"f_initial_N": 40.0})
    sim = Simulator(parse_scene(d))
    before = sim.taxel_state().phi.copy()
    sim.step_until(500_000_000)
    truth = sim.truth()
    assert truth.slip_distance_m == 0.0 and abs(truth.theta) > math.radians(0.2)  # turned, elastically
    assert np.array_equal(sim.taxel_state().phi > 0, before > 0)


def test_a_gripper_scene_names_what_it_cannot_take():
    bad = gripper_scene(gripper={"contact": {"stiffness_N_per_m3": 1e9}})
    with pytest.raises(ConfigError, match="gripper.contact: stiffness_N_per_m3 must equal"):
        parse_scene(bad)
    with pytest.raises(ConfigError, match="ridges are a flat or offset face's"):
        parse_scene(gripper_scene(gripper={"contact": {"model": "hertz", "ridge_depth": 0.5}}))
    with pytest.raises(ConfigError, match="weight_on_s"):
        parse_scene(gripper_scene(gripper={"weight_on_s": [0.5, 0.1]}))


def test_a_contact_damped_harder_than_the_step_resolves_is_refused():
    with pytest.raises(ConfigError, match="damping_Ns_per_m3: 2e\\+07 damps the object faster"):
        Simulator(parse_scene(gripper_scene(contact={"damping_Ns_per_m3": 2e7})))
