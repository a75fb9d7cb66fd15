"""From identified ramps to a material: pooled coefficients, load-factor noise, onset levels.

The pieces of :mod:`slipstack.analysis.identify_cli` that are plain computation:

More in docs/modules.md, `lib/material_fit.py`.
"""

from __future__ import annotations

import math

import numpy as np

from slipstack.lib.limit_set import torsional_coefficient

__all__ = ["pooled", "pooled_model", "frame_noise", "onset_frames", "beta_from_pressure",
           "interval_half_width"]

_MIN_NOISE_FRAMES = 5


def pooled(values: list[float], standard_errors: list[float]) -> tuple[float, float]:
    """Inverse-variance weighted mean and its standard error; NaN, NaN without a finite pair.

    An estimate with a zero or non-finite standard error is left out (its weight is
    undefined); with only such estimates, their plain mean with SE NaN.
    """
    pairs = [(v, s) for v, s in zip(values, standard_errors) if math.isfinite(v)]
    weighted = [(v, s) for v, s in pairs if math.isfinite(s) and s > 0]
    if not weighted:
        return (float(np.mean([v for v, _ in pairs])), math.nan) if pairs else (math.nan, math.nan)
    w = np.array([1.0 / (s * s) for _, s in weighted])
    v = np.array([v for v, _ in weighted])
    return float(w @ v / w.sum()), float(1.0 / math.sqrt(w.sum()))


def pooled_model(values: list[float], models: list[float]) -> float:
    """Model error of a pooled coefficient (same unit as ``values``).

    The largest finite model error of the estimates (a model error does not average
    away over recordings of the same contact), or, with two or more finite values, their
    scatter (sample standard deviation) if that is larger: ramps that disagree by more
    than their model errors show an error none of them saw. NaN without any.
    """
    finite_values = [v for v in values if math.isfinite(v)]
    candidates = [m for m in models if math.isfinite(m)]
    if len(finite_values) >= 2:
        candidates.append(float(np.std(finite_values, ddof=1)))
    return max(candidates) if candidates else math.nan


def beta_from_pressure(phis: list[np.ndarray], positions: np.ndarray, mu: float) -> float:
    """``μ × r̄`` (m): β of rigid Coulomb friction on the measured pressure.

    Args:
        phis: pressure frames, each ``(N,)`` per taxel (any unit: only its shape counts).
        positions: ``(N, 2)`` taxel centres in ``F``, m.
        mu: friction coefficient (``μ_s`` for β_s, ``μ_d`` for β_d).

    ``r̄`` is the median over the frames of the pressure-weighted mean distance from the
    geometric median (``lib/limit_set.torsional_coefficient``); NaN without a usable frame.
    """
    distances = []
    for phi in phis:
        r = torsional_coefficient(phi, positions, 1.0)
        if r.status.usable and r.beta_m > 0:
            distances.append(r.beta_m)
    return mu * float(np.median(distances)) if distances and math.isfinite(mu) else math.nan


def interval_half_width(se: float, model: float) -> float:
    """``2·√(se² + model²)``: the ± of a value with standard error ``se`` and model error
    ``model`` (a NaN model error counts as 0, a NaN ``se`` gives NaN)."""
    return 2.0 * math.hypot(se, model if math.isfinite(model) else 0.0)


def frame_noise(gamma: np.ndarray) -> float:
    """``std(diff(γ))/√2`` over the finite frames; NaN with fewer than 5 of them."""
    g = np.asarray(gamma, dtype=float)
    g = g[np.isfinite(g)]
    if g.size < _MIN_NOISE_FRAMES:
        return math.nan
    return float(np.std(np.diff(g), ddof=1) / math.sqrt(2.0))


def onset_frames(frame_ns: np.ndarray, gamma: np.ndarray, onsets_ns: list[int], *,
                 max_age_ns: int = 20_000_000) -> list[int]:
    """Index of the newest frame with a finite γ before each onset, if no older than ``max_age_ns``.

    Args:
        frame_ns: frame stamps, ns, increasing.
        gamma: the frames' load factors (dimensionless).
        onsets_ns: gross-slip onsets, ns.
        max_age_ns: onsets without such a frame are skipped.
    """
    t = np.asarray(frame_ns, dtype=np.int64)
    finite = np.flatnonzero(np.isfinite(np.asarray(gamma, dtype=float)))
    frames = []
    for onset in onsets_ns:
        k = int(np.searchsorted(t[finite], onset, side="left")) - 1
        if k >= 0 and onset - t[finite[k]] <= max_age_ns:
            frames.append(int(finite[k]))
    return frames
