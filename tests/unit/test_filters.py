"""lib/filters.py (first-order low-pass) and lib/frames.py (rpy rotations)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.spatial.transform import Rotation

from slipstack.lib.filters import LowPass, lowpass_alpha, lowpass_step
from slipstack.lib.frames import rotation_rpy


def test_alpha_is_the_exact_zero_order_hold_factor():
    # τ = 1/(2π·10 Hz); after dt = τ the step response is 1 − 1/e.
    tau = 1.0 / (2.0 * math.pi * 10.0)
    assert lowpass_alpha(tau, 10.0) == pytest.approx(1.0 - math.exp(-1.0), rel=1e-12)
    assert lowpass_alpha(1e-3, 0.0) == 1.0  # off: pass-through
    assert lowpass_alpha(0.0, 10.0) == 0.0  # no time passed: hold


def test_step_response_is_independent_of_the_sample_rate():
    # Reaching t = 50 ms in 10 steps of 5 ms or 50 steps of 1 ms gives the same value.
    def run(dt, n):
        y = np.zeros(2)
        for _ in range(n):
            y = lowpass_step(y, [1.0, -2.0], dt, 10.0)
        return y

    expected = (1.0 - math.exp(-2.0 * math.pi * 10.0 * 0.05)) * np.array([1.0, -2.0])
    np.testing.assert_allclose(run(0.005, 10), expected, rtol=1e-12)
    np.testing.assert_allclose(run(0.001, 50), expected, rtol=1e-12)


def test_stateful_filter_passes_the_first_sample_and_skips_non_finite_input():
    f = LowPass(10.0)
    np.testing.assert_array_equal(f.step([3.0, 4.0], 0.01), [3.0, 4.0])
    bad = f.step([np.nan, 0.0], 0.01)
    assert np.isnan(bad[0]) and f.state.tolist() == [3.0, 4.0]
    a = lowpass_alpha(0.01, 10.0)
    np.testing.assert_allclose(f.step([5.0, 4.0], 0.01), [3.0 + 2.0 * a, 4.0])
    f.reset()
    np.testing.assert_array_equal(f.step([-1.0, -1.0], 0.01), [-1.0, -1.0])


@settings(max_examples=100, deadline=None)
@given(st.floats(-10, 10), st.floats(1e-5, 1.0), st.floats(0.0, 1e4), st.floats(-10, 10))
def test_output_stays_between_previous_output_and_input(y0, dt, fc, x):
    y = float(lowpass_step(np.array([y0]), np.array([x]), dt, fc)[0])
    assert min(y0, x) - 1e-12 <= y <= max(y0, x) + 1e-12


def test_pure_yaw_turns_sensor_x_towards_pad_y():
    np.testing.assert_allclose(rotation_rpy(0.0, 0.0, math.pi / 2) @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)


@settings(max_examples=100, deadline=None)
@given(st.floats(-math.pi, math.pi), st.floats(-math.pi / 2, math.pi / 2), st.floats(-math.pi, math.pi))
def test_rpy_matches_fixed_axis_xyz_of_scipy(roll, pitch, yaw):
    expected = Rotation.from_euler("xyz", [roll, pitch, yaw]).as_matrix()  # extrinsic x, y, z
    np.testing.assert_allclose(rotation_rpy(roll, pitch, yaw), expected, atol=1e-12)
