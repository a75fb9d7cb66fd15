"""Physics checks of the simulated rig (issue "The simulated rig", Must show 1).

Each test builds a short scene with sensors off (truth only) and checks an outcome
against an independent computation: Coulomb onset μ_s·f_n, the pure-torque limit
min_c μ Σ φ_i |p_i − c| (scipy), Hertz scaling f_n^{4/3}, energy books, determinism.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.optimize

import slipstack.launch
from slipstack.lib.errors import ConfigError
from slipstack.lib.limit_set import load_factor
from slipstack.lib.pad import PadGeometry
from slipstack.lib.rig.actuator import FingerActuator
from slipstack.lib.rig.contact import PressureModel
from slipstack.lib.rig.disturbance import Profile
from slipstack.lib.rig.scene import ContactSpec, FingerSpec, Segment, load_scene, parse_scene, with_rig_material
from slipstack.lib.rig.simulator import GROSS_SLIP_FRACTION, Simulator, Truth

MU = 0.45


def make_scene(*, contact: dict, free=("x", "y", "theta"), segments: list, f_n=5.0,
               duration=1.0, step_us=1000, seed=1, mode="wrench", sensors=False,
               damping=(0.0, 0.0), **extra):
    data = {
        "name": "test", "seed": seed, "duration_s": duration,
        "object": {"mass_kg": 0.2, "inertia_kgm2": 4e-5},
        "contact": {"mu_s": MU, "mu_d": MU, "mu_spread": 0.0, **contact},
        "dof": {"free": list(free)},
        "finger": {"f_initial_N": f_n},
        "sim": {"step_us": step_us, "truth_rate_hz": 1e6 / step_us},
        "sensors": {"ft": {"enabled": sensors}, "tactile": {"enabled": sensors}},
        "disturbance": {"mode": mode, "segments": segments,
                        "damping_Ns_per_m": damping[0], "damping_Nms_per_rad": damping[1]},
    }
    data.update(extra)
    return parse_scene(data)


def truths(sim: Simulator) -> list[Truth]:
    return [s for s in sim if isinstance(s, Truth)]


def pure_torque_limit(phi: np.ndarray, pos: np.ndarray, mu: float) -> tuple[float, np.ndarray]:
    """min over c of μ Σ φ_i |p_i − c| (docs/math.md §4.3), by scipy, independent of the rig."""
    def torque(c):
        return mu * float(np.sum(phi * np.hypot(pos[:, 0] - c[0], pos[:, 1] - c[1])))
    res = scipy.optimize.minimize(torque, (phi @ pos) / phi.sum(), method="Nelder-Mead",
                                  options={"xatol": 1e-9, "fatol": 1e-12})
    return res.fun, res.x


# --------------------------------------------------------------------------- onset


def test_force_ramp_starts_sliding_at_mu_s_fn():
    scene = make_scene(contact={"model": "flat", "mu_d": 0.36},
                       segments=[{"kind": "ramp", "duration_s": 1.0, "force_N": [0.0, 4.0]}])
    tr = truths(Simulator(scene))
    onset = next(t for t in tr if t.gross_slip)
    expected = MU * 5.0
    assert onset.disturbance_force[1] == pytest.approx(expected, rel=0.02)
    peak = max(abs(t.load_force[1]) for t in tr)
    assert peak == pytest.approx(expected, rel=0.02)
    # After the static→dynamic drop the contact transmits μ_d f_n while sliding.
    assert tr[-1].gross_slip and tr[-1].load_force[1] == pytest.approx(0.36 * 5.0, rel=0.02)
    assert tr[-1].slip_direction_rad == pytest.approx(math.pi / 2, abs=1e-6)


def test_torque_ramp_peaks_at_pure_torque_limit_about_the_geometric_median():
    # Tilted face: pressure rising along x, so the COR (weighted geometric median)
    # is not the centre of pressure; the object is free and finds it itself.
    contact = {"model": "offset", "footprint": "rect", "half_size_m": [7.5e-3, 7.5e-3],
               "slope_per_m": [130.0, 0.0], "moves_with_object": False,
               "stiffness_N_per_m3": 3e8}
    scene = make_scene(contact=contact, duration=0.5, step_us=500, damping=(0.0, 0.01),
                       segments=[{"kind": "ramp", "duration_s": 0.5, "torque_Nm": 0.02}])
    sim = Simulator(scene)
    phi = sim.taxel_state().phi
    tr = truths(sim)
    limit, median = pure_torque_limit(phi, scene.pad.positions, MU)
    cop = (phi @ scene.pad.positions) / phi.sum()
    assert abs(median[0] - cop[0]) > 3e-4  # the check is not trivial
    peak = max(abs(t.load_torque) for t in tr)
    assert peak == pytest.approx(limit, rel=0.02)
    onset = next(t for t in tr if t.gross_slip)
    assert abs(onset.load_torque) == pytest.approx(limit, rel=0.02)
    assert onset.cor is not None
    assert np.hypot(*(np.array(onset.cor) - median)) < 0.25 * scene.pad.pitch_m


def test_torque_peak_lies_between_dynamic_and_static_limits_when_mu_d_lt_mu_s():
    scene = make_scene(contact={"model": "flat", "mu_d": 0.36}, duration=0.5,
                       damping=(0.0, 0.01),
                       segments=[{"kind": "ramp", "duration_s": 0.5, "torque_Nm": 0.03}])
    sim = Simulator(scene)
    phi = sim.taxel_state().phi
    peak = max(abs(t.load_torque) for t in truths(sim))
    static, _ = pure_torque_limit(phi, scene.pad.positions, MU)
    assert 0.36 / MU * static < peak < static


def test_hertz_torque_limit_scales_as_fn_to_four_thirds():
    forces = np.array([2.5, 5.0, 10.0, 20.0])
    peaks = []
    for f_n in forces:
        expected = MU * 3 * math.pi / 16 * 5e-3 * (f_n / 5.0) ** (1 / 3) * f_n
        # A stiff, thin rubber (the core under the Hertzian peak pressure must reach its
        # cap within a small twist); rotation about the contact centre only.
        scene = make_scene(contact={"model": "hertz", "a_ref_m": 5e-3, "f_ref_N": 5.0,
                                    "stiffness_N_per_m3": 1e9},
                           free=("theta",), f_n=f_n, duration=0.4, damping=(0.0, 0.005),
                           segments=[{"kind": "ramp", "duration_s": 0.4,
                                      "torque_Nm": 1.6 * expected}])
        sim = Simulator(scene)
        phi = sim.taxel_state().phi
        peak = max(abs(t.load_torque) for t in truths(sim))
        limit, _ = pure_torque_limit(phi, scene.pad.positions, MU)
        assert peak == pytest.approx(limit, rel=0.02)
        # Sub-taxel sampling keeps the discrete limit near the continuum (3π/16) μ f_n a.
        assert limit == pytest.approx(expected, rel=0.05)
        peaks.append(peak)
    slope = np.polyfit(np.log(forces), np.log(peaks), 1)[0]
    assert slope == pytest.approx(4 / 3, rel=0.03)


def test_hertz_contact_slips_at_the_edges_before_gross_slip():
    scene = make_scene(contact={"model": "hertz", "mu_d": 0.36},
                       segments=[{"kind": "ramp", "duration_s": 1.0, "force_N": [3.0, 0.0]}])
    sim = Simulator(scene)
    pos = scene.pad.positions
    partial = None
    for sample in sim:
        if isinstance(sample, Truth) and 0.2 < sample.slip_fraction < 0.8:
            partial = sim.taxel_state()
            break
    assert partial is not None, "no partial-slip state before gross slip"
    r = np.hypot(pos[:, 0], pos[:, 1])
    in_contact = partial.phi > 0
    slipping = r[in_contact & partial.sliding]
    sticking = r[in_contact & ~partial.sliding]
    assert slipping.min() > sticking.max() - 1e-9  # an annulus slips, the core sticks


def test_stick_slip_under_a_constant_speed_drag():
    scene = make_scene(contact={"model": "flat", "mu_d": 0.30, "slip_weakening_m": 2e-5},
                       free=("x",), mode="drag", duration=3.0,
                       segments=[{"kind": "ramp", "duration_s": 3.0, "position_m": [6e-3, 0.0]}])
    tr = truths(Simulator(scene))
    flags = np.array([t.gross_slip for t in tr])
    episodes = int(np.sum(flags[1:] & ~flags[:-1]))
    assert episodes >= 3
    load = np.array([t.load_force[0] for t in tr])
    assert load.max() == pytest.approx(MU * 5.0, rel=0.02)
    assert load[len(load) // 2:].min() < 0.9 * MU * 5.0  # drops after each release


def test_object_resticks_and_holds_after_the_load_drops():
    # Slide at 3 N > μ_d f_n, then drop the load to 1 N < μ_d f_n: the object must
    # stop and stay, friction now opposing the remaining load (the re-stuck bristles
    # keep the deflection of the slip, along the slip velocity).
    scene = make_scene(contact={"model": "flat", "mu_d": 0.36}, free=("x",), duration=0.6,
                       damping=(200.0, 0.0),
                       segments=[{"kind": "step", "duration_s": 0.2, "force_N": [3.0, 0.0]},
                                 {"kind": "step", "duration_s": 0.4, "force_N": [1.0, 0.0]}])
    tr = truths(Simulator(scene))
    assert tr[150].gross_slip and tr[150].vx > 1e-3
    late = tr[300:]
    assert all(not t.gross_slip and t.vx > -1e-6 for t in late)
    assert abs(late[-1].vx) < 1e-6
    assert late[-1].load_force[0] == pytest.approx(1.0, rel=1e-3)
    # From the deflection at the slip force (1.8 N) the contact relaxes to the 1 N
    # load: the object springs back a little, never forward (the bristle was
    # deflected along the slip, not against it).
    arrest = next(t for t in tr[200:] if not t.gross_slip)
    assert late[-1].x <= arrest.x + 1e-7


def test_gross_slip_of_a_coulomb_contact_carries_a_load_on_its_limit_surface():
    # With mu_d = mu_s, gross slip (at least 95 % of the friction capacity slipping) means
    # the transmitted load lies on the limit surface: gamma >= 0.95 by the exact limit set
    # of the true pressure. The shipped default scene's sine, after its first slips, holds
    # the contact near its capacity; at a 1 ms step its taxels then switch between stick
    # and slip every step, slipping ones transmitting 56-95 % of their cap: counted at
    # their full cap, single steps read as gross slip at gamma 0.79-0.89.
    path = Path(slipstack.launch.__file__).parent / "scenes" / "default.toml"
    scene = with_rig_material(load_scene(path), "coulomb")
    scene = dataclasses.replace(scene, duration_s=7.5, ft=dataclasses.replace(scene.ft, enabled=False),
                                tactile=dataclasses.replace(scene.tactile, enabled=False))
    pressure = PressureModel(scene.contact, scene.pad, scene.object.pose)
    gammas = [load_factor(pressure.phi_uncached(t.f_n_applied, complex(t.x, t.y), t.theta), scene.pad.positions,
                          t.load_force, t.load_torque, scene.contact.mu_s).gamma
              for t in truths(Simulator(scene)) if t.gross_slip]
    assert len(gammas) > 1000  # the slips of the ramp and the first sine period
    # the per-taxel friction spread (2 %) moves gamma by a few tenths of a per cent
    assert min(gammas) >= GROSS_SLIP_FRACTION - 0.01


# --------------------------------------------------------------------------- energy


def test_energy_is_only_dissipated_while_sliding():
    scene = make_scene(contact={"model": "hertz", "mu_d": 0.36, "mu_spread": 0.05},
                       duration=0.6, damping=(50.0, 0.01),
                       segments=[{"kind": "ramp", "duration_s": 0.3, "force_N": [2.5, 1.0],
                                  "torque_Nm": 0.004},
                                 {"kind": "sine", "duration_s": 0.3, "amplitude_force_N": [0.5, 0.5],
                                  "frequency_hz": 10.0}])
    tr = truths(Simulator(scene))
    assert any(t.gross_slip for t in tr) and any(not t.gross_slip for t in tr)
    energy = np.array([t.energy_J for t in tr])
    work = np.array([t.work_J for t in tr])
    dissipated = np.diff(work) - np.diff(energy)  # per step, ≥ 0
    tol = 1e-12 + 1e-9 * np.abs(energy[1:])
    assert np.all(dissipated >= -tol)
    assert dissipated.sum() > 0.5 * work[-1]


# --------------------------------------------------------------------------- determinism


def _streams(seed: int):
    scene = make_scene(contact={"model": "hertz", "mu_d": 0.36, "mu_spread": 0.05},
                       duration=0.3, seed=seed, sensors=True,
                       segments=[{"kind": "ramp", "duration_s": 0.3, "force_N": [3.0, 0.5]}])
    out = list(Simulator(scene))
    return [s for s in out if isinstance(s, Truth)], [s for s in out if not isinstance(s, Truth)]


def test_same_seed_gives_bit_identical_truth_and_sensors():
    t1, s1 = _streams(7)
    t2, s2 = _streams(7)
    assert t1 == t2  # dataclass equality: every float bit-identical
    assert len(s1) == len(s2)
    for a, b in zip(s1, s2):
        fields = ("counts",) if hasattr(a, "counts") else ("force_n", "torque_nm")
        assert all(np.array_equal(getattr(a, f), getattr(b, f)) for f in fields)
    t3, _ = _streams(8)
    assert t1 != t3


# --------------------------------------------------------------------------- kinematics


def test_constrained_dofs_are_not_integrated():
    scene = make_scene(contact={"model": "flat", "mu_d": 0.36}, free=("x",), duration=0.3,
                       segments=[{"kind": "step", "duration_s": 0.3, "force_N": [3.0, 2.0],
                                  "torque_Nm": 0.05}])
    tr = truths(Simulator(scene))
    assert tr[-1].x > 1e-4
    assert all(t.y == 0.0 and t.theta == 0.0 and t.vy == 0.0 and t.omega == 0.0 for t in tr)


def test_pivot_rig_rotates_about_the_known_cor():
    scene = make_scene(contact={"model": "flat", "mu_d": 0.36}, free=("theta",), duration=0.3,
                       dof={"free": ["theta"], "pivot_m": [4e-3, 2e-3]},
                       segments=[{"kind": "step", "duration_s": 0.3, "torque_Nm": 0.05}])
    tr = truths(Simulator(scene))
    moving = [t for t in tr if t.cor is not None]
    assert moving and all(np.allclose(t.cor, (4e-3, 2e-3), atol=1e-12) for t in moving)
    assert tr[-1].gross_slip


def test_step_too_coarse_for_the_stiffness_is_a_config_error():
    with pytest.raises(ConfigError, match="step_us"):
        Simulator(make_scene(contact={"model": "flat", "stiffness_N_per_m3": 1e10},
                             segments=[]))


# --------------------------------------------------------------------------- parts


@pytest.mark.parametrize("model, extra", [
    ("flat", {"footprint": "disc", "radius_m": 4e-3}),
    ("offset", {"footprint": "rect", "slope_per_m": [100.0, -50.0]}),
    ("hertz", {}),
    ("edge", {"angle_rad": 0.3}),
])
def test_pressure_models_conserve_normal_force(model, extra):
    pad = PadGeometry()
    pm = PressureModel(ContactSpec(model=model, **extra), pad, (0.0, 0.0, 0.0))
    for f_n in (0.5, 5.0, 18.0):
        phi = pm.phi(f_n, 0j, 0.0)
        assert phi.min() >= 0.0
        assert phi.sum() == pytest.approx(f_n, rel=1e-12)


def test_hertz_contact_radius_grows_as_cube_root_of_force():
    pad = PadGeometry()
    pm = PressureModel(ContactSpec(model="hertz", a_ref_m=4e-3, f_ref_N=5.0), pad, (0, 0, 0))
    area = [np.count_nonzero(pm.phi(f, 0j, 0.0)) * pad.taxel_area_m2 for f in (2.0, 16.0)]
    # 8× the force → 2× the radius → 4× the area (taxel-counted, coarse).
    assert area[1] / area[0] == pytest.approx(4.0, rel=0.2)


def test_offset_footprint_moves_with_the_object():
    pad = PadGeometry()
    pm = PressureModel(ContactSpec(model="flat", footprint="disc", radius_m=3e-3), pad, (0, 0, 0))
    pos = pad.positions
    phi = pm.phi(5.0, complex(2e-3, -1e-3), 0.0)
    assert (phi @ pos) / 5.0 == pytest.approx([2e-3, -1e-3], abs=2e-4)


def test_contact_off_the_pad_is_a_config_error():
    with pytest.raises(ConfigError, match="centre_m"):
        Simulator(make_scene(contact={"model": "flat", "footprint": "disc",
                                      "radius_m": 1e-3, "centre_m": [0.05, 0.0]}, segments=[]))


def test_finger_actuator_lag_rate_limit_and_saturation():
    act = FingerActuator(FingerSpec(f_initial_N=0.0, bandwidth_hz=10.0, rate_N_per_s=1e6,
                                    f_max_N=10.0))
    act.command(4.0)
    tau = 1 / (2 * math.pi * 10.0)
    f = [act.step(1e-4) for _ in range(round(tau / 1e-4))][-1]
    assert f == pytest.approx(4.0 * (1 - math.exp(-1)), rel=1e-3)
    slow = FingerActuator(FingerSpec(f_initial_N=0.0, bandwidth_hz=1e3, rate_N_per_s=20.0,
                                     f_max_N=10.0))
    slow.command(50.0)  # saturates at f_max
    assert slow.command_N == 10.0
    assert [slow.step(0.01) for _ in range(10)][-1] == pytest.approx(2.0)
    assert slow.command(float("nan")) is False and slow.rejected == 1 and slow.command_N == 10.0
    assert slow.command(4.0) is True and slow.command_N == 4.0
    assert slow.command(-3.0) is True and slow.command_N == 0.0  # clipped to 0 N, not refused


def test_finger_actuator_releases_no_faster_than_its_rate_and_lags_small_steps():
    act = FingerActuator(FingerSpec(f_initial_N=8.0, bandwidth_hz=1e3, rate_N_per_s=20.0, f_max_N=10.0))
    act.command(2.0)
    assert act.step(0.01) == pytest.approx(7.8)  # down at 20 N/s, never a jump to the command
    lag = FingerActuator(FingerSpec(f_initial_N=1.0, bandwidth_hz=10.0, rate_N_per_s=1e6, f_max_N=10.0))
    lag.command(1.5)  # half a newton above: the first-order lag, not a snap to the command
    assert lag.step(1e-3) == pytest.approx(1.0 + 0.5 * (1 - math.exp(-2 * math.pi * 10.0 * 1e-3)), rel=1e-9)


def test_disturbance_profile_segments():
    prof = Profile((Segment("ramp", 1.0, target=(2.0, 0.0, 0.1)),
                    Segment("hold", 1.0),
                    Segment("sine", 1.0, amplitude=(1.0, 0.0, 0.0), frequency_hz=1.0),
                    Segment("step", 1.0, target=(0.0, 1.0, 0.0))))
    assert prof.value(0.5) == pytest.approx((1.0, 0.0, 0.05))
    assert prof.value(1.5) == pytest.approx((2.0, 0.0, 0.1))
    assert prof.value(2.25) == pytest.approx((3.0, 0.0, 0.1))
    assert prof.value(3.5) == pytest.approx((0.0, 1.0, 0.0))
    assert prof.value(99.0) == pytest.approx((0.0, 1.0, 0.0))


# --------------------------------------------------------------------------- sensors


def _quiet(scene, **ft):
    import dataclasses
    return dataclasses.replace(scene, ft=dataclasses.replace(
        scene.ft, noise_force_N=0.0, noise_torque_Nm=0.0, resolution_force_N=0.0,
        resolution_torque_Nm=0.0, **ft))


def test_ft_reading_maps_back_to_the_true_contact_load():
    scene = make_scene(contact={"model": "hertz", "centre_m": [2e-3, -1e-3]}, duration=0.2,
                       sensors=True, segments=[{"kind": "ramp", "duration_s": 0.2,
                                                "force_N": [1.0, -0.6], "torque_Nm": 0.002}])
    scene = _quiet(scene, yaw_rad=0.4, origin_m=(1e-3, 2e-3, -0.02))
    sim = Simulator(scene)
    pairs = {}
    for s in sim:
        pairs.setdefault(s.stamp_ns, {})[type(s).__name__] = s
    checked = 0
    for group in pairs.values():
        if "FtSample" in group and "Truth" in group:
            ft, truth = group["FtSample"], group["Truth"]
            fx, fy, tau, f_n = sim.ft.pad_load(ft.force_n, ft.torque_nm)
            assert (fx, fy) == pytest.approx(truth.load_force, abs=1e-12)
            assert tau == pytest.approx(truth.load_torque, abs=1e-12)
            assert f_n == pytest.approx(5.0, rel=1e-12)
            checked += 1
    assert checked > 100


def test_ft_sees_moments_of_an_offset_sensor_and_quantises():
    scene = make_scene(contact={"model": "flat"}, sensors=True, segments=[])
    sim = Simulator(scene)
    phi = sim.taxel_state().phi
    force, torque = sim.ft.ideal_wrench(phi, 5.0, complex(2.0, 0.0), 0.0)
    # Uniform pressure (no moment about the pad origin) and f_x = 2 N, 20 mm in front
    # of the sensor origin: τ_y = −s_z f_x = +0.04 N·m; f_z = −f_n.
    assert force == pytest.approx([2.0, 0.0, -5.0])
    assert torque == pytest.approx([0.0, 0.04, 0.0], abs=1e-12)
    sample = sim.ft.measure(0, 0, phi, 5.0, complex(2.0, 0.0), 0.0)
    res = scene.ft.resolution_force_N
    assert np.allclose(sample.force_n / res, np.round(sample.force_n / res))
    assert not sample.saturated
    big = sim.ft.measure(0, 1, phi, 5.0, complex(100.0, 0.0), 0.0)
    assert big.saturated and big.force_n[0] == scene.ft.range_force_N[0]


def test_tactile_counts_follow_the_rubber_curve_with_dead_taxels():
    scene = make_scene(contact={"model": "hertz"}, sensors=True, segments=[],
                       )
    import dataclasses
    scene = dataclasses.replace(scene, tactile=dataclasses.replace(
        scene.tactile, noise_counts=0.0, gain_spread=0.0, dead_taxels=((7, 7),)))
    sim = Simulator(scene)
    frame = next(s for s in sim.step_until(0) if hasattr(s, "counts"))
    assert frame.counts.dtype == np.uint16 and frame.counts.shape == (16, 16)
    assert frame.counts[7, 7] == 0
    phi = sim.taxel_state().phi
    expected = np.rint(sim.tactile.nominal_counts(phi / scene.pad.taxel_area_m2))
    alive = np.ones(256, bool)
    alive[7 * 16 + 7] = False
    assert np.array_equal(frame.counts.ravel()[alive], expected[alive])
    p, c = sim.tactile.calibration_table(17)
    assert np.all(np.diff(p) > 0) and np.all(np.diff(c) > 0) and p[0] == 0.0
    assert np.allclose(sim.tactile.nominal_counts(p), c)
    assert sim.tactile.nominal_counts(np.array([1e7]))[0] == pytest.approx(4095.0)
