"""Two fingers, one squeeze (lib/grasp.py): hand-checked values of the least squeeze, the
limit-set prediction, the pads' view of the object, and the tracking law's phases."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slipstack.lib import grasp as G
from slipstack.lib.pad import PadGeometry
from slipstack.lib.rig.contact import PressureModel
from slipstack.lib.rig.scene import ContactSpec

PAD = PadGeometry()
POS = PAD.positions


def test_the_least_squeeze_is_the_larger_finger_share_not_the_half_of_the_total():
    # finger 0 carries 3 N at 10 N squeeze (γ = 3/(0.45·10)), finger 1 carries 1 N
    g0, g1 = 3.0 / 4.5, 1.0 / 4.5
    assert G.least_squeeze((g0, g1), (10.0, 10.0)) == pytest.approx(3.0 / 0.45)
    assert G.least_squeeze((g0, math.nan), (10.0, 10.0)) != G.least_squeeze((g0, math.nan), (10.0, 10.0))  # NaN
    assert G.least_squeeze((math.inf, 0.1), (10.0, 10.0)) == math.inf
    assert G.load_shares(((0.0, -3.0), (0.0, -1.0))) == pytest.approx((0.75, 0.25))


def test_finger_1_sees_the_load_mirrored():
    assert G.to_finger0((1.0, -2.0), 0.3) == ((-1.0, -2.0), -0.3)
    phi = np.ones(PAD.n_taxels)
    p, x, f_t, tau = G.combined_contact((phi, 2 * phi), POS, (((0.5, -1.0), 0.01), ((0.25, -1.0), 0.02)))
    assert p.shape == (512,) and x[256:, 0] == pytest.approx(-POS[:, 0]) and x[256:, 1] == pytest.approx(POS[:, 1])
    assert f_t == pytest.approx((0.25, -2.0)) and tau == pytest.approx(-0.01)


def test_the_prediction_of_a_pure_weight_on_two_uniform_pads_is_coulombs():
    # two whole pads pressed with 10 N each carry 3 N of weight: the static limit 2·μ_s·f holds
    # it down to f = 3/(2·0.45), sliding friction balances it at 3/(2·0.36); no turn
    phi = np.full(PAD.n_taxels, 10.0 / PAD.n_taxels)
    p, x, f_t, tau = G.combined_contact((phi, phi), POS, (((0.0, -1.5), 0.0), ((0.0, -1.5), 0.0)))
    r = G.predict_turn(p, x, f_t, tau, 10.0, 0.45, 0.36)
    assert r.usable and r.sense == 0 and r.cor is None
    assert r.start_n == pytest.approx(3.0 / 0.9, rel=1e-9) and r.kinetic_n == pytest.approx(3.0 / 0.72, rel=1e-9)
    assert r.hold_translation_n == pytest.approx(3.0 / 0.72)


def test_a_torque_is_predicted_to_turn_the_object_about_a_point_near_the_grasp_axis():
    phi = np.full(PAD.n_taxels, 10.0 / PAD.n_taxels)
    p, x, f_t, tau = G.combined_contact((phi, phi), POS, (((0.0, -0.5), -0.02), ((0.0, -0.5), 0.02)))
    r = G.predict_turn(p, x, f_t, tau, 10.0, 0.45, 0.36)
    # the COR lies across the force (−y) from the pads' centre, where its torque and force balance
    assert r.sense == -1 and r.cor is not None and abs(r.cor[1]) < 1e-9 and -3e-3 < r.cor[0] < -1e-3
    assert r.kinetic_n == pytest.approx(r.start_n * 0.45 / 0.36)
    assert r.start_n < 10.0  # the load is held at 10 N


@pytest.mark.parametrize("deg", [0.0, 17.0, 44.0, 71.0])
def test_the_pad_sees_an_elongated_footprint_turn(deg):
    spec = ContactSpec(model="flat", footprint="rect", half_size_m=(0.008, 0.003))
    model = PressureModel(spec, PAD, (0.0, 0.0, 0.0))
    pose = G.pad_pose(model.phi(10.0, 0j, math.radians(deg)), POS)
    assert pose.elongation > 3.0 and pose.force == pytest.approx(10.0)
    assert math.degrees(G._wrap_half_turn(pose.angle - math.radians(deg))) == pytest.approx(0.0, abs=1.0)
    disc = PressureModel(ContactSpec(model="flat", footprint="disc", radius_m=0.006), PAD, (0.0, 0.0, 0.0))
    assert G.pad_pose(disc.phi(10.0, 0j, 0.0), POS).elongation < 1.1
    assert G.pad_pose(np.zeros(PAD.n_taxels), POS) is None


def test_the_estimator_averages_finger_1s_mirrored_view_and_unwraps_past_the_half_turn():
    spec = ContactSpec(model="flat", footprint="rect", half_size_m=(0.008, 0.003))
    m0 = PressureModel(spec, PAD, (0.0, 0.0, 0.0))
    m1 = PressureModel(spec, PAD, (0.0, 0.0, 0.0))
    est = G.MotionEstimator(window_ns=100_000_000)
    for k in range(51):  # the object turns 100° at 200 °/s, a frame every 10 ms
        a = math.radians(2.0 * k)
        poses = (G.pad_pose(m0.phi(10.0, 0j, a), POS), G.pad_pose(m1.phi(10.0, 0j, -a), POS))
        motion = est.update(k * 10_000_000, poses)
    assert motion.sees_angle
    assert math.degrees(motion.angle) == pytest.approx(100.0, abs=1.0)
    assert math.degrees(motion.rate) == pytest.approx(200.0, rel=0.05)  # the taxel raster's error: < 1° an angle


def test_the_odometer_follows_the_ridges_of_a_face_sliding_down_both_pads():
    spec = ContactSpec(model="flat", footprint="pad", ridge_depth=0.5, ridge_period_m=0.005,
                       ridge_angle_rad=math.pi / 2)
    m0 = PressureModel(spec, PAD, (0.0, 0.0, 0.0))
    m1 = PressureModel(spec, PAD, (0.0, 0.0, 0.0))
    odo = G.TextureOdometer(0.005, POS, (0.0, -1.0))
    for k in range(101):  # 20 mm down at 20 mm/s, a frame every 2 ms: 0.04 mm a frame
        y = -0.0002 * k
        progress, rate = odo.update(k * 2_000_000, (m0.phi(10.0, complex(0.0, y), 0.0),
                                                    m1.phi(10.0, complex(0.0, y), 0.0)))
    assert odo.sees and progress == pytest.approx(0.020, abs=2e-4) and rate == pytest.approx(0.1, rel=0.05)
    blank = G.TextureOdometer(0.005, POS, (0.0, -1.0))
    flat = np.full(PAD.n_taxels, 10.0 / PAD.n_taxels)
    blank.update(0, (flat, flat))
    assert not blank.sees


def test_the_tracking_law_releases_tracks_and_regrips():
    g = G.TrackGains(k_p=100.0, k_d=0.0, k_i=0.0, release_n_per_s=10.0, accel=1000.0, moving=0.01, lead_s=0.0)
    c = G.TrackControl(0.5, 0.25, start_n=20.0, kinetic_n=25.0, floor_n=5.0, now_ns=0, gains=g)
    assert c.step(0, 0.0, 0.0, 21.0) == G.ModeOutput(20.4, "release")
    assert c.step(500_000_000, 0.0, 0.0, 21.0).demand_n == pytest.approx(15.4)  # 10 N/s down
    out = c.step(600_000_000, 0.02, 0.25, 21.0)  # it moved: the reference starts at its progress
    assert out.phase == "track" and out.demand_n == pytest.approx(25.0, abs=0.1)
    out = c.step(1_600_000_000, 0.02 + 0.15, 0.25, 21.0)  # 0.1 rad behind a reference at 0.25 rad
    assert out.demand_n == pytest.approx(25.0 - 100.0 * (0.25 - 0.15), abs=0.2)
    out = c.step(2_000_000_000, 0.5, 0.25, 21.0)
    assert out == G.ModeOutput(25.0 * g.regrip_margin, "regrip", "reached")


def test_the_feed_forward_weakens_from_the_breakaway_squeeze_and_a_stuck_object_is_released_again():
    g = G.TrackGains(k_p=0.0, k_d=0.0, k_i=0.0, release_n_per_s=10.0, accel=1000.0, moving=0.01, lead_s=0.0,
                     weakening=0.1)
    c = G.TrackControl(1.0, 0.25, start_n=20.0, kinetic_n=25.0, floor_n=5.0, now_ns=0, gains=g)
    c.step(0, 0.0, 0.0, 21.0)
    out = c.step(100_000_000, 0.02, 0.25, 21.0)  # broke away at 20.4 - 10 N/s x 0.1 s = 19.4 N
    assert out.phase == "track" and out.demand_n == pytest.approx(19.4)  # static friction still: its squeeze
    out = c.step(200_000_000, 0.12, 0.25, 21.0)  # 0.1 further: friction weakened by 1/e towards sliding
    assert out.demand_n == pytest.approx(25.0 + (19.4 - 25.0) * math.exp(-1.0))
    # it sticks: the reference runs on, the object does not; it is released from where it broke away
    out = c.step(800_000_000, 0.12, 0.0, 21.0)  # the reference at 0.175 from where tracking began
    assert out.phase == "release" and out.demand_n == pytest.approx(19.4)
    out = c.step(900_000_000, 0.125, 0.0, 21.0)  # still stuck: lowered at the release rate
    assert out.phase == "release" and out.demand_n == pytest.approx(18.4)
    out = c.step(1_000_000_000, 0.135, 0.2, 21.0)  # moved 0.015 since: tracking again, from static friction
    assert out.phase == "track" and out.demand_n == pytest.approx(17.4)


def test_the_drop_guards_end_the_mode_and_grip():
    g = G.TrackGains(k_p=100.0, k_d=0.0, k_i=0.0, release_n_per_s=100.0, accel=1000.0, moving=0.01,
                     overspeed=3.0, overspeed_min=0.5)
    c = G.TrackControl(0.5, 0.25, start_n=20.0, kinetic_n=25.0, floor_n=12.0, now_ns=0, gains=g)
    assert c.step(200_000_000, 0.0, 0.0, 21.0).demand_n == 12.0  # held at the floor
    out = c.step(600_000_000, 0.0, 0.0, 21.0)  # at the floor for 0.4 s and still not moving
    assert out.phase == "regrip" and out.ended.startswith("drop-guard") and out.demand_n == pytest.approx(37.5)
    fast = G.TrackControl(0.5, 0.25, start_n=20.0, kinetic_n=25.0, floor_n=5.0, now_ns=0, gains=g)
    out = fast.step(1_000_000, 0.05, 0.8, 21.0)  # 0.8 rad/s: over 3 × 0.25 and over 0.5
    assert out.ended.startswith("drop-guard: moving at 3.2 times")


def test_the_squeeze_law_hands_the_grasp_nodes_demand_to_the_governor():
    from slipstack.lib.grip_laws import GripInput, GripReason
    law = G.SqueezeLaw(f_nom_n=5.0, f_max_n=60.0)
    assert law.decide(GripInput(demand_n=12.0)).f_n_desired == 12.0
    assert law.decide(GripInput(demand_n=2.0)).f_n_desired == 5.0
    assert law.decide(GripInput()).reason is GripReason.FAIL_SAFE
