"""The tactile pad's compiled counts against the numpy code they replaced (lib/rig/sensors.py)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, strategies as st
from hypothesis.extra import numpy as hnp

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
