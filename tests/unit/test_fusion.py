"""Fusion of tactile pressure and F/T wrench (docs/math.md §2) and the sensor-to-pad transform."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from numba import config as numba_config

from slipstack.lib.errors import ConfigError
from slipstack.lib.fusion import FusionThresholds, SensorMount, fuse, pressure_shape, wrench_to_pad
from slipstack.lib.pad import PadGeometry
from slipstack.lib.status import SolverStatus

PAD = PadGeometry(4, 4, 1e-3)


def test_wrench_to_pad_by_hand():
    # sensor 1 cm below the pad, same axes: a 1 N push along x gives −0.01 N·m about y
    f, t = wrench_to_pad([1.0, 0, 0], [0, 0, 0], np.eye(3), [0, 0, -0.01])
    assert f == pytest.approx([1, 0, 0]) and t == pytest.approx([0, -0.01, 0])
    # sensor turned +90° about z and 1 cm along +x of the pad origin
    R = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    f, t = wrench_to_pad([1.0, 0, -2], [0, 0, 0.2], R, [0.01, 0, 0])
    assert f == pytest.approx([0, 1, -2])
    # τ_F = R τ_S + p × f = (0,0,0.2) + (0.01,0,0)×(0,1,−2) = (0, 0.02, 0.21)
    assert t == pytest.approx([0, 0.02, 0.21])


def test_fuse_spreads_the_normal_force_over_the_pressure_shape():
    p = np.zeros(16)
    p[[5, 6]] = [100.0, 300.0]  # Pa
    res = fuse(p, [0.1, -0.2, -2.0], [0, 0, 3e-3], PAD, tactile_stamp_ns=1000, wrench_stamp_ns=1500)
    assert res.status is SolverStatus.OK
    assert res.f_n == pytest.approx(2.0) and res.phi[[5, 6]] == pytest.approx([0.5, 1.5])
    assert res.f_t == pytest.approx([0.1, -0.2]) and res.tau == 3e-3
    assert res.cop == pytest.approx(0.25 * PAD.positions[5] + 0.75 * PAD.positions[6])
    assert res.n_contact == 2 and res.contact_area_m2 == pytest.approx(2e-6)
    assert res.stamp_offset_ns == 500
    with pytest.raises(ValueError):
        res.phi[0] = 1.0  # read-only


def test_fuse_clips_and_counts_bad_taxels():
    p = np.full(16, 10.0)
    p[0], p[1], p[2] = np.nan, np.inf, -5.0
    res = fuse(p, [0, 0, -1.3], [0, 0, 0], PAD)
    assert res.status is SolverStatus.CLIPPED_INPUT and res.status.usable
    assert (res.n_nonfinite, res.n_negative, res.n_contact) == (2, 1, 13)
    assert np.all(np.isfinite(res.phi)) and res.phi[:3].sum() == 0 and res.f_n == pytest.approx(1.3)


def test_fuse_no_contact_and_invalid_input():
    p = np.full(16, 10.0)
    assert fuse(p, [0, 0, 0.5], [0, 0, 0], PAD).status is SolverStatus.NO_CONTACT  # pulling
    assert fuse(np.zeros(16), [0, 0, -1], [0, 0, 0], PAD).status is SolverStatus.NO_CONTACT
    th = FusionThresholds(noise_floor_pa=20.0)
    assert fuse(p, [0, 0, -1], [0, 0, 0], PAD, th).status is SolverStatus.NO_CONTACT
    assert fuse(p, [np.nan, 0, -1], [0, 0, 0], PAD).status is SolverStatus.INVALID_INPUT
    assert fuse(np.ones(9), [0, 0, -1], [0, 0, 0], PAD).status is SolverStatus.INVALID_INPUT
    res = fuse(p, [0, 0, 0.5], [0, 0, 0], PAD)
    assert res.f_n == 0.0 and not res.phi.any()


def test_fuse_with_a_sensor_mount_and_saturation():
    mount = SensorMount(R_FS=((1, 0, 0), (0, -1, 0), (0, 0, -1)), p_SF=(0, 0, -0.02))  # flipped sensor
    p = np.full(16, 10.0)
    sat = np.zeros(16, dtype=bool)
    sat[3] = True
    res = fuse(p, [0.5, 0, 2.0], [0, 0, 0], PAD, mount=mount, saturated=sat)
    assert res.f_n == pytest.approx(2.0) and res.f_t == pytest.approx([0.5, 0]) and res.n_saturated == 1


def test_configuration_errors_say_what_to_fix():
    with pytest.raises(ConfigError, match="rotation"):
        SensorMount(R_FS=((2, 0, 0), (0, 1, 0), (0, 0, 1)))
    with pytest.raises(ConfigError, match="noise_floor_pa"):
        FusionThresholds(noise_floor_pa=-1.0)


@pytest.mark.parametrize("pressure_pa", [2.2e-313, 5e306])
def test_pressures_at_the_ends_of_the_float_range_still_share_the_normal_force(pressure_pa):
    # Found by hypothesis: Σw underflowed (φ = w·f_n/Σw became inf) or overflowed (φ = 0).
    pad = PadGeometry(6, 6, 1e-3)
    fr = fuse(np.full(36, pressure_pa), [0.1, 0.0, -1.0], [0.0, 0.0, 1e-4], pad, FusionThresholds(0.0, 0.0, 0.0))
    assert fr.status is SolverStatus.OK
    np.testing.assert_allclose(fr.phi, 1.0 / 36, rtol=1e-12)
    assert fr.f_n == pytest.approx(1.0, rel=1e-12)


def test_one_pressure_shape_serves_every_wrench_paired_with_its_frame():
    from slipstack.lib.fusion import fuse_shape, pressure_shape

    pad = PadGeometry(4, 4, 1e-3)
    pressure = np.zeros(16)
    pressure[[5, 6, 9]] = [1e4, 3e4, -5.0]  # one negative taxel: clipped and counted once
    shape = pressure_shape(pressure, pad, FusionThresholds(noise_floor_pa=100.0))
    assert shape.n_negative == 1 and shape.mask.sum() == 2
    for f_n in (1.0, 4.0):
        fr = fuse_shape(shape, [0.2, 0.0, -f_n], [0.0, 0.0, 0.0], pad, FusionThresholds(noise_floor_pa=100.0))
        assert fr.status is SolverStatus.CLIPPED_INPUT and fr.n_negative == 1
        assert fr.phi[5] == pytest.approx(0.25 * f_n) and fr.phi[6] == pytest.approx(0.75 * f_n)
        np.testing.assert_allclose(fr.cop, 0.25 * pad.positions[5] + 0.75 * pad.positions[6], rtol=1e-12)
    whole = fuse(pressure, [0.2, 0.0, -4.0], [0.0, 0.0, 0.0], pad, FusionThresholds(noise_floor_pa=100.0))
    np.testing.assert_array_equal(whole.phi, fr.phi)


def _rotation(axis, angle_rad: float) -> np.ndarray:
    """Rodrigues' formula, written out here (not the code under test)."""
    k = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle_rad) * K + (1 - np.cos(angle_rad)) * K @ K


