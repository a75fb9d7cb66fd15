"""First-order low-pass filter on vectors, discretised exactly for a sample interval.

The continuous filter ``τ·dy/dt + y = x`` with cut-off ``f_c = 1/(2π τ)`` (Hz), held
constant over a step of ``dt`` seconds (zero-order hold), gives::

    y_k = y_{k−1} + α·(x_k − y_{k−1}),    α = 1 − exp(−2π f_c dt)

so the filter is stable for every ``dt > 0`` and its step response reaches
``1 − e^{−1}`` after τ seconds whatever the sample rate. ``f_c = 0`` means *off*
(α = 1, the output is the input). Pure computation: time is the ``dt`` argument.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["lowpass_alpha", "lowpass_step", "LowPass"]


def lowpass_alpha(dt_s: float, cutoff_hz: float) -> float:
    """Smoothing factor α ∈ [0, 1] for a step of ``dt_s`` seconds at ``cutoff_hz`` Hz.

    ``cutoff_hz <= 0`` (filter off) gives 1; ``dt_s <= 0`` (no time passed) gives 0.
    """
    if cutoff_hz <= 0:
        return 1.0
    if dt_s <= 0:
        return 0.0
    return -math.expm1(-2.0 * math.pi * cutoff_hz * dt_s)


def lowpass_step(y_prev: np.ndarray, x: np.ndarray, dt_s: float, cutoff_hz: float) -> np.ndarray:
    """One filter step: ``y_prev + α·(x − y_prev)`` (same shape and units as ``x``)."""
    y_prev = np.asarray(y_prev, dtype=float)
    return y_prev + lowpass_alpha(dt_s, cutoff_hz) * (np.asarray(x, dtype=float) - y_prev)


class LowPass:
    """A :func:`lowpass_step` with its state: the first sample (and the first after
    :meth:`reset`) passes through unchanged, so a restart has no transient from zero.

    A sample with a non-finite entry is returned as is and leaves the state
    untouched, so one bad value neither poisons nor hides later ones.
    """

    def __init__(self, cutoff_hz: float) -> None:
        self.cutoff_hz = float(cutoff_hz)
        self.state: np.ndarray | None = None

    def reset(self) -> None:
        """Forget the state; the next sample passes through."""
        self.state = None

    def step(self, x: np.ndarray, dt_s: float) -> np.ndarray:
        """Filter one sample taken ``dt_s`` seconds after the previous one."""
        x = np.asarray(x, dtype=float)
        # the finite check on Python floats: ~5x cheaper than np.isfinite(x).all() on a short
        # vector (an F/T sample's 6 values, at the sensor rate)
        if not all(map(math.isfinite, x.ravel().tolist())):
            return x
        self.state = x.copy() if self.state is None else lowpass_step(self.state, x, dt_s, self.cutoff_hz)
        return self.state
