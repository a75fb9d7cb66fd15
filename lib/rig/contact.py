"""Pressure models: the normal force on each taxel, ``φ_i ≥ 0`` with ``Σ φ_i = f_n``.

Positions are complex numbers ``x + i·y`` in the pad frame ``F`` (docs/math.md §1), metres.
Each taxel cell is sampled at ``s × s`` sub-taxel points and its weight is the mean
pressure over them, so a contact smaller than a taxel or an edge crossing a cell is
not aliased onto a single taxel centre. Models (parameters in
:class:`~slipstack.lib.rig.scene.ContactSpec`):

More in docs/modules.md, `lib/rig/contact.py`.
"""

from __future__ import annotations

import cmath

import numpy as np

from slipstack.lib.errors import ConfigError
from slipstack.lib.pad import PadGeometry
from slipstack.lib.rig.pressure_kernels import (
    FOOTPRINT_DISC, FOOTPRINT_PAD, FOOTPRINT_RECT, MAX_POINTS_PER_CELL, footprint_cell_means, hertz_cell_means)
from slipstack.lib.rig.scene import MAX_SUBSAMPLES, ContactSpec

__all__ = ["PressureModel"]

_FOOTPRINTS = {"pad": FOOTPRINT_PAD, "disc": FOOTPRINT_DISC, "rect": FOOTPRINT_RECT}
"""The scene's ``contact.footprint`` → the kernel's code."""
_SHAPE_FORCE_RTOL = 2e-3
"""Re-evaluate a force-dependent shape when f_n moved by more than this (relative);
a Hertzian radius then moves by ≤ 0.07 %."""
_SHAPE_MOVE_FRACTION = 0.02
"""Re-evaluate an attached footprint when any pad point moved by 2 % of a pitch."""


