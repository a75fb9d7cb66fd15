"""Fusion of a tactile frame and an F/T wrench into local normal forces (docs/math.md §2).

The tactile pad gives the *shape* of the pressure, the F/T sensor its *size*::

    φ_i = f_n · w_i / Σ_j w_j        over the taxels in contact (w_i > noise floor).

More in docs/modules.md, `lib/fusion.py`.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from slipstack.lib.errors import ConfigError
from slipstack.lib.pad import PadGeometry
from slipstack.lib.status import SolverStatus
from slipstack.lib.weber import JIT

__all__ = ["FusionResult", "FusionThresholds", "PressureShape", "SensorMount", "compile_kernels", "fuse", "fuse_shape",
           "ft_understates_pad", "pressure_shape", "wrench_to_pad"]


def wrench_to_pad(
    force_S: np.ndarray, torque_S: np.ndarray, R_FS: np.ndarray, p_SF: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Move a wrench from the sensor frame S to the pad frame F.

    ``force_F = R_FS·force_S`` and ``torque_F = R_FS·torque_S + p_SF × force_F``:
    the torque about F's origin equals the torque about S's origin plus
    ``(p_S − p_F) × f`` (docs/math.md §1).

    Args:
        force_S: (3,) force in S coordinates, N.
        torque_S: (3,) torque about S's origin in S coordinates, N·m.
        R_FS: (3, 3) rotation taking S coordinates to F coordinates (``v_F = R_FS v_S``).
        p_SF: (3,) position of S's origin minus F's origin, in F coordinates, m.

    Returns:
        ``(force_F (3,), torque_F (3,))``: the same wrench in F, torque about F's origin.
    """
    R = np.asarray(R_FS, dtype=float)
    # ndarray.dot, not @: the same BLAS product for a matrix and a vector (the same bits), without the
    # ufunc machinery of matmul (0.25 instead of 0.65 µs on 3-vectors, at every F/T sample)
    f = R.dot(np.asarray(force_S, dtype=float))
    t = R.dot(np.asarray(torque_S, dtype=float))  # a new array: added to in place below
    x, y, z = np.asarray(p_SF, dtype=float).tolist()
    a, b, c = f.tolist()
    # p × f written out on Python floats (np.cross costs ~5x more on 3-vectors, at every F/T sample)
    t[0] += y * c - z * b
    t[1] += z * a - x * c
    t[2] += x * b - y * a
    return f, t


