"""Compiled per-taxel arithmetic of one bristle-friction step (see lib/rig/friction.py).

More in docs/modules.md, `lib/rig/bristle_kernels.py`.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
from numba import config as numba_config
from numba import njit
from numba.core import types
from numba.extending import intrinsic

from slipstack.lib.weber import JIT

__all__ = ["complex_abs", "finish_sliding", "linearise_sliding", "advance", "limit_slip_damping", "release_over_cap",
           "slide_caps", "stick_arrays", "surface_velocity", "take_normal_forces", "restart_weakening",
           "caps_and_stick_arrays", "count_sliding", "new_normal_forces", "end_step", "deflection_square_sum", "elastic_twist",
           "N_TAXEL_ROWS", "MU_S", "MU_D", "SLIP", "WEAKENING", "PHI", "CAP_STATIC", "CAP_DYNAMIC", "CAP_WEAKENING",
           "CAP_SLIDE", "CAP_SLIDE_TOL", "CAP_STICK", "DT_SLIDE_MASK", "STICK_STIFFNESS", "SPEED_N", "STICK_DAMPING",
           "DAMPING", "SLIDE_MASK", "SPEED_AVG", "N_FLAG_ROWS", "SLIDING", "CONTACT", "N_VECTOR_ROWS", "POSITION",
           "DEFLECTION", "FORCE", "U_N", "U_PREV", "U_AVG", "EXPLICIT"]

_TINY_SPEED = 1e-300
"""Floor of a speed used as a divisor (m/s): a direction from a zero velocity is 0."""


def _exact_fused_multiply_add(a: float, b: float, c: float) -> float:
    """``a·b + c`` rounded once, in Python (exact rationals; the float conversion rounds
    to nearest): what the FMA instruction gives, for interpreted runs."""
    return float(Fraction(a) * Fraction(b) + Fraction(c))


@intrinsic
def _fma_instruction(typingctx, a, b, c):
    """``a·b + c`` rounded once: the FMA instruction, as numpy's SIMD loops use it."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        return builder.fma(*args)

    return sig, codegen


# NUMBA_DISABLE_JIT=1 (the mutation runner's --interpreted) cannot call an intrinsic
_fused_multiply_add = _exact_fused_multiply_add if numba_config.DISABLE_JIT else _fma_instruction


@njit(**JIT)
def complex_abs(z: complex) -> float:
    """``|z|`` computed as numpy's vectorised ``abs`` does: ``l·sqrt(fma(s/l, s/l, 1))``
    with ``l, s`` the larger and smaller of ``|Re z|, |Im z|`` (0 for z = 0; inf if a
    part is infinite; NaN if a part is NaN and none is infinite)."""
    re = abs(z.real)
    im = abs(z.imag)
    if re == math.inf or im == math.inf:
        return math.inf
    if re != re or im != im:
        return math.nan
    larger = max(re, im)
    if larger == 0.0:
        return 0.0
    ratio = min(re, im) / larger
    return math.sqrt(_fused_multiply_add(ratio, ratio, 1.0)) * larger


@njit(**JIT)
def surface_velocity(v_origin: complex, omega: float, positions: np.ndarray, u_out: np.ndarray) -> None:
    """Surface velocity over each taxel ``u_i = v_0 + i·ω·p_i`` (m/s).

    Args:
        v_origin: velocity of the body point over the pad origin (complex, m/s).
        omega: angular rate (rad/s).
        positions: taxel centres ``p_i`` (complex, m).
        u_out: receives ``u_i``.
    """
    spin = 1j * omega
    for i in range(positions.shape[0]):
        u_out[i] = v_origin + spin * positions[i]


@njit(**JIT)
def advance(e: np.ndarray, damping: np.ndarray, u_avg: np.ndarray, z: np.ndarray, dt: float,
            q_out: np.ndarray, z_out: np.ndarray) -> None:
    """Forces of the step ``q_i = e_i − D_i ū_i`` (N) and the stuck deflections moved
    by the step, ``z_i + dt·ū_i`` (m)."""
    for i in range(u_avg.shape[0]):
        u = u_avg[i]
        q_out[i] = e[i] - damping[i] * u
        z_out[i] = z[i] + dt * u