def test_wrench_to_pad_in_general_position_matches_the_textbook_transform():
    # Every component non-zero: torque about F's origin = R τ_S + p_SF × (R f_S) (np.cross).
    R = _rotation([0.3, -0.5, 0.8], 0.7)
    f_S, t_S, p = np.array([1.5, -2.0, 0.7]), np.array([0.03, 0.01, -0.02]), np.array([0.004, -0.006, 0.011])
    f, t = wrench_to_pad(f_S, t_S, R, p)
    np.testing.assert_allclose(f, R @ f_S, rtol=1e-12)
    np.testing.assert_allclose(t, R @ t_S + np.cross(p, R @ f_S), rtol=1e-12)


def test_default_mount_and_thresholds_change_nothing():
    # Defaults: the sensor frame is the pad frame, and any positive pressure and force is contact.
    mount = SensorMount()
    assert np.array_equal(mount.R_FS, np.eye(3)) and mount.p_SF == (0.0, 0.0, 0.0)
    assert FusionThresholds() == FusionThresholds(0.0, 0.0, 0.0)
    p = np.zeros(16)
    p[7] = 0.5  # Pa: above the default noise floor 0 and pressure sum 0
    plain = fuse(p, [0.1, 0.2, -0.5], [0.01, 0.02, 0.03], PAD)
    mounted = fuse(p, [0.1, 0.2, -0.5], [0.01, 0.02, 0.03], PAD, mount=mount)
    assert plain.status is SolverStatus.OK and plain.n_contact == 1 and plain.f_n == 0.5
    for a, b in ((plain.f_t, mounted.f_t), (plain.phi, mounted.phi), (plain.cop, mounted.cop)):
        np.testing.assert_array_equal(a, b)
    assert plain.tau == mounted.tau == 0.03


def test_a_rotation_within_the_documented_tolerance_is_accepted():
    # Orthonormal to 1e-9 (a rotation read from a calibration file with ~11 digits):
    # its determinant is 1 - 9e-11, below 1 yet a proper rotation.
    R = _rotation([0.0, 0.0, 1.0], 0.3) * (1.0 - 3e-11)
    assert np.linalg.det(R) < 1.0
    mount = SensorMount(R_FS=tuple(map(tuple, R)))
    assert mount.R_FS[0][0] == R[0, 0]


@pytest.mark.parametrize("R_FS, p_SF", [
    (((1.001, 0, 0), (0, 1.001, 0), (0, 0, 1.001)), (0, 0, 0)),    # a scaled rotation
    (((1, 0), (0, 1)), (0, 0, 0)),                                # not 3x3
    (((1, 0, 0), (0, 1, 0), (0, 0, float("nan"))), (0, 0, 0)),    # not finite
    (((1, 0, 0), (0, 1, 0), (0, 0, -1)), (0, 0, 0)),              # a reflection (det -1)
    (((1, 0, 0), (0, 1, 0), (0, 0, 1)), (0, 0)),                  # offset not 3 numbers
    (((1, 0, 0), (0, 1, 0), (0, 0, 1)), (0, 0, float("inf"))),    # offset not finite
])
def test_every_bad_mount_is_a_config_error(R_FS, p_SF):
    with pytest.raises(ConfigError, match="sensor mount"):
        SensorMount(R_FS=R_FS, p_SF=p_SF)


