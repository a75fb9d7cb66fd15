"""Compiled arithmetic of the simulated sensors (see lib/rig/sensors.py).

:func:`ft_reading` is a whole F/T reading (ideal wrench, bias, noise, quantisation,
range) in one call: it replaced a loop over the six axes in Python and two numpy dot
products per sample (~10 µs a sample in the lock-step run); its moments ``Σ x φ``
and ``Σ y φ`` are plain loops, so their last bits may differ from numpy's.

More in docs/modules.md, `lib/rig/sensor_kernels.py`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from slipstack.lib.weber import JIT

__all__ = ["compile_kernels", "tactile_counts", "ideal_wrench", "ft_reading", "FT_ORIGIN", "FT_COS_SIN",
           "FT_BIAS", "FT_NOISE", "FT_RESOLUTION", "FT_RANGE", "N_FT_CONSTANTS"]


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


FT_ORIGIN, FT_COS_SIN, FT_BIAS, FT_NOISE, FT_RESOLUTION, FT_RANGE = 0, 3, 5, 11, 17, 23
"""Offsets in the F/T constants: sensor origin ``p_S`` in ``F`` (3, m); cos and sin of
its yaw; per axis ``(f_x, f_y, f_z, τ_x, τ_y, τ_z)``: bias, noise standard deviation,
resolution (0: not quantised) and range (6 each; N, N·m)."""
N_FT_CONSTANTS = 29


@njit(**JIT)
def ideal_wrench(phi: np.ndarray, px: np.ndarray, py: np.ndarray, f_n: float, load_force: complex,
                 load_torque: float, constants: np.ndarray, wrench_out: np.ndarray) -> None:
    """Noise-free wrench in the sensor frame ``S`` (N, N·m) into ``wrench_out`` (6,).

    The pad's normal forces ``−φ_i ẑ`` at ``p_i = (x_i, y_i, 0)`` and the tangential load
    give, about the pad origin, ``τ_F = (−Σ y φ, Σ x φ, load_torque)`` with
    ``f_F = (load_force, −f_n)``; then ``τ_S = τ_F − p_S × f`` and both rotate by −yaw.
    """
    fx, fy, fz = load_force.real, load_force.imag, -f_n
    mx = my = 0.0
    for i in range(phi.shape[0]):
        mx += px[i] * phi[i]
        my += py[i] * phi[i]
    tx, ty, tz = -my, mx, load_torque
    sx, sy, sz = constants[FT_ORIGIN], constants[FT_ORIGIN + 1], constants[FT_ORIGIN + 2]
    tx -= sy * fz - sz * fy
    ty -= sz * fx - sx * fz
    tz -= sx * fy - sy * fx
    c, s = constants[FT_COS_SIN], constants[FT_COS_SIN + 1]
    wrench_out[0] = c * fx + s * fy
    wrench_out[1] = -s * fx + c * fy
    wrench_out[2] = fz
    wrench_out[3] = c * tx + s * ty
    wrench_out[4] = -s * tx + c * ty
    wrench_out[5] = tz


@njit(**JIT)
def ft_reading(phi: np.ndarray, px: np.ndarray, py: np.ndarray, f_n: float, load_force: complex,
               load_torque: float, constants: np.ndarray, noise: np.ndarray, force_out: np.ndarray,
               torque_out: np.ndarray) -> bool:
    """A reading: :func:`ideal_wrench` plus bias plus ``σ·noise``, rounded half to even
    to the resolution, clipped to ``±range``; force (N) and torque (N·m) into the
    outputs (3 each). Returns whether some axis was clipped (saturated).

    Args:
        phi, px, py: normal force (N) and centre ``(x, y)`` (m) of each taxel.
        f_n: ``Σ φ_i`` (N). load_force, load_torque: see :func:`ideal_wrench`.
        constants: see :data:`N_FT_CONSTANTS`. noise: six standard normal draws.
    """
    wrench = np.empty(6)
    ideal_wrench(phi, px, py, f_n, load_force, load_torque, constants, wrench)
    saturated = False
    for axis in range(6):
        v = wrench[axis] + (constants[FT_BIAS + axis] + constants[FT_NOISE + axis] * noise[axis])
        res = constants[FT_RESOLUTION + axis]
        if res > 0.0:
            v = np.rint(v / res) * res
        limit = constants[FT_RANGE + axis]
        if abs(v) > limit:
            saturated = True
            v = math.copysign(limit, v)
        if axis < 3:
            force_out[axis] = v
        else:
            torque_out[axis - 3] = v
    return saturated


def compile_kernels() -> None:
    """Compile these kernels, or load them from numba's cache."""
    f = np.ones(2)
    tactile_counts(f, 4095.0, 0.0, f, np.array([True, False]), np.empty(2, dtype=np.uint16))
    constants = np.ones(N_FT_CONSTANTS)
    ft_reading(f, f, f, 1.0, 1j, 1.0, constants, np.ones(6), np.empty(3), np.empty(3))
    ideal_wrench(f, f, f, 1.0, 1j, 1.0, constants, np.empty(6))