@njit(**JIT)
def linearise_sliding(u_n: np.ndarray, u_prev: np.ndarray, sliding: np.ndarray, cap_slide: np.ndarray,
                      stick_damping: np.ndarray, v_reg: float, speed_n_out: np.ndarray,
                      damping_out: np.ndarray) -> None:
    """Damping ``D_i`` of the coming step while some taxel slides (N·s/m).

    Slipping taxels: ``D_i = cap_i / ŝ_i`` with the expected mid-step speed
    ``ŝ_i = max(|1.5 u_n − 0.5 u_prev|, |u_n|, v_reg)``; sticking ones keep
    ``stick_damping``. ``speed_n_out`` receives ``|u_n|`` of the slipping taxels (the
    only ones :func:`finish_sliding` reads; most taxels stick, and their two magnitudes
    were most of this kernel's time).
    """
    for i in range(u_n.shape[0]):
        if not sliding[i]:
            damping_out[i] = stick_damping[i]
            continue
        speed_n = complex_abs(u_n[i])
        speed_n_out[i] = speed_n
        speed = complex_abs(1.5 * u_n[i] - 0.5 * u_prev[i])
        speed = max(speed, speed_n)
        speed = max(speed, v_reg)
        damping_out[i] = cap_slide[i] / speed


@njit(**JIT)
def limit_slip_damping(damping: np.ndarray, u_avg: np.ndarray, cap_slide_tol: np.ndarray,
                       cap_slide: np.ndarray, speed_out: np.ndarray, damping_out: np.ndarray) -> bool:
    """Cap check of the slipping taxels after a solve.

    ``speed_out`` receives ``|ū_i|``. Where ``D_i |ū_i| > cap_tol_i`` (a slipping
    patch over its cap plus slack; sticking taxels have an infinite tolerance),
    ``damping_out`` gets ``cap_i / |ū_i|``, elsewhere ``D_i``. Returns True if any
    taxel was over (``damping_out`` then differs from ``damping``).
    """
    over_any = False
    for i in range(u_avg.shape[0]):
        speed = complex_abs(u_avg[i])
        speed_out[i] = speed
        if damping[i] * speed > cap_slide_tol[i]:
            over_any = True
            damping_out[i] = cap_slide[i] / max(speed, _TINY_SPEED)
        else:
            damping_out[i] = damping[i]
    return over_any


@njit(**JIT)
def finish_sliding(u_avg: np.ndarray, u_n: np.ndarray, speed: np.ndarray, speed_n: np.ndarray,
                   sliding: np.ndarray, cap_slide: np.ndarray, inv_k: float, v_stick: float,
                   z_new: np.ndarray, s: np.ndarray) -> int:
    """Deflection and re-sticking of the slipping taxels at the end of a step.

    A slipping bristle rests along the slip velocity, ``z_i = ū_i·cap_i/(k |ū_i|)``,
    written into ``z_new``. It sticks again when the velocity reverses within the
    step (``Re(ū_i·conj(u_n,i)) ≤ 0``) or falls below ``v_stick`` while decelerating;
    such taxels leave ``sliding`` and their slip distance ``s`` restarts at 0.

    Returns:
        The number of taxels that stuck again.
    """
    restuck = 0
    for i in range(u_avg.shape[0]):
        if not sliding[i]:
            continue
        u = u_avg[i]
        z_new[i] = u * (cap_slide[i] * inv_k / max(speed[i], _TINY_SPEED))
        un = u_n[i]
        reversed_ = u.real * un.real + u.imag * un.imag <= 0.0
        if reversed_ or (speed[i] < v_stick and speed[i] < speed_n[i]):
            sliding[i] = False
            s[i] = 0.0
            restuck += 1
    return restuck