def test_a_frame_of_the_wrong_size_counts_no_taxel_as_clipped():
    from slipstack.lib.fusion import pressure_shape

    shape = pressure_shape(np.full(9, np.nan), PAD)
    assert not shape.valid and shape.shape_sum == 0.0 and shape.pressure_sum_pa == 0.0 and not shape.mask.any()
    assert np.array_equal(shape.cop, [0.0, 0.0]) and np.array_equal(shape.shape, np.zeros(16))
    assert (shape.n_nonfinite, shape.n_negative, shape.n_saturated) == (0, 0, 0)
    res = fuse(np.full(9, np.nan), [0, 0, -1], [0, 0, 0], PAD)
    assert res.status is SolverStatus.INVALID_INPUT
    assert (res.n_nonfinite, res.n_negative, res.n_saturated, res.n_contact) == (0, 0, 0, 0)
    assert res.f_t.tolist() == [0.0, 0.0] and res.tau == 0.0 and res.f_n == 0.0  # no load from a bad frame
    assert res.cop.tolist() == [0.0, 0.0] and res.phi.tolist() == [0.0] * 16


def test_an_empty_frame_has_a_zero_shape_not_nan():
    from slipstack.lib.fusion import pressure_shape

    for frame in (np.zeros(16), np.full(16, -3.0)):
        shape = pressure_shape(frame, PAD)
        assert shape.valid and shape.shape_sum == 0.0 and shape.pressure_sum_pa == 0.0
        assert np.array_equal(shape.shape, np.zeros(16)) and np.array_equal(shape.cop, [0.0, 0.0])
        assert fuse(frame, [0, 0, -1], [0, 0, 0], PAD).status is SolverStatus.NO_CONTACT


def test_a_saturation_mask_of_the_wrong_size_is_ignored():
    p = np.full(16, 10.0)
    assert fuse(p, [0, 0, -1], [0, 0, 0], PAD).n_saturated == 0
    assert fuse(p, [0, 0, -1], [0, 0, 0], PAD, saturated=np.ones(9, dtype=bool)).n_saturated == 0
    assert fuse(p, [0, 0, -1], [0, 0, 0], PAD, saturated=np.ones(16, dtype=bool)).n_saturated == 16


def test_thresholds_are_strict_and_one_stamp_gives_no_offset():
    p = np.full(16, 10.0)  # Pa; sum 160 Pa
    th = FusionThresholds(min_normal_force_n=1.0)
    below = fuse(p, [0.1, -0.2, -1.0], [0, 0, 3e-3], PAD, th)
    assert below.status is SolverStatus.NO_CONTACT  # not above
    assert below.f_t.tolist() == [0.1, -0.2] and below.tau == 3e-3  # the load is still reported
    assert fuse(p, [0, 0, -1.000001], [0, 0, 0], PAD, th).status is SolverStatus.OK
    th = FusionThresholds(min_pressure_sum_pa=160.0)
    assert fuse(p, [0, 0, -1.0], [0, 0, 0], PAD, th).status is SolverStatus.NO_CONTACT
    assert fuse(p, [0, 0, -1.0], [0, 0, 0], PAD, FusionThresholds(min_pressure_sum_pa=159.9)).status is SolverStatus.OK
    assert fuse(p, [0, 0, -1.0], [0, 0, 0], PAD, FusionThresholds(noise_floor_pa=10.0)).n_contact == 0
    assert fuse(p, [0, 0, -1], [0, 0, 0], PAD, tactile_stamp_ns=1000).stamp_offset_ns is None
    assert fuse(p, [0, 0, -1], [0, 0, 0], PAD, wrench_stamp_ns=1000).stamp_offset_ns is None
    assert fuse(p, [0, 0, -1], [0, 0, 0], PAD, tactile_stamp_ns=1500, wrench_stamp_ns=1000).stamp_offset_ns == -500


@pytest.mark.skipif(numba_config.DISABLE_JIT, reason="the kernel interpreted is numpy's scalar maths, which warns")
@pytest.mark.parametrize("pressure_pa, total", [(5e306, math.inf), (2e306, 36 * 2e306), (1e4, 36 * 1e4)])
def test_a_frames_pressure_sum_overflows_quietly(pressure_pa, total):
    # The sum is only compared with a threshold: an overflow to inf is expected, not warned about.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        shape = pressure_shape(np.full(36, pressure_pa), PadGeometry(6, 6, 1e-3), FusionThresholds(0.0, 0.0, 0.0))
    assert shape.pressure_sum_pa == pytest.approx(total, rel=1e-12)
    assert shape.shape_sum == pytest.approx(36.0, rel=1e-12)
