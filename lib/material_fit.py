"""From identified ramps to a material: pooled coefficients, load-factor noise, onset levels.

The pieces of :mod:`slipstack.analysis.identify_cli` that are plain computation:

- :func:`pooled`: several estimates of one coefficient (one per recording) as their
  inverse-variance weighted mean and its standard error.
- :func:`frame_noise`: the frame-to-frame noise of a load-factor series, the standard
  deviation of its first differences over √2. A slow trend (a load ramp, the friction's
  decay while sliding) changes consecutive frames by far less than the noise, so it
  hardly enters; the difference of two independent noisy frames has variance 2σ².
- :func:`onset_levels`: the load factor γ of the last frame before each gross-slip
  onset, the last one still sticking (dimensionless).

Times are integer ns; nothing here raises on data (empty inputs give NaN or empty).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["pooled", "frame_noise", "onset_levels"]

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


def frame_noise(gamma: np.ndarray) -> float:
    """``std(diff(γ))/√2`` over the finite frames; NaN with fewer than 5 of them."""
    g = np.asarray(gamma, dtype=float)
    g = g[np.isfinite(g)]
    if g.size < _MIN_NOISE_FRAMES:
        return math.nan
    return float(np.std(np.diff(g), ddof=1) / math.sqrt(2.0))


def onset_levels(frame_ns: np.ndarray, gamma: np.ndarray, onsets_ns: list[int], *,
                 max_age_ns: int = 20_000_000) -> list[float]:
    """γ of the newest finite frame before each onset, if no older than ``max_age_ns``.

    Args:
        frame_ns: frame stamps, ns, increasing.
        gamma: the frames' load factors (dimensionless).
        onsets_ns: gross-slip onsets, ns.
        max_age_ns: onsets without such a frame are skipped.
    """
    t = np.asarray(frame_ns, dtype=np.int64)
    g = np.asarray(gamma, dtype=float)
    keep = np.isfinite(g)
    t, g = t[keep], g[keep]
    levels = []
    for onset in onsets_ns:
        k = int(np.searchsorted(t, onset, side="left")) - 1
        if k >= 0 and onset - t[k] <= max_age_ns:
            levels.append(float(g[k]))
    return levels