@dataclass(frozen=True)
class SensorMount:
    """Where the F/T sensor sits relative to the pad (configuration, validated once).

    Attributes:
        R_FS: rotation S → F, 3×3 proper orthonormal (tuple of rows).
        p_SF: S's origin minus F's origin in F coordinates, m.
    """

    R_FS: tuple[tuple[float, float, float], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    p_SF: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        R = np.asarray(self.R_FS, dtype=float)
        p = np.asarray(self.p_SF, dtype=float)
        if R.shape != (3, 3) or not np.isfinite(R).all():
            raise ConfigError("sensor mount R_FS must be a finite 3x3 rotation matrix")
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0:
            raise ConfigError("sensor mount R_FS must be orthonormal with det +1 (a rotation)")
        if p.shape != (3,) or not np.isfinite(p).all():
            raise ConfigError("sensor mount p_SF must be 3 finite numbers in metres")


@dataclass(frozen=True)
class FusionThresholds:
    """Contact thresholds (all ≥ 0; a value must be *strictly above* its threshold).

    Attributes:
        noise_floor_pa: a taxel is in contact iff its pressure > this (Pa).
        min_normal_force_n: contact iff ``f_n`` > this (N).
        min_pressure_sum_pa: contact iff the summed in-contact pressure > this (Pa).
    """

    noise_floor_pa: float = 0.0
    min_normal_force_n: float = 0.0
    min_pressure_sum_pa: float = 0.0

    def __post_init__(self) -> None:
        for name in ("noise_floor_pa", "min_normal_force_n", "min_pressure_sum_pa"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ConfigError(f"fusion threshold {name} must be a finite number >= 0, got {v!r}")


@dataclass(frozen=True, eq=False, slots=True)
class FusionResult:
    """One fused contact sample (pad frame F, SI units). Satisfies the slip tests' contact protocol.

    Attributes:
        phi: (N,) local normal force per taxel, N (zeros without contact). Read-only.
        f_n: normal force pressing the pad, N (0 without contact).
        f_t: (2,) tangential load, N.
        tau: torque about z through the pad origin, N·m.
        cop: (2,) centre of pressure ``Σ φ_i p_i / f_n``, m ((0, 0) without contact).
        mask: (N,) bool, taxels above the noise floor (after clipping). Read-only.
        n_contact: number of taxels in the mask.
        contact_area_m2: ``n_contact · h²``.
        positions: (N, 2) taxel positions, m (the pad's read-only array).
        n_nonfinite: taxels that were NaN/Inf and were set to 0.
        n_negative: taxels that were negative and were set to 0.
        n_saturated: in-contact taxels flagged saturated by the driver (shape is then unreliable).
        stamp_offset_ns: wrench stamp − tactile stamp (ns), ``None`` if not given:
            which samples were paired.
        status: OK, CLIPPED_INPUT (usable, some taxels clipped), NO_CONTACT, or
            INVALID_INPUT (bad wrench or pressure shape).
    """

    phi: np.ndarray
    f_n: float
    f_t: np.ndarray
    tau: float
    cop: np.ndarray
    mask: np.ndarray
    n_contact: int
    contact_area_m2: float
    positions: np.ndarray
    n_nonfinite: int = 0
    n_negative: int = 0
    n_saturated: int = 0
    stamp_offset_ns: int | None = None
    status: SolverStatus = field(default=SolverStatus.OK)


_SUM_CANNOT_OVERFLOW = sys.float_info.max / 2
"""``n·peak`` of non-negative pressures at or below which their sum cannot overflow (the
rounding of a pairwise sum adds far less than a factor 2), so it needs no ``np.errstate``
(a costly context at every tactile frame)."""
_sum = np.add.reduce
"""``a.sum()`` of a 1-D array without ndarray.sum's Python wrapper (the same pairwise
sum, so the same bits, at two thirds of the cost: fusion sums at every sample)."""


def _frozen(a: np.ndarray) -> np.ndarray:
    a.setflags(write=False)
    return a


@dataclass(frozen=True, eq=False, slots=True)
class PressureShape:
    """The tactile half of fusion: one frame's cleaned pressure shape (pad frame F).

    It depends on the tactile frame alone, so a node computes it once per frame and
    fuses it with every wrench that frame is paired with (:func:`fuse_shape`).

    Attributes:
        shape: (N,) pressure over its peak (dimensionless, in [0, 1]; 0 outside the
            mask), so that its sum neither overflows nor underflows. Read-only.
        shape_sum: ``Σ shape`` (≥ 1 with contact, 0 without).
        cop: (2,) centre of pressure ``Σ shape_i p_i / Σ shape``, m ((0, 0) without contact).
        mask: (N,) bool, taxels above the noise floor (after clipping). Read-only.
        pressure_sum_pa: summed in-contact pressure, Pa (``inf`` if it overflows).
        n_nonfinite, n_negative: taxels that were NaN/Inf or negative and were set to 0.
        n_saturated: in-contact taxels flagged saturated by the driver.
        valid: False when the frame does not match the pad (wrong number of taxels).
        n_contact: number of taxels in the mask.
    """

    shape: np.ndarray
    shape_sum: float
    cop: np.ndarray
    mask: np.ndarray
    pressure_sum_pa: float
    n_nonfinite: int = 0
    n_negative: int = 0
    n_saturated: int = 0
    valid: bool = True
    n_contact: int = 0


def pressure_shape(
    pressure_pa: np.ndarray,
    pad: PadGeometry,
    thresholds: FusionThresholds = FusionThresholds(),
    *,
    saturated: np.ndarray | None = None,
) -> PressureShape:
    """Clean one tactile frame and normalise its shape (docs/math.md §2); never raises.

    Args:
        pressure_pa: (N,) or (R, C) calibrated pressure per taxel, Pa, row-major.
        pad: the pad geometry.
        thresholds: the noise floor applies here.
        saturated: optional (N,) bool raw-count saturation mask from the driver.

    Returns:
        :class:`PressureShape`. NaN/Inf and negative taxels are set to 0 and counted.
    """
    n = pad.n_taxels
    w = np.array(pressure_pa, dtype=float).reshape(-1)
    if w.shape != (n,):
        empty = np.zeros(n)
        return PressureShape(_frozen(empty), 0.0, np.zeros(2), _frozen(np.zeros(n, dtype=bool)), 0.0, valid=False)
    mask, n_nonfinite, n_negative, n_contact, peak = _clean_pressure(w, float(thresholds.noise_floor_pa))
    n_sat = 0
    if saturated is not None:
        sat = np.asarray(saturated, dtype=bool).reshape(-1)
        if sat.size == n:
            n_sat = int(np.count_nonzero(sat & mask))
    if peak * n <= _SUM_CANNOT_OVERFLOW:
        total = float(_sum(w))
    else:
        with np.errstate(over="ignore"):
            total = float(_sum(w))  # inf for absurd pressures: only compared with the threshold
    if peak > 0.0:
        w /= peak  # in [0, 1]: Σ neither overflows (huge pressures) nor underflows (tiny ones)
        shape_sum = float(_sum(w))
        cop = w @ pad.positions / shape_sum
    else:
        shape_sum, cop = 0.0, np.zeros(2)
    return PressureShape(_frozen(w), shape_sum, _frozen(cop), _frozen(mask), total, n_nonfinite, n_negative, n_sat,
                         n_contact=n_contact)


@njit(**JIT)
def _clean_pressure(w, noise_floor_pa):
    """Clean the pressures ``w`` (Pa, a 1-D float64 copy) in place, in one pass (compiled).

    NaN/Inf and negative taxels are set to 0 and counted; every taxel not above
    ``noise_floor_pa`` is set to 0. Returns ``(mask, n_nonfinite, n_negative, n_contact,
    peak)``: the taxels above the floor (a new bool array), the counts, the number in the
    mask and the largest pressure left (0 without contact). It replaces a dozen numpy
    calls at every tactile frame (isfinite, the comparisons, their counts, where, max)
    with the same element-wise operations, so every number is as before.
    """
    mask = np.empty(w.size, np.bool_)
    n_nonfinite = 0
    n_negative = 0
    n_contact = 0
    peak = 0.0
    for i in range(w.size):
        v = w[i]
        if not math.isfinite(v):
            n_nonfinite += 1
            v = 0.0
        elif v < 0.0:
            n_negative += 1
            v = 0.0
        in_contact = v > noise_floor_pa
        mask[i] = in_contact
        if in_contact:
            n_contact += 1
            peak = max(peak, v)
        else:
            w[i] = 0.0
    return mask, n_nonfinite, n_negative, n_contact, peak


def compile_kernels() -> None:
    """Compile the kernel of :func:`pressure_shape`, or load it from numba's cache; the
    fusion node calls it in ``start``, so its first tactile frame runs at full speed."""
    _clean_pressure(np.array([-1.0, math.nan, 0.0, 3.0]), 1.0)


def fuse_shape(
    shape: PressureShape,
    force: np.ndarray,
    torque: np.ndarray,
    pad: PadGeometry,
    thresholds: FusionThresholds = FusionThresholds(),
    *,
    mount: SensorMount | None = None,
    tactile_stamp_ns: int | None = None,
    wrench_stamp_ns: int | None = None,
) -> FusionResult:
    """Fuse a frame's :class:`PressureShape` with an F/T wrench: ``φ_i = f_n·shape_i/Σ shape``.

    Args:
        shape: from :func:`pressure_shape` (the same pad).
        force: (3,) force the object exerts on the pad, N, in F (or in S if ``mount``).
        torque: (3,) torque, N·m, about F's origin in F (or about S's origin in S).
        pad: the pad geometry.
        thresholds: the normal-force and pressure-sum thresholds apply here.
        mount: if given, ``force``/``torque`` are in the sensor frame and are moved to F
            with :func:`wrench_to_pad`.
        tactile_stamp_ns, wrench_stamp_ns: stamps of the paired samples (integer ns).

    Returns:
        :class:`FusionResult`; never raises.
    """
    offset = None
    if tactile_stamp_ns is not None and wrench_stamp_ns is not None:
        offset = int(wrench_stamp_ns) - int(tactile_stamp_ns)
    f3 = np.asarray(force, dtype=float).reshape(-1)
    t3 = np.asarray(torque, dtype=float).reshape(-1)
    f_list = t_list = None
    if f3.shape == (3,) and t3.shape == (3,):
        f_list, t_list = f3.tolist(), t3.tolist()
    if not shape.valid or f_list is None or not _all_finite(f_list + t_list):
        n = pad.n_taxels
        return _empty(pad, np.zeros(n), np.zeros(n, dtype=bool), 0, 0, 0, 0, offset, SolverStatus.INVALID_INPUT)
    if mount is not None:
        f3, t3 = wrench_to_pad(f3, t3, np.asarray(mount.R_FS), np.asarray(mount.p_SF))
        f_list, t_list = f3.tolist(), t3.tolist()
    counts = (shape.n_nonfinite, shape.n_negative, shape.n_saturated)
    f_x, f_y, f_z = f_list
    tau = t_list[2]
    f_n = -f_z
    if not (f_n > thresholds.min_normal_force_n and shape.pressure_sum_pa > thresholds.min_pressure_sum_pa
            and shape.shape_sum > 0.0):
        return _empty(pad, np.zeros(pad.n_taxels), shape.mask, shape.n_contact, *counts, offset,
                      SolverStatus.NO_CONTACT, f_t=(f_x, f_y), tau=tau)
    phi = shape.shape * (f_n / shape.shape_sum)
    status = SolverStatus.CLIPPED_INPUT if (shape.n_nonfinite or shape.n_negative) else SolverStatus.OK
    return _result(pad, phi, np.array((f_x, f_y)), tau, shape.cop, shape.mask, shape.n_contact, *counts, offset,
                   status)


def _all_finite(values: list[float]) -> bool:
    """Whether every value is finite: ``np.isfinite(a).all()`` for a 3-vector's
    ``tolist()``, at a tenth of its cost (two of them at every F/T sample)."""
    return all(map(math.isfinite, values))


def ft_understates_pad(shape: PressureShape, pad: PadGeometry, f_n: float, *, ratio: float,
                       min_pad_force_n: float) -> bool:
    """Whether the F/T normal force ``f_n`` (N) is implausibly small for the pressed pad.

    The pad's own estimate of the normal force is ``Σ p_i h²`` over the taxels in
    contact (N; ``h`` the pitch). A biased or spoofed F/T sensor that reads (near) zero
    while the pad is pressed would make every consumer conclude "no load" and release
    the grip; this flags it: true when the pad's force exceeds ``min_pad_force_n`` and
    ``f_n < pad force / ratio``. Only that direction is checked: an F/T reading
    *larger* than the pad's only makes the grip firmer. ``ratio`` > 1 allows for the
    tactile calibration's error (the simulated rig agrees within 4 %; real tactile
    arrays are often off by tens of percent); ``ratio <= 0`` disables the check.
    """
    if ratio <= 0.0 or not shape.valid:
        return False
    pad_force_n = shape.pressure_sum_pa * pad.taxel_area_m2
    return pad_force_n > min_pad_force_n and f_n * ratio < pad_force_n


def fuse(
    pressure_pa: np.ndarray,
    force: np.ndarray,
    torque: np.ndarray,
    pad: PadGeometry,
    thresholds: FusionThresholds = FusionThresholds(),
    *,
    mount: SensorMount | None = None,
    saturated: np.ndarray | None = None,
    tactile_stamp_ns: int | None = None,
    wrench_stamp_ns: int | None = None,
) -> FusionResult:
    """Fuse calibrated taxel pressures with an F/T wrench (docs/math.md §2):
    :func:`pressure_shape` then :func:`fuse_shape` (see them for the arguments).

    Returns:
        :class:`FusionResult`; never raises. NaN/Inf and negative taxels are set
        to 0 and counted.
    """
    return fuse_shape(pressure_shape(pressure_pa, pad, thresholds, saturated=saturated), force, torque, pad,
                      thresholds, mount=mount, tactile_stamp_ns=tactile_stamp_ns, wrench_stamp_ns=wrench_stamp_ns)


def _result(pad, phi, f_t, tau, cop, mask, n_contact, n_nonfinite, n_negative, n_sat, offset, status) -> FusionResult:
    return FusionResult(
        phi=_frozen(phi),
        f_n=float(_sum(phi)),
        f_t=_frozen(np.asarray(f_t, dtype=float)),
        tau=float(tau),
        cop=_frozen(cop),
        mask=_frozen(mask),
        n_contact=n_contact,
        contact_area_m2=n_contact * pad.taxel_area_m2,
        positions=pad.positions,
        n_nonfinite=n_nonfinite,
        n_negative=n_negative,
        n_saturated=n_sat,
        stamp_offset_ns=offset,
        status=status,
    )


def _empty(pad, zeros, mask, n_contact, n_nonfinite, n_negative, n_sat, offset, status, f_t=None,
           tau=0.0) -> FusionResult:
    ft = np.zeros(2) if f_t is None else np.array(f_t, dtype=float)
    return _result(pad, zeros, ft, tau, np.zeros(2), mask.copy(), n_contact, n_nonfinite, n_negative, n_sat, offset,
                   status)
