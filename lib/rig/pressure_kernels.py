"""Compiled Hertzian pressure sampling of the taxel cells (see lib/rig/contact.py).

More in docs/modules.md, `lib/rig/pressure_kernels.py`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from slipstack.lib.rig.bristle_kernels import complex_abs
from slipstack.lib.weber import JIT

__all__ = ["MAX_POINTS_PER_CELL", "compile_kernels", "hertz_cell_means", "footprint_cell_means", "numpy_pairwise_sum",
           "FOOTPRINT_PAD", "FOOTPRINT_DISC", "FOOTPRINT_RECT"]

MAX_POINTS_PER_CELL = 128
"""numpy's PW_BLOCKSIZE: runs up to this long are summed in eight interleaved lanes (longer
ones by halving, which :func:`numpy_pairwise_sum` does not do)."""


@njit(**JIT)
def numpy_pairwise_sum(a: np.ndarray, n: int) -> float:
    """``a[:n].sum()`` of a contiguous float64 run of at most 128 values, in numpy's order.

    numpy adds short runs (< 8) left to right, and runs up to 128 in eight interleaved
    partial sums combined as a tree, then the last ``n mod 8`` left to right.
    """
    if n < 8:
        total = 0.0
        for i in range(n):
            total += a[i]
        return total
    l0, l1, l2, l3, l4, l5, l6, l7 = a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7]
    end = n - n % 8
    i = 8
    while i < end:
        l0 += a[i]
        l1 += a[i + 1]
        l2 += a[i + 2]
        l3 += a[i + 3]
        l4 += a[i + 4]
        l5 += a[i + 5]
        l6 += a[i + 6]
        l7 += a[i + 7]
        i += 8
    total = ((l0 + l1) + (l2 + l3)) + ((l4 + l5) + (l6 + l7))
    while i < n:
        total += a[i]
        i += 1
    return total


@njit(**JIT)
def hertz_cell_means(points: np.ndarray, centre: complex, radius_m: float, out: np.ndarray) -> None:
    """Mean Hertzian pressure ``sqrt(max(1 − |q − c|²/a², 0))`` over each cell's points.

    Args:
        points: sample points, shape (N, s²) (complex, m), ``s² ≤ MAX_POINTS_PER_CELL``.
        centre: contact centre ``c`` (complex, m).
        radius_m: contact radius ``a`` (m); 0 gives no pressure anywhere.
        out: receives the N cell means.
    """
    n_cells, n_points = points.shape
    scale = radius_m * radius_m
    row = np.empty(n_points)
    for k in range(n_cells):
        for j in range(n_points):
            d = points[k, j] - centre
            r2 = (d.real * d.real + d.imag * d.imag) / scale if radius_m > 0 else math.inf
            row[j] = math.sqrt(max(1.0 - r2, 0.0))
        out[k] = numpy_pairwise_sum(row, n_points) / n_points


FOOTPRINT_PAD, FOOTPRINT_DISC, FOOTPRINT_RECT = 0, 1, 2
"""Footprints of :func:`footprint_cell_means`: the whole pad, a disc, a rectangle."""


@njit(**JIT)
def footprint_cell_means(points: np.ndarray, centre: complex, footprint: int, radius_m: float, half_x_m: float,
                         half_y_m: float, sloped: bool, slope_x: float, slope_y: float, ridge_depth: float,
                         ridge_kx: float, ridge_ky: float, out: np.ndarray) -> None:
    """Mean pressure of the flat and offset models over each cell's points.

    At a point ``d = q − c`` from the centre: 1 inside the footprint (``|d| ≤ radius``
    for a disc, ``|d_x| ≤ half_x`` and ``|d_y| ≤ half_y`` for a rectangle, everywhere
    for the pad), 0 outside; ``sloped`` (the offset model) multiplies it by
    ``max(1 + slope_x d_x + slope_y d_y, 0)``; ridges (``ridge_depth > 0``) multiply it by
    ``1 + ridge_depth·cos(k_x d_x + k_y d_y)``. The expressions and the order of each
    cell's sum are numpy's, so the means without ridges are bit for bit those of the numpy code.

    Args:
        points: sample points, shape (N, s²) (complex, m), ``s² ≤ MAX_POINTS_PER_CELL``.
        centre: footprint centre ``c`` (complex, m).
        footprint: ``FOOTPRINT_PAD``, ``FOOTPRINT_DISC`` or ``FOOTPRINT_RECT``.
        radius_m, half_x_m, half_y_m: the disc's radius, the rectangle's half sizes (m).
        sloped, slope_x, slope_y: the offset model's slope (1/m).
        ridge_depth, ridge_kx, ridge_ky: the ridges' relative depth (0: none) and wave
            vector (rad/m).
        out: receives the N cell means (dimensionless).
    """
    n_cells, n_points = points.shape
    row = np.empty(n_points)
    for k in range(n_cells):
        for j in range(n_points):
            d = points[k, j] - centre
            if footprint == FOOTPRINT_DISC:
                inside = complex_abs(d) <= radius_m
            elif footprint == FOOTPRINT_RECT:
                inside = abs(d.real) <= half_x_m and abs(d.imag) <= half_y_m
            else:
                inside = True
            value = 1.0 if inside else 0.0
            if sloped:
                level = 1.0 + (slope_x * d.real + slope_y * d.imag)
                value *= level if not level < 0.0 else 0.0  # np.clip(level, 0, None): NaN stays NaN
            if ridge_depth > 0.0:
                value *= 1.0 + ridge_depth * math.cos(ridge_kx * d.real + ridge_ky * d.imag)
            row[j] = value
        out[k] = numpy_pairwise_sum(row, n_points) / n_points


def compile_kernels() -> None:
    """Compile these kernels, or load them from numba's cache."""
    hertz_cell_means(np.zeros((2, 4), dtype=complex), 0j, 1e-3, np.empty(2))
    footprint_cell_means(np.zeros((2, 4), dtype=complex), 0j, FOOTPRINT_RECT, 1e-3, 1e-3, 1e-3, True, 1.0, 1.0,
                         0.5, 1e3, 0.0, np.empty(2))
