"""Model errors of identified coefficients, apart from their standard errors (hand-checked)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slipstack.lib.identify import identify_mu
from slipstack.lib.material_fit import beta_from_pressure, interval_half_width, pooled_model

FS = 500.0
F_N = 10.0


def slip_ramp(ratio: np.ndarray, t_on: float) -> dict:
    """Noise-free inputs for identify_mu: constant f_n, the ratio, slip after ``t_on``."""
    t = np.arange(ratio.size) / FS
    return {"t_s": t, "f_n_n": np.full(t.size, F_N), "f_t_n": ratio * F_N,
            "slip_m": np.where(t > t_on + 1e-9, (t - t_on) * 1e-3, 0.0)}


def test_a_ramp_that_bends_over_before_the_onset_has_a_static_model_error() -> None:
    # The ratio rises at 0.5 /s and levels off at 0.488 from sample 488 to the onset at
    # sample 500 (the 12-sample last half of the 50 ms = 25-sample static window is flat).
    # The 25-sample line ends above 0.488, the 12-sample one is flat at 0.488: the model
    # error is the 25-sample line's excess, computed here by an independent polyfit.
    n, onset = 900, 500
    t = np.arange(n) / FS
    ratio = np.full(n, 0.35)
    ratio[: onset + 1] = np.minimum(0.5 * t[: onset + 1], 0.5 * t[onset - 12])
    est = identify_mu(**slip_ramp(ratio, t[onset]))
    window = slice(onset - 24, onset + 1)
    long_line = np.polyval(np.polyfit(t[window], ratio[window], 1), t[onset])
    assert est.onset_index == onset
    assert est.static == pytest.approx(long_line, abs=1e-12)
    assert est.static_model == pytest.approx(long_line - ratio[onset], abs=1e-12)
    assert est.static_model > 0.001
    # a straight ramp to the onset: no bend
    straight = np.where(t <= t[onset], 0.5 * t, 0.35)
    assert identify_mu(**slip_ramp(straight, t[onset])).static_model == pytest.approx(0.0, abs=1e-12)


def test_a_plateau_still_drifting_has_a_dynamic_model_error() -> None:
    # After the onset (sample 500) and the 0.1 s settle (50 samples) the plateau runs over
    # samples 551..999 (449 samples) falling at 1e-5 per sample. The level is the mean of
    # its second half (225 samples, 775..999), the model error the difference of the means
    # of that half's halves (112 and 113 samples, centres 55.5 and 168 samples in):
    # 112.5 samples apart at 1e-5 per sample = 0.001125.
    n, onset = 1000, 500
    t = np.arange(n) / FS
    ratio = np.empty(n)
    ratio[: onset + 1] = 0.45 * t[: onset + 1] / t[onset]
    k = np.arange(onset + 1, n)
    ratio[onset + 1:] = 0.36 - 1e-5 * (k - onset)
    est = identify_mu(**slip_ramp(ratio, t[onset]))
    plateau = ratio[onset + 1 + 50:]
    late = plateau[plateau.size // 2:]
    assert late.size == 225
    assert est.dynamic == pytest.approx(late.mean(), abs=1e-12)
    assert est.dynamic_model == pytest.approx(112.5 * 1e-5, rel=1e-9)


def test_pooled_model_error_by_hand() -> None:
    # The larger of the recordings' model errors and their scatter.
    assert pooled_model([1.0, 1.2], [0.05, 0.1]) == pytest.approx(math.sqrt(0.02))   # std 0.1414
    assert pooled_model([1.0, 1.01], [0.05, math.nan]) == pytest.approx(0.05)
    assert pooled_model([1.0], [0.3]) == pytest.approx(0.3)
    assert math.isnan(pooled_model([1.0], [math.nan]))


def test_beta_from_pressure_by_hand() -> None:
    # Four equal taxels on the corners of a 2 mm square: the geometric median is the
    # centre, every taxel sqrt(2) mm from it, so beta = mu * sqrt(2) mm.
    positions = np.array([[-1e-3, -1e-3], [1e-3, -1e-3], [-1e-3, 1e-3], [1e-3, 1e-3]])
    square = np.ones(4)
    assert beta_from_pressure([square], positions, 0.5) == pytest.approx(0.5 * math.sqrt(2) * 1e-3, rel=1e-6)
    # The median over frames: a frame on two taxels (median anywhere on the segment
    # between them: mean distance 1 mm) and two square frames -> sqrt(2) mm.
    pair = np.array([1.0, 1.0, 0.0, 0.0])
    assert beta_from_pressure([pair, square, square], positions, 1.0) == pytest.approx(math.sqrt(2) * 1e-3, rel=1e-6)
    assert math.isnan(beta_from_pressure([np.zeros(4)], positions, 1.0))


def test_interval_half_width_by_hand() -> None:
    assert interval_half_width(0.003, 0.004) == pytest.approx(0.01)
    assert interval_half_width(0.003, math.nan) == pytest.approx(0.006)
    assert math.isnan(interval_half_width(math.nan, 0.004))