@njit(**JIT)
def release_over_cap(q: np.ndarray, cap_stick: np.ndarray, cap_static: np.ndarray, k: float,
                     z_new: np.ndarray, sliding: np.ndarray, s: np.ndarray) -> int:
    """Sticking taxels whose force ``|q_i|`` exceeds the static cap start to slip.

    Their deflection shrinks to the static cap along itself (``|z| ≤ cap/k``: never
    raised), they enter ``sliding`` with slip distance 0. ``cap_stick`` is infinite
    for taxels already slipping (skipped). Returns the number of taxels released.
    """
    released = 0
    for i in range(q.shape[0]):
        if cap_stick[i] != math.inf and complex_abs(q[i]) > cap_stick[i]:  # |q| > inf is never true
            mag = complex_abs(z_new[i])
            z_new[i] *= min(1.0, (cap_static[i] / k) / max(mag, _TINY_SPEED))
            sliding[i] = True
            s[i] = 0.0
            released += 1
    return released


@njit(**JIT)
def take_normal_forces(phi: np.ndarray, mu_s: np.ndarray, mu_d: np.ndarray, contact: np.ndarray,
                       z: np.ndarray, s: np.ndarray, sliding: np.ndarray, cap_static_out: np.ndarray,
                       cap_dynamic_out: np.ndarray, cap_weakening_out: np.ndarray) -> int:
    """New normal forces ``φ_i`` (N): the contact set and the static and dynamic caps.

    A taxel entering or leaving contact (``φ_i > 0``) restarts relaxed and sticking
    (``z = 0``, ``s = 0``). Writes ``μ_s φ``, ``μ_d φ`` and their difference (N).
    Returns the number of taxels whose contact changed.
    """
    changed = 0
    for i in range(phi.shape[0]):
        touching = phi[i] > 0.0
        if touching != contact[i]:
            contact[i] = touching
            z[i] = 0j
            s[i] = 0.0
            sliding[i] = False
            changed += 1
        cap_static = mu_s[i] * phi[i]
        cap_dynamic = mu_d[i] * phi[i]
        cap_static_out[i] = cap_static
        cap_dynamic_out[i] = cap_dynamic
        cap_weakening_out[i] = cap_static - cap_dynamic
    return changed


@njit(**JIT)
def slide_caps(cap_dynamic: np.ndarray, cap_weakening: np.ndarray, weakening: np.ndarray,
               sliding: np.ndarray, cap_slide_out: np.ndarray, cap_slide_tol_out: np.ndarray) -> None:
    """Slip-weakened caps ``μ_d φ + (μ_s − μ_d) φ·weakening`` (N), ``weakening = exp(−s/d_c)``;
    the checked cap is 1.001 times that for slipping taxels, infinite for sticking ones."""
    for i in range(cap_dynamic.shape[0]):
        cap = cap_dynamic[i] + cap_weakening[i] * weakening[i]
        cap_slide_out[i] = cap
        cap_slide_tol_out[i] = 1.001 * cap if sliding[i] else math.inf


@njit(**JIT)
def stick_arrays(sliding: np.ndarray, contact: np.ndarray, phi: np.ndarray, cap_static: np.ndarray,
                 stick_damping: float, k: float, dt: float, cap_stick_out: np.ndarray,
                 slide_mask_out: np.ndarray, dt_slide_mask_out: np.ndarray, stick_damping_out: np.ndarray,
                 stick_stiffness_out: np.ndarray) -> None:
    """Per-taxel coefficients that change only when the stick/slip set or ``φ`` changes.

    Writes: ``cap_stick`` (static cap of sticking taxels, inf if slipping), the slip mask
    (1.0/0.0) and ``dt`` times it, and for sticking taxels in contact the damping
    ``c + k dt/2`` and stiffness ``−k`` of the step (0 elsewhere).
    """
    for i in range(sliding.shape[0]):
        slide = sliding[i]
        mask = 1.0 if slide else 0.0
        stick = contact[i] and not slide
        cap_stick_out[i] = math.inf if slide else cap_static[i]
        slide_mask_out[i] = mask
        dt_slide_mask_out[i] = dt * mask
        stick_damping_out[i] = stick_damping * stick
        stick_stiffness_out[i] = -k * stick



