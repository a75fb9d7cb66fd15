"""Sensor models of the rig: a 6-axis F/T sensor and a conductive-rubber tactile pad.

More in docs/modules.md, `lib/rig/sensors.py`.
"""

from __future__ import annotations

import math

import numpy as np

from slipstack.lib.pad import PadGeometry
from slipstack.lib.rig.scene import FtSpec, TactileSpec
from slipstack.lib.rig import sensor_kernels
from slipstack.lib.rig.sensor_kernels import tactile_counts
from slipstack.lib.samples import FtSample, TactileSample

__all__ = ["FtSensorModel", "TactileSensorModel"]

_NO_NOISE = np.zeros(0)


class FtSensorModel:
    """Wrench at the sensor origin with bias, Gaussian noise, quantisation and range.

    Args:
        spec: sensor parameters (origin ``p_S`` in ``F``, yaw of ``S`` about ``z``).
        pad: the taxel grid (for the moments of the normal forces).
        rng: noise generator.
        finger: the finger it sits in (its samples say so).
    """

    def __init__(self, spec: FtSpec, pad: PadGeometry, rng: np.random.Generator, finger: int = 0) -> None:
        self.spec = spec
        self.finger = finger
        self._px = pad.positions[:, 0].copy()
        self._py = pad.positions[:, 1].copy()
        self._rng = rng
        res = [spec.resolution_force_N] * 3 + [spec.resolution_torque_Nm] * 3
        if min(res) <= 0.0:  # quantised on every axis or on none
            res = [0.0] * 6
        self._constants = np.array([*spec.origin_m, math.cos(spec.yaw_rad), math.sin(spec.yaw_rad),
                                    *spec.bias_force_N, *spec.bias_torque_Nm,
                                    *[spec.noise_force_N] * 3, *[spec.noise_torque_Nm] * 3,
                                    *res, *spec.range_force_N, *spec.range_torque_Nm])
        """The reading's constants (lib/rig/sensor_kernels.py, ``N_FT_CONSTANTS``)."""
        self._cos, self._sin = math.cos(spec.yaw_rad), math.sin(spec.yaw_rad)

    def ideal_wrench(self, phi: np.ndarray, f_n: float, load_force: complex,
                     load_torque: float) -> tuple[list[float], list[float]]:
        """Noise-free wrench in ``S`` from the contact state.

        Args:
            phi: normal force per taxel (N).
            f_n: ``Σ φ_i`` (N).
            load_force: tangential force of the object on the finger, ``−Σ q_i``
                (complex N, ``F``).
            load_torque: its torque about the pad's ``z`` axis through the pad origin,
                ``−Σ p_i × q_i`` (N·m).

        Returns:
            ``(force_S, torque_S)``, three floats each, N and N·m.
        """
        wrench = np.empty(6)
        sensor_kernels.ideal_wrench(phi, self._px, self._py, f_n, load_force, load_torque, self._constants, wrench)
        values = wrench.tolist()
        return values[:3], values[3:]

    def measure(self, t_ns: int, seq: int, phi: np.ndarray, f_n: float, load_force: complex,
                load_torque: float) -> FtSample:
        """A noisy, biased, quantised, range-limited reading (see :meth:`ideal_wrench`)."""
        noise = self._rng.standard_normal(6)
        force, torque = np.empty(3), np.empty(3)
        saturated = sensor_kernels.ft_reading(phi, self._px, self._py, f_n, load_force, load_torque,
                                              self._constants, noise, force, torque)
        return FtSample(t_ns, force, torque, device_seq=seq, saturated=saturated, finger=self.finger)

    def pad_load(self, force_S: np.ndarray, torque_S: np.ndarray) -> tuple[float, float, float, float]:
        """Map a reading to docs/math.md §1: returns ``(f_x N, f_y N, τ N·m, f_n N)`` in ``F``.

        ``f_t = (f_x, f_y)`` and ``τ`` are the load on the object; ``f_n = −f_z``.
        """
        c, s = self._cos, self._sin  # rotate S → F: by +yaw about z
        fx, fy, fz = (float(v) for v in force_S)
        tz = float(torque_S[2])  # rotation about z leaves τ_z unchanged
        fx, fy = c * fx - s * fy, s * fx + c * fy
        sx, sy, _ = self.spec.origin_m
        return fx, fy, tz + sx * fy - sy * fx, -fz  # τ_F,z = τ_S,z + (p_S × f)_z


