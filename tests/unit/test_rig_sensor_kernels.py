"""The sensors' compiled arithmetic against the numpy and Python code it replaced (lib/rig/sensors.py)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, strategies as st
from hypothesis.extra import numpy as hnp

from slipstack.lib.rig import sensor_kernels as kernels
from slipstack.lib.rig.sensor_kernels import tactile_counts


def _reference_counts(level, full_scale, baseline, noise, alive):
    """TactileSensorModel.measure of 1637698 from its exp on."""
    level = level.copy()
    level *= -full_scale
    level += baseline + full_scale
    if noise is not None:
        level += noise
    np.clip(level, 0.0, full_scale, out=level)
    level *= alive
    with np.errstate(invalid="ignore"):
        return np.rint(level).astype(np.uint16)


@given(n=st.integers(1, 300), data=st.data())
def test_tactile_counts_match_the_numpy_formula(n, data):
    level = data.draw(hnp.arrays(np.float64, n, elements=st.floats(0.0, 1.0)))
    noise = data.draw(st.one_of(st.none(), hnp.arrays(np.float64, n, elements=st.floats(-50.0, 50.0))))
    alive = data.draw(hnp.arrays(bool, n))
    full_scale = float(data.draw(st.sampled_from([4095, 65535, 255])))
    baseline = data.draw(st.sampled_from([0.0, 12.5, 100.0]))
    counts = np.empty(n, dtype=np.uint16)
    tactile_counts(level, full_scale, baseline, np.zeros(0) if noise is None else noise, alive, counts)
    np.testing.assert_array_equal(counts, _reference_counts(level, full_scale, baseline, noise, alive))


def test_tactile_counts_known_values():
    level = np.array([1.0, 0.0, 0.5, 0.0, np.nan])
    counts = np.empty(5, dtype=np.uint16)
    tactile_counts(level, 4095.0, 0.0, np.array([0.0, 10.0, 0.25, 0.0, 0.0]), np.array([True, True, True, False, True]),
                   counts)
    # 0; saturated at full scale; 2047.5 + 0.25 -> 2048; a dead taxel reads 0; NaN -> 0 (numpy's cast)
    np.testing.assert_array_equal(counts, [0, 4095, 2048, 0, 0])


def _reference_reading(phi, px, py, f_n, load_force, load_torque, origin, yaw, bias, sd, res, limit, noise):
    """FtSensorModel.ideal_wrench and measure of 1637698 (numpy dot products, a loop in Python)."""
    fx, fy, fz = load_force.real, load_force.imag, -f_n
    tx, ty, tz = -float(py @ phi), float(px @ phi), load_torque
    sx, sy, sz = origin
    tx -= sy * fz - sz * fy
    ty -= sz * fx - sx * fz
    tz -= sx * fy - sy * fx
    c, s = math.cos(yaw), math.sin(yaw)
    ideal = [c * fx + s * fy, -s * fx + c * fy, fz, c * tx + s * ty, -s * tx + c * ty, tz]
    out, saturated = [], False
    for v, b, sd_, r, lim, z in zip(ideal, bias, sd, res, limit, noise):
        v += b + sd_ * z
        if min(res) > 0.0:
            v = round(v / r) * r
        if abs(v) > lim:
            saturated = True
            v = math.copysign(lim, v)
        out.append(v)
    return ideal, out, saturated


_six = st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6)


@given(n=st.integers(1, 300), data=st.data())
def test_an_ft_reading_matches_the_python_formula(n, data):
    """Moments are loops, not BLAS: the ideal wrench agrees within 1e-12 of its scale
    (a sum of n ≤ 300 products rounds differently by at most ~n·eps of the terms);
    quantised readings agree exactly (a random value lands within 1e-12 of a rounding
    tie with probability ~1e-12), unquantised ones within 1e-12."""
    phi = data.draw(hnp.arrays(np.float64, n, elements=st.floats(0.0, 1.0)))
    px = data.draw(hnp.arrays(np.float64, n, elements=st.floats(-0.01, 0.01)))
    py = data.draw(hnp.arrays(np.float64, n, elements=st.floats(-0.01, 0.01)))
    load_force = complex(data.draw(st.floats(-20.0, 20.0)), data.draw(st.floats(-20.0, 20.0)))
    load_torque = data.draw(st.floats(-0.5, 0.5))
    origin = data.draw(st.lists(st.floats(-0.03, 0.03), min_size=3, max_size=3))
    yaw = data.draw(st.floats(-math.pi, math.pi))
    bias, noise = data.draw(_six), data.draw(_six)
    sd = [data.draw(st.floats(0.0, 0.1))] * 6
    res = data.draw(st.sampled_from([[0.0] * 6, [1 / 32] * 3 + [1 / 2000] * 3]))
    limit = data.draw(st.sampled_from([[100.0] * 6, [10.0] * 3 + [0.1] * 3]))
    f_n = float(phi.sum())
    constants = np.array([*origin, math.cos(yaw), math.sin(yaw), *bias, *sd, *res, *limit])
    ideal, want, want_saturated = _reference_reading(phi, px, py, f_n, load_force, load_torque, origin, yaw,
                                                     bias, sd, res, limit, noise)
    wrench = np.empty(6)
    kernels.ideal_wrench(phi, px, py, f_n, load_force, load_torque, constants, wrench)
    scale = max(abs(v) for v in ideal) + 0.01 * f_n
    np.testing.assert_allclose(wrench, ideal, rtol=0.0, atol=1e-12 * scale)
    force, torque = np.empty(3), np.empty(3)
    saturated = kernels.ft_reading(phi, px, py, f_n, load_force, load_torque, constants, np.array(noise), force,
                                   torque)
    assert saturated == want_saturated
    if res[0] > 0.0:
        np.testing.assert_array_equal(np.concatenate([force, torque]), want)
    else:
        np.testing.assert_allclose(np.concatenate([force, torque]), want, rtol=0.0, atol=1e-12 * (scale + 1.0))