class PressureModel:
    """Maps ``(f_n, object pose)`` to ``φ`` per taxel, caching the normalised shape.

    Args:
        spec: contact parameters of the scene.
        pad: the taxel grid.
        initial_pose: ``(x, y, θ)`` of the object at t = 0 (the footprint's reference).
    """

    def __init__(self, spec: ContactSpec, pad: PadGeometry,
                 initial_pose: tuple[float, float, float]) -> None:
        self._spec = spec
        self._pad = pad
        s = spec.subsamples
        if not 1 <= s * s <= MAX_POINTS_PER_CELL:
            raise ConfigError(f"contact.subsamples: {s} is out of range; use 1 to {MAX_SUBSAMPLES}")
        offs = ((np.arange(s) + 0.5) / s - 0.5) * pad.pitch_m
        sub = (offs[None, :] + 1j * offs[:, None]).ravel()
        centres = pad.positions[:, 0] + 1j * pad.positions[:, 1]
        self._points = centres[:, None] + sub[None, :]  # (N, s²) complex
        self._centres = centres
        self._pose0 = (complex(initial_pose[0], initial_pose[1]), float(initial_pose[2]))
        # A uniform pressure over the whole pad does not change when the object moves.
        self._attached = spec.attached_to_object and not (
            spec.model == "flat" and spec.footprint == "pad" and spec.ridge_depth == 0.0)
        self._force_dependent = spec.model in ("hertz", "edge")
        reach = float(np.max(np.abs(centres))) + pad.pitch_m
        self._move_tol = _SHAPE_MOVE_FRACTION * pad.pitch_m
        self._rot_tol = self._move_tol / reach
        self._key: tuple[float, complex, float] | None = None
        k = 2.0 * np.pi / spec.ridge_period_m if spec.ridge_depth > 0.0 else 0.0
        self._ridge_wave = (k * np.cos(spec.ridge_angle_rad), k * np.sin(spec.ridge_angle_rad))
        self._shape = np.zeros(pad.n_taxels)

    @property
    def attached(self) -> bool:
        """True when the footprint moves with the object."""
        return self._attached

    def shape(self, f_n: float, origin: complex, theta: float) -> np.ndarray:
        """Normalised pressure shape ``w_i ≥ 0``, ``Σ w_i = 1`` (all zero: no contact).

        Args:
            f_n: normal force (N); only shapes of hertz and edge depend on it.
            origin: object centre of mass in ``F`` (complex, m).
            theta: object angle (rad).
        """
        if self._key is None or self._stale(f_n, origin, theta):
            self._key = (f_n, origin, theta)
            self._shape = self._evaluate(f_n, origin, theta)
        return self._shape

    def phi(self, f_n: float, origin: complex, theta: float) -> np.ndarray:
        """Normal force per taxel ``φ_i = f_n·w_i`` (N), shape ``(R·C,)``, row-major."""
        return max(f_n, 0.0) * self.shape(f_n, origin, theta)

    def phi_uncached(self, f_n: float, origin: complex, theta: float) -> np.ndarray:
        """:meth:`phi` evaluated afresh, ignoring the shape cache (N per taxel).

        :meth:`shape` reuses its shape while the force stays within 0.2 % (and the pose
        is unchanged), so ``phi(f)`` depends on the evaluation history; comparisons with
        the truth (the benchmarks' oracle and true load factor) want it not to.
        """
        return max(f_n, 0.0) * self._evaluate(f_n, origin, theta)

    def check_touches_pad(self, f_n: float) -> None:
        """Raise ConfigError if the contact at the initial pose misses the pad."""
        o0, th0 = self._pose0
        if not np.any(self._evaluate(max(f_n, 1e-3), o0, th0) > 0):
            raise ConfigError(
                f"contact: the {self._spec.model} pressure footprint does not touch the "
                f"{self._pad.rows}x{self._pad.cols} pad; move contact.centre_m onto it")

    def _stale(self, f_n: float, origin: complex, theta: float) -> bool:
        f0, o0, th0 = self._key
        if self._force_dependent and abs(f_n - f0) > _SHAPE_FORCE_RTOL * max(abs(f0), 1e-9):
            return True
        return self._attached and (abs(origin - o0) > self._move_tol
                                   or abs(theta - th0) > self._rot_tol)

    def _evaluate(self, f_n: float, origin: complex, theta: float) -> np.ndarray:
        points = self._points
        if self._attached:
            o0, th0 = self._pose0
            points = o0 + cmath.exp(1j * (th0 - theta)) * (points - origin)
        spec = self._spec
        if spec.model == "hertz":  # re-evaluated often (its shape follows f_n): compiled
            weights = np.empty(points.shape[0])
            hertz_cell_means(points, complex(*spec.centre_m), self._hertz_radius(f_n), weights)
        elif spec.model == "edge":
            weights = self._edge_pressure(points, f_n).mean(axis=1)
        else:  # flat, offset: re-evaluated whenever an attached contact moves: compiled
            weights = np.empty(points.shape[0])
            footprint_cell_means(points, complex(*spec.centre_m), _FOOTPRINTS[spec.footprint], spec.radius_m,
                                 *spec.half_size_m, spec.model == "offset", *spec.slope_per_m, spec.ridge_depth,
                                 *self._ridge_wave, weights)
        total = float(weights.sum())
        if total > 0.0:
            return weights / total
        if self._force_dependent and f_n > 0.0:
            return self._point_contact()
        return np.zeros_like(weights)

    def _point_contact(self) -> np.ndarray:
        """A contact smaller than the sampling: all force on the nearest taxel."""
        out = np.zeros(self._pad.n_taxels)
        out[int(np.argmin(np.abs(self._centres - complex(*self._spec.centre_m))))] = 1.0
        return out

    def _hertz_radius(self, f_n: float) -> float:
        """Hertzian contact radius ``a = a_ref·(f_n/f_ref)^{1/3}`` (m)."""
        spec = self._spec
        return spec.a_ref_m * (max(f_n, 0.0) / spec.f_ref_N) ** (1.0 / 3.0)

    def _edge_pressure(self, q: np.ndarray, f_n: float) -> np.ndarray:
        """Unnormalised pressure of the edge model at points ``q`` (complex, in the
        footprint's frame); the other models are compiled (lib/rig/pressure_kernels.py)."""
        spec = self._spec
        d = q - complex(*spec.centre_m)
        b = spec.b_ref_m * (max(f_n, 0.0) / spec.f_ref_N) ** 0.5
        local = d * cmath.exp(-1j * spec.angle_rad)
        across = (local.imag / b) ** 2 if b > 0 else np.full(d.shape, np.inf)
        along = np.abs(local.real) <= spec.length_m / 2
        return np.sqrt(np.clip(1.0 - across, 0.0, None)) * along
