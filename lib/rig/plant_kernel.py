"""The rig's plant step as one compiled call: bristle friction and body together.

More in docs/modules.md, `lib/rig/plant_kernel.py`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from slipstack.lib.rig.bristle_kernels import (
    CAP_SLIDE, CAP_SLIDE_TOL, CONTACT, DAMPING, DEFLECTION, DT_SLIDE_MASK, EXPLICIT, FORCE, N_FLAG_ROWS, N_TAXEL_ROWS,
    N_VECTOR_ROWS, PHI, POSITION, SLIDE_MASK, SLIDING, SLIP, SPEED_AVG, SPEED_N, STICK_DAMPING, STICK_STIFFNESS, U_AVG,
    U_N, U_PREV, WEAKENING, advance, complex_abs, deflection_square_sum, end_step, limit_slip_damping,
    linearise_sliding, new_normal_forces, surface_velocity)
from slipstack.lib.rig.body import mid_point_twist
from slipstack.lib.weber import JIT

__all__ = ["MAX_CAP_PASSES", "N_CONSTANTS", "force_sums", "plant_step", "compile_kernels"]

MAX_CAP_PASSES = 4
"""Solves per step at most: the last one is taken even if a cap is still exceeded."""

N_CONSTANTS = 11
"""Length of ``constants``: ``k`` (N/m), ``dt`` (s), the stick damping ``c + k dt/2``
(N·s/m), ``v_reg``, ``v_stick`` (m/s), ``−1/d_c`` (1/m), the body's mass (kg) and
inertia (kg·m²), its free mask ``(x, y, θ)`` (1.0 free, 0.0 held)."""


@njit(**JIT)
def _damping_sums(damping: np.ndarray, positions: np.ndarray) -> tuple[float, complex, float]:
    """``(Σ D, Σ D p, Σ D |p|²)`` over the taxels (N·s/m, N·s, N·m·s)."""
    s = spx = spy = spp = 0.0
    for i in range(damping.shape[0]):
        d = damping[i]
        p = positions[i]
        s += d
        spx += d * p.real
        spy += d * p.imag
        spp += d * (p.real * p.real + p.imag * p.imag)
    return s, complex(spx, spy), spp


@njit(**JIT)
def force_sums(forces: np.ndarray, positions: np.ndarray) -> tuple[complex, float]:
    """``(Σ f_i, Σ p_i × f_i)`` of per-taxel forces (complex N, N·m about the pad origin)."""
    fx = fy = tau = 0.0
    for i in range(forces.shape[0]):
        f = forces[i]
        p = positions[i]
        fx += f.real
        fy += f.imag
        tau += p.real * f.imag - p.imag * f.real
    return complex(fx, fy), tau


@njit(**JIT)
def _slip_share(taxels: np.ndarray, q: np.ndarray) -> float:
    """``Σ_slip φ_i |ū_i| min(1, |q_i|/cap_i) / Σ φ_i |ū_i|`` of the last cap check: a
    slipping taxel counts by the share of its cap it transmits (one that decelerates
    within the step transmits less); with the object at rest the slipping share of
    ``f_n``, 0 with no contact (``BristleField.slip_share``)."""
    phi, mask, speed, cap = taxels[PHI], taxels[SLIDE_MASK], taxels[SPEED_AVG], taxels[CAP_SLIDE]
    total = slipping = f_n = f_slip = 0.0
    for i in range(phi.shape[0]):
        weight = speed[i] * phi[i]
        total += weight
        if mask[i] != 0.0:
            slipping += weight * min(1.0, complex_abs(q[i]) / cap[i])
        f_n += phi[i]
        f_slip += phi[i] * mask[i]
    if total > 0.0:
        return min(1.0, slipping / total)
    return f_slip / f_n if f_n > 0.0 else 0.0


@njit(**JIT)
def plant_step(taxels: np.ndarray, flags: np.ndarray, vectors: np.ndarray, constants: np.ndarray, n_sliding: int,
               has_prev: bool, r: complex, v_ref: complex, omega: float, s_ext: float, sp_ext: complex,
               spp_ext: float, s_rot: float, force_ext: complex, tau_ext: float
               ) -> tuple[int, complex, float, float, complex, float]:
    """One step of the bristles and the body, at fixed normal forces.

    1. Linearised contact forces ``q_i = e_i − D_i ū_i`` (friction.py): ``e_i = −k z_i``
       for sticking taxels; while some taxel slides, ``u_n`` and the slip damping
       (:func:`linearise_sliding`; ``has_prev``: ``U_PREV`` holds the last step's ``u_n``).
    2. Up to :data:`MAX_CAP_PASSES` solves of the body's mid-point twist
       (:func:`mid_point_twist`) with ``Σ D``, ``Σ D p``, ``Σ D |p|²`` plus the external
       terms, and ``Σ e`` plus ``force_ext``, ``Σ p × e`` plus ``tau_ext``; after each solve
       the slipping taxels over their cap get ``D_i = cap_i/|ū_i|`` (:func:`limit_slip_damping`)
       and the body is solved again, until none is over.
    3. The slip share of the step (before the stick set changes), the forces ``q``,
       deflections ``z + dt ū``, slip distances and weakening ``exp(−s/d_c)`` of
       slipping taxels, then :func:`end_step` (re-sticking and release).

    Args:
        taxels, flags, vectors: BristleField's tables (updated in place).
        constants: see :data:`N_CONSTANTS`.
        n_sliding: taxels in the slip state at the start of the step.
        has_prev: ``U_PREV`` holds the previous step's ``u_n`` (some taxel slid then).
        r: the body's reference point (complex, m); v_ref, omega: its twist at the
            start of the step (complex m/s, rad/s).
        s_ext, sp_ext, spp_ext, s_rot: damping of the motor and the support about the
            pad origin (N·s/m, N·s, N·m·s) and rotational (N·m·s/rad).
        force_ext, tau_ext: the motor's force (complex N) and its torque about the pad
            origin (N·m).

    Returns:
        ``(n_sliding, v̄_r, ω̄, slip_share, Σ q, Σ p × q)``: slipping taxels at the end,
        the mid-point twist to commit, the slip share, and the sums of the step's
        contact forces on the object (complex N, N·m).
    """
    k, dt, stick_damping, v_reg, v_stick, neg_inv_d_c = (constants[0], constants[1], constants[2], constants[3],
                                                         constants[4], constants[5])
    mass, inertia, free_x, free_y, free_r = constants[6], constants[7], constants[8], constants[9], constants[10]
    positions, z, e = vectors[POSITION], vectors[DEFLECTION], vectors[EXPLICIT]
    u_n, u_avg = vectors[U_N], vectors[U_AVG]
    damping, speed_avg = taxels[DAMPING], taxels[SPEED_AVG]
    stick_stiffness = taxels[STICK_STIFFNESS]
    for i in range(z.shape[0]):
        e[i] = stick_stiffness[i] * z[i]
    if n_sliding:
        u_prev = vectors[U_PREV]
        u_prev[:] = u_n
        surface_velocity(v_ref - 1j * omega * r, omega, positions, u_n)
        linearise_sliding(u_n, u_prev if has_prev else u_n, flags[SLIDING], taxels[CAP_SLIDE],
                          taxels[STICK_DAMPING], v_reg, taxels[SPEED_N], damping)
    else:
        damping[:] = taxels[STICK_DAMPING]
    f_e, tau_e = force_sums(e, positions)
    force = f_e + force_ext
    tau = tau_e + tau_ext
    v_mid = v_ref
    w_mid = omega
    for _ in range(MAX_CAP_PASSES):
        s, sp, spp = _damping_sums(damping, positions)
        v_mid, w_mid = mid_point_twist(dt, mass, inertia, free_x, free_y, free_r, r, v_ref, omega, s + s_ext,
                                       sp + sp_ext, spp + spp_ext, s_rot, force, tau)
        surface_velocity(v_mid - 1j * w_mid * r, w_mid, positions, u_avg)
        if not n_sliding or not limit_slip_damping(damping, u_avg, taxels[CAP_SLIDE_TOL], taxels[CAP_SLIDE],
                                                   speed_avg, damping):
            break
    slip_share = 0.0
    q = vectors[FORCE]
    advance(e, damping, u_avg, z, dt, q, z)
    if n_sliding:
        slip_share = _slip_share(taxels, q)
        s_slid, dt_slide_mask, weakening = taxels[SLIP], taxels[DT_SLIDE_MASK], taxels[WEAKENING]
        for i in range(s_slid.shape[0]):
            if dt_slide_mask[i] != 0.0:
                s_slid[i] += speed_avg[i] * dt_slide_mask[i]
                weakening[i] = math.exp(s_slid[i] * neg_inv_d_c)
    n_sliding = end_step(n_sliding, stick_damping, k, dt, v_stick, taxels, flags, vectors)
    f_q, tau_q = force_sums(q, positions)
    return n_sliding, v_mid, w_mid, slip_share, f_q, tau_q


def compile_kernels() -> None:
    """Compile the kernels the simulator calls (:func:`plant_step`,
    :func:`~slipstack.lib.rig.bristle_kernels.new_normal_forces` and
    :func:`~slipstack.lib.rig.bristle_kernels.deflection_square_sum`), or load them from
    numba's cache (a few seconds the first time after an install, some milliseconds
    after); the kernels they chain are compiled into them."""
    n = 2
    taxels = np.ones((N_TAXEL_ROWS, n))
    flags = np.zeros((N_FLAG_ROWS, n), dtype=bool)
    vectors = np.zeros((N_VECTOR_ROWS, n), dtype=complex)
    constants = np.ones(N_CONSTANTS)
    new_normal_forces(1.0, np.ones(n), 1, 1.0, 1.0, 1e-3, taxels, flags, vectors)
    plant_step(taxels, flags, vectors, constants, 1, True, 0j, 0j, 1.0, 0.0, 0j, 0.0, 0.0, 0j, 0.0)
    deflection_square_sum(vectors[DEFLECTION], flags[CONTACT])
    force_sums(vectors[FORCE][:1], vectors[POSITION][:1])  # a finger's share (a view: its own specialisation)
