"""Compiled per-taxel arithmetic of the simulated tactile pad (see lib/rig/sensors.py).

:meth:`~slipstack.lib.rig.sensors.TactileSensorModel.measure` turned the rubber's
saturation level into 12-bit counts with seven numpy calls on the 256 taxels of
every frame; :func:`tactile_counts` does them in one pass, with the same operations
in the same order (so the counts do not change). The exponential stays numpy's (its
rounding differs from libm's) and so does the noise generator.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from slipstack.lib.weber import JIT

__all__ = ["compile_kernels", "tactile_counts"]


@njit(**JIT)
def tactile_counts(level: np.ndarray, full_scale: float, baseline: float, noise: np.ndarray, alive: np.ndarray,
                   counts_out: np.ndarray) -> None:
    """Counts ``rint(clip(baseline + full·(1 − level) + noise, 0, full)·alive)``.

    Evaluated as numpy did: ``level·(−full) + (baseline + full)``, ``+ noise`` (an
    empty ``noise``: none), clipped (NaN stays NaN), times the alive mask (1/0),
    rounded half to even, cast to uint16 (NaN → 0, as numpy's cast gives here).

    Args:
        level: ``exp(−g p/p0)`` per taxel (dimensionless).
        full_scale, baseline: counts.
        noise: per-taxel noise (counts), shape (N,) or (0,).
        alive: False for dead taxels.
        counts_out: receives the counts, uint16.
    """
    offset = baseline + full_scale
    has_noise = noise.shape[0] > 0
    for i in range(level.shape[0]):
        v = level[i] * -full_scale + offset
        if has_noise:
            v += noise[i]
        if v < 0.0:
            v = 0.0
        if v > full_scale:
            v = full_scale
        v = np.rint(v * (1.0 if alive[i] else 0.0))
        counts_out[i] = 0 if v != v else np.uint16(v)


def compile_kernels() -> None:
    """Compile these kernels, or load them from numba's cache."""
    f = np.ones(2)
    tactile_counts(f, 4095.0, 0.0, f, np.array([True, False]), np.empty(2, dtype=np.uint16))