class TactileSensorModel:
    """Conductive-rubber taxels: saturating 12-bit counts of the local pressure.

    ``counts_i = baseline + full·(1 − exp(−g_i p'_i / p0)) + N(0, σ²)``, rounded and
    clipped to ``[0, full]``; ``p_i = φ_i/h²`` (Pa), ``p'`` with neighbour leakage,
    ``g_i`` per-taxel gain; dead taxels read 0.

    Args:
        spec: tactile parameters.
        pad: the taxel grid.
        rng_init: draws gains and random dead taxels once.
        rng_noise: per-frame noise.
        finger: the finger it sits in (its frames say so).
    """

    def __init__(self, spec: TactileSpec, pad: PadGeometry, rng_init: np.random.Generator,
                 rng_noise: np.random.Generator, finger: int = 0) -> None:
        self.spec = spec
        self.finger = finger
        self.pad = pad
        n = pad.n_taxels
        self.gains = np.clip(1.0 + spec.gain_spread * rng_init.standard_normal(n), 0.1, None)
        dead = rng_init.random(n) < spec.dead_fraction
        for r, c in spec.dead_taxels:
            dead[r * pad.cols + c] = True
        self.dead = dead
        self._alive = ~dead
        self._rng = rng_noise
        self._neg_scale = -self.gains / (spec.p0_Pa * pad.taxel_area_m2)  # φ (N) → exponent

    def measure(self, t_ns: int, seq: int, phi: np.ndarray) -> TactileSample:
        """A frame of counts for normal forces ``phi`` (N per taxel)."""
        spec = self.spec
        if spec.crosstalk > 0.0:
            phi = self._leak(phi)
        level = self._neg_scale * phi
        np.exp(level, out=level)  # e^{−g p/p0}
        noise = self._rng.normal(0.0, spec.noise_counts, level.shape[0]) if spec.noise_counts > 0.0 else _NO_NOISE
        counts = np.empty(level.shape[0], dtype=np.uint16)
        tactile_counts(level, float(spec.full_scale_counts), float(spec.baseline_counts), noise, self._alive, counts)
        return TactileSample(t_ns, counts.reshape(self.pad.rows, self.pad.cols), device_seq=seq, finger=self.finger)

    def _leak(self, phi: np.ndarray) -> np.ndarray:
        grid = phi.reshape(self.pad.rows, self.pad.cols)
        out = grid.copy()
        k = self.spec.crosstalk
        out[1:, :] += k * grid[:-1, :]
        out[:-1, :] += k * grid[1:, :]
        out[:, 1:] += k * grid[:, :-1]
        out[:, :-1] += k * grid[:, 1:]
        return out.ravel()

    def nominal_counts(self, pressure_Pa: np.ndarray) -> np.ndarray:
        """The nominal curve (gain 1, no noise): counts (float) for pressures in Pa."""
        spec = self.spec
        p = np.asarray(pressure_Pa, dtype=float)
        return spec.baseline_counts + spec.full_scale_counts * -np.expm1(-p / spec.p0_Pa)

    def nominal_pressure(self, counts: np.ndarray) -> np.ndarray:
        """Inverse of the nominal curve: pressure (Pa) for counts, NaN at saturation."""
        spec = self.spec
        x = (np.asarray(counts, dtype=float) - spec.baseline_counts) / spec.full_scale_counts
        x = np.clip(x, 0.0, None)
        with np.errstate(divide="ignore", invalid="ignore"):
            p = -spec.p0_Pa * np.log1p(-x)
        return np.where(x < 1.0, p, np.nan)

    def calibration_table(self, n_points: int = 33,
                          top_fraction: float = 0.99) -> tuple[np.ndarray, np.ndarray]:
        """Points of the nominal curve for a tactile driver's calibration table.

        Args:
            n_points: number of points, evenly spaced in counts.
            top_fraction: the last point sits at this fraction of full scale (the curve
                is flat beyond it: saturation).

        Returns:
            ``(pressure_Pa, counts)``, both shape ``(n_points,)``, increasing, starting
            at ``(0, baseline)``.
        """
        spec = self.spec
        top = spec.baseline_counts + top_fraction * (spec.full_scale_counts - spec.baseline_counts)
        counts = np.linspace(spec.baseline_counts, top, n_points)
        return self.nominal_pressure(counts), counts