@njit(**JIT)
def elastic_twist(z: np.ndarray, positions: np.ndarray, contact: np.ndarray) -> tuple[complex, float]:
    """The rigid displacement ``u(p) = t + i·ω·p`` nearest the deflections ``z_i`` of the taxels in
    contact (least squares): ``(t`` complex m, ``ω`` rad); zero with fewer than two taxels."""
    n = 0
    zx = zy = px = py = 0.0
    for i in range(z.shape[0]):
        if contact[i]:
            n += 1
            zx += z[i].real
            zy += z[i].imag
            px += positions[i].real
            py += positions[i].imag
    if n < 2:
        return 0j, 0.0
    zx /= n
    zy /= n
    px /= n
    py /= n
    cross = spread = 0.0
    for i in range(z.shape[0]):
        if contact[i]:
            dx = positions[i].real - px
            dy = positions[i].imag - py
            cross += dx * (z[i].imag - zy) - dy * (z[i].real - zx)
            spread += dx * dx + dy * dy
    omega = cross / spread if spread > 0.0 else 0.0
    return complex(zx + omega * py, zy - omega * px), omega


@njit(**JIT)
def deflection_square_sum(z: np.ndarray, contact: np.ndarray) -> float:
    """``Σ |z_i|²`` over the taxels in contact (m²), in taxel order."""
    total = 0.0
    for i in range(z.shape[0]):
        if contact[i]:
            total += z[i].real * z[i].real + z[i].imag * z[i].imag
    return total


# ------------------------------------------------------------------ the per-taxel state tables
#
# The plant step (lib/rig/plant_kernel.py) and the kernels below read and write
# BristleField's per-taxel state in three tables with named rows rather than as
# two dozen arrays: every array argument costs its unboxing on each call.

N_TAXEL_ROWS = 18
"""Rows of the float table (shape (N_TAXEL_ROWS, N)) of per-taxel state:"""
MU_S, MU_D = 0, 1
"""Static and dynamic friction coefficients."""
SLIP = 2
"""Distance slid since the taxel last stuck ``s`` (m)."""
WEAKENING = 3
"""Slip weakening ``exp(−s/d_c)`` (1 where ``s = 0``)."""
PHI = 4
"""Normal force ``φ`` (N)."""
CAP_STATIC, CAP_DYNAMIC, CAP_WEAKENING = 5, 6, 7
"""``μ_s φ``, ``μ_d φ`` and their difference (N)."""
CAP_SLIDE, CAP_SLIDE_TOL, CAP_STICK = 8, 9, 10
"""Slip cap ``μ(s) φ`` (the static cap while none slides), 1.001 times it for slipping
taxels (inf elsewhere; left as is while none slides), static cap of sticking taxels
(inf for slipping ones) (N)."""
DT_SLIDE_MASK, STICK_STIFFNESS, SPEED_N = 11, 12, 13
"""``dt`` for slipping taxels else 0 (s); ``−k`` for sticking taxels in contact else 0
(N/m); ``|u_n|`` of slipping taxels at the start of the step (m/s)."""
STICK_DAMPING, DAMPING, SLIDE_MASK, SPEED_AVG = 14, 15, 16, 17
"""``c + k dt/2`` for sticking taxels in contact else 0, and the damping ``D`` of the
step being taken (N·s/m); 1.0 for slipping taxels else 0.0; ``|ū|`` of the last cap
check (m/s)."""
N_FLAG_ROWS = 2
"""Rows of the bool table (shape (N_FLAG_ROWS, N)):"""
SLIDING, CONTACT = 0, 1
"""In the slip state; in contact (``φ > 0``)."""
N_VECTOR_ROWS = 7
"""Rows of the complex table (shape (N_VECTOR_ROWS, N)) of planar per-taxel vectors:"""
POSITION, DEFLECTION, FORCE = 0, 1, 2
"""Taxel centre ``p`` (m); bristle deflection ``z`` (m); force of the last step ``q`` on the object (N)."""
U_N, U_PREV, U_AVG, EXPLICIT = 3, 4, 5, 6
"""Surface velocity at the start of the step ``u_n`` and of the step before (m/s), the
mid-point one ``ū`` (m/s); explicit force ``e`` of the step (N)."""


@njit(**JIT)
def restart_weakening(s: np.ndarray, weakening: np.ndarray) -> None:
    """``weakening_i = 1`` where the slip distance restarted (``s_i = 0``): ``exp(−0/d_c)``,
    so the weakening of the other taxels need not be recomputed."""
    for i in range(s.shape[0]):
        if s[i] == 0.0:
            weakening[i] = 1.0


