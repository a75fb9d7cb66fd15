"""The compiled pressure sampling (hertz, flat, offset) against the numpy code it replaced.

The kernels must give the shapes numpy gave, bit for bit: their per-cell mean sums in
numpy's pairwise order. Hand-checked values, then hypothesis on random contacts.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, strategies as st
from hypothesis.extra import numpy as hnp

from slipstack.lib.errors import ConfigError
from slipstack.lib.pad import PadGeometry
from slipstack.lib.rig.contact import PressureModel
from slipstack.lib.rig.pressure_kernels import (
    FOOTPRINT_DISC, FOOTPRINT_PAD, FOOTPRINT_RECT, MAX_POINTS_PER_CELL, footprint_cell_means, hertz_cell_means,
    numpy_pairwise_sum)
from slipstack.lib.rig.scene import MAX_SUBSAMPLES, ContactSpec


def _reference_hertz_means(points: np.ndarray, centre: complex, a: float) -> np.ndarray:
    """PressureModel._pressure(...).mean(axis=1) of b737fcd for the hertz model."""
    d = points - centre
    with np.errstate(divide="ignore"):  # a² may underflow to 0: r² = inf, no pressure
        r2 = (d.real**2 + d.imag**2) / (a * a) if a > 0 else np.full(d.shape, np.inf)
    return np.sqrt(np.clip(1.0 - r2, 0.0, None)).mean(axis=1)


def test_pairwise_sum_known_values():
    assert numpy_pairwise_sum(np.array([1.0, 2.0, 3.0]), 3) == 6.0
    assert numpy_pairwise_sum(np.arange(16.0), 16) == 120.0
    assert numpy_pairwise_sum(np.zeros(0), 0) == 0.0
    # eight lanes (1e16 + 1 rounds back to 1e16, 1 + 1 = 2 in the other seven): 1e16 + 14,
    # where left to right every 1 would be lost
    run = np.array([1e16] + [1.0] * 15)
    assert numpy_pairwise_sum(run, 16) == run.sum() == 1e16 + 14.0


def test_hertz_cell_means_known_values():
    points = np.array([[0j, 0.5e-3 + 0j], [2e-3 + 0j, 1e-3j]])
    out = np.empty(2)
    hertz_cell_means(points, 0j, 1e-3, out)  # sqrt(1 − r²/a²): 1 and sqrt(0.75); 0 and 0
    assert out[0] == (1.0 + math.sqrt(0.75)) / 2
    assert out[1] == 0.0
    hertz_cell_means(points, 0j, 0.0, out)  # no radius: no pressure
    np.testing.assert_array_equal(out, [0.0, 0.0])


@given(hnp.arrays(np.float64, st.integers(0, MAX_POINTS_PER_CELL),
                  elements=st.floats(-1e6, 1e6, allow_nan=False, allow_subnormal=False)))
def test_pairwise_sum_is_numpys_sum(a):
    assert numpy_pairwise_sum(a, a.size) == a.sum()


@given(st.integers(1, MAX_SUBSAMPLES), st.floats(-3e-3, 3e-3), st.floats(-3e-3, 3e-3),
       st.floats(0.0, 5e-3), st.integers(1, 6))
def test_hertz_cell_means_match_the_numpy_formula(s, cx, cy, a, n_cells):
    rng = np.random.default_rng(s * 7 + n_cells)
    points = (rng.uniform(-4e-3, 4e-3, (n_cells, s * s)) + 1j * rng.uniform(-4e-3, 4e-3, (n_cells, s * s)))
    out = np.empty(n_cells)
    hertz_cell_means(points, complex(cx, cy), a, out)
    np.testing.assert_array_equal(out, _reference_hertz_means(points, complex(cx, cy), a))


@pytest.mark.parametrize("f_n", [0.0, 0.5, 3.0, 20.0])
def test_pressure_model_hertz_shape_is_the_numpy_formulas(f_n):
    pad = PadGeometry()
    spec = ContactSpec(model="hertz", a_ref_m=3e-3, f_ref_N=5.0, centre_m=(0.4e-3, -0.7e-3))
    model = PressureModel(spec, pad, (0.0, 0.0, 0.0))
    got = model.phi_uncached(f_n, 0j, 0.0)
    a = spec.a_ref_m * (f_n / spec.f_ref_N) ** (1.0 / 3.0)
    s = spec.subsamples
    offs = ((np.arange(s) + 0.5) / s - 0.5) * pad.pitch_m
    centres = pad.positions[:, 0] + 1j * pad.positions[:, 1]
    points = centres[:, None] + (offs[None, :] + 1j * offs[:, None]).ravel()[None, :]
    weights = _reference_hertz_means(points, complex(*spec.centre_m), a)
    total = float(weights.sum())
    expected = f_n * (weights / total) if total > 0 else got  # f_n = 0: no shape to compare
    np.testing.assert_array_equal(got, expected)
    assert got.sum() == pytest.approx(f_n, rel=1e-12)


def test_too_many_subsamples_is_a_clear_error():
    with pytest.raises(ConfigError, match="subsamples"):
        PressureModel(ContactSpec(model="hertz", subsamples=MAX_SUBSAMPLES + 1), PadGeometry(), (0.0, 0.0, 0.0))


def _reference_footprint_means(points, centre, footprint, radius, half_size, slope):
    """PressureModel._pressure(...).mean(axis=1) of 1637698 for the flat (slope None) and offset models."""
    d = points - centre
    if footprint == "pad":
        inside = np.ones(d.shape, dtype=bool)
    elif footprint == "disc":
        inside = np.abs(d) <= radius
    else:
        inside = (np.abs(d.real) <= half_size[0]) & (np.abs(d.imag) <= half_size[1])
    if slope is None:
        return inside.astype(float).mean(axis=1)
    level = slope[0] * d.real + slope[1] * d.imag
    return (inside * np.clip(1.0 + level, 0.0, None)).mean(axis=1)


_CODES = {"pad": FOOTPRINT_PAD, "disc": FOOTPRINT_DISC, "rect": FOOTPRINT_RECT}


def test_footprint_cell_means_known_values():
    points = np.array([[0j, 2e-3 + 0j], [1e-3 + 1e-3j, -3e-3j]])
    out = np.empty(2)
    footprint_cell_means(points, 0j, FOOTPRINT_DISC, 1.5e-3, 0.0, 0.0, False, 0.0, 0.0, 0.0, 0.0, 0.0, out)
    np.testing.assert_array_equal(out, [0.5, 0.5])  # |1+1j| mm = 1.41 mm is inside
    footprint_cell_means(points, 0j, FOOTPRINT_RECT, 0.0, 2e-3, 1e-3, True, 100.0, 0.0, 0.0, 0.0, 0.0, out)
    np.testing.assert_array_equal(out, [(1.0 + 1.2) / 2, 1.1 / 2])  # 1 + 100·x inside, 0 outside
    footprint_cell_means(points, 0j, FOOTPRINT_PAD, 0.0, 0.0, 0.0, True, 0.0, -1000.0, 0.0, 0.0, 0.0, out)
    np.testing.assert_array_equal(out, [1.0, (0.0 + 4.0) / 2])  # 1 − 1000·y, clipped at 0


@given(st.integers(1, MAX_SUBSAMPLES), st.sampled_from(["pad", "disc", "rect"]), st.booleans(),
       st.floats(-3e-3, 3e-3), st.floats(-3e-3, 3e-3), st.floats(0.0, 5e-3), st.floats(0.0, 5e-3),
       st.floats(-500.0, 500.0), st.floats(-500.0, 500.0), st.integers(1, 6))
def test_footprint_cell_means_match_the_numpy_formula(s, footprint, sloped, cx, cy, size, other, sx, sy, n_cells):
    rng = np.random.default_rng(s * 11 + n_cells)
    points = (rng.uniform(-4e-3, 4e-3, (n_cells, s * s)) + 1j * rng.uniform(-4e-3, 4e-3, (n_cells, s * s)))
    out = np.empty(n_cells)
    footprint_cell_means(points, complex(cx, cy), _CODES[footprint], size, size, other, sloped, sx, sy, 0.0, 0.0, 0.0, out)
    want = _reference_footprint_means(points, complex(cx, cy), footprint, size, (size, other),
                                      (sx, sy) if sloped else None)
    np.testing.assert_array_equal(out, want)