@njit(**JIT)
def caps_and_stick_arrays(n_sliding: int, taxels: np.ndarray, flags: np.ndarray, stick_damping: float, k: float,
                          dt: float) -> None:
    """The slip caps (:func:`slide_caps`; the static caps while no taxel slides, the
    tolerance then left as it is) and :func:`stick_arrays`, after φ or the stick set changed."""
    sliding = flags[SLIDING]
    if n_sliding:
        slide_caps(taxels[CAP_DYNAMIC], taxels[CAP_WEAKENING], taxels[WEAKENING], sliding, taxels[CAP_SLIDE],
                   taxels[CAP_SLIDE_TOL])
    else:
        taxels[CAP_SLIDE][:] = taxels[CAP_STATIC]
    stick_arrays(sliding, flags[CONTACT], taxels[PHI], taxels[CAP_STATIC], stick_damping, k, dt, taxels[CAP_STICK],
                 taxels[SLIDE_MASK], taxels[DT_SLIDE_MASK], taxels[STICK_DAMPING], taxels[STICK_STIFFNESS])


@njit(**JIT)
def count_sliding(sliding: np.ndarray) -> int:
    """Number of taxels in the slip state."""
    n_sliding = 0
    for i in range(sliding.shape[0]):
        n_sliding += sliding[i]
    return n_sliding


@njit(**JIT)
def new_normal_forces(f_n: float, shape: np.ndarray, n_sliding: int, stick_damping: float, k: float, dt: float,
                      taxels: np.ndarray, flags: np.ndarray, vectors: np.ndarray) -> int:
    """Normal forces ``φ_i = f_n·shape_i`` (N) into the ``PHI`` row, :func:`take_normal_forces`
    of them, then :func:`caps_and_stick_arrays`.

    Returns:
        The new number of slipping taxels.
    """
    phi = taxels[PHI]
    for i in range(shape.shape[0]):
        phi[i] = f_n * shape[i]
    sliding = flags[SLIDING]
    if take_normal_forces(phi, taxels[MU_S], taxels[MU_D], flags[CONTACT], vectors[DEFLECTION], taxels[SLIP],
                          sliding, taxels[CAP_STATIC], taxels[CAP_DYNAMIC], taxels[CAP_WEAKENING]):
        n_sliding = count_sliding(sliding)
        restart_weakening(taxels[SLIP], taxels[WEAKENING])
    caps_and_stick_arrays(n_sliding, taxels, flags, stick_damping, k, dt)
    return n_sliding


@njit(**JIT)
def end_step(n_sliding: int, stick_damping: float, k: float, dt: float, v_stick: float, taxels: np.ndarray,
             flags: np.ndarray, vectors: np.ndarray) -> int:
    """The end of a step after the forces ``q``, the moved deflections and the new slip
    distances and weakening: while some taxel slides, its caps (:func:`slide_caps`) and
    :func:`finish_sliding`; then :func:`release_over_cap`. If the stick set changed,
    :func:`caps_and_stick_arrays` again.

    Returns:
        The new number of slipping taxels.
    """
    sliding, s, z_new = flags[SLIDING], taxels[SLIP], vectors[DEFLECTION]
    changed = False
    if n_sliding:
        slide_caps(taxels[CAP_DYNAMIC], taxels[CAP_WEAKENING], taxels[WEAKENING], sliding, taxels[CAP_SLIDE],
                   taxels[CAP_SLIDE_TOL])
        changed = finish_sliding(vectors[U_AVG], vectors[U_N], taxels[SPEED_AVG], taxels[SPEED_N], sliding,
                                 taxels[CAP_SLIDE], 1.0 / k, v_stick, z_new, s) > 0
    # only sticking taxels have a finite cap here
    if release_over_cap(vectors[FORCE], taxels[CAP_STICK], taxels[CAP_STATIC], k, z_new, sliding, s):
        changed = True
    if not changed:
        return n_sliding
    n_sliding = count_sliding(sliding)
    restart_weakening(s, taxels[WEAKENING])
    caps_and_stick_arrays(n_sliding, taxels, flags, stick_damping, k, dt)
    return n_sliding
