"""Planar rigid body under the pad, integrated only in its free degrees of freedom.

State, in the pad frame ``F`` (complex numbers ``x + i·y`` for planar vectors): the
centre of mass ``o`` (m), the angle ``θ`` (rad), and the twist about a *reference
point* ``r``: the velocity ``v_r`` of the body point at ``r`` and the rate ``ω``. The
reference point is the centre of mass, or the fixed pivot of a rotation-only rig
(the paper's Fig. 13). The velocity of the body point at ``p`` is
``v_r + i·ω·(p − r)`` (``i·d`` is ``perp(d)`` of docs/math.md §1).

More in docs/modules.md, `lib/rig/body.py`.
"""

from __future__ import annotations

import cmath

from numba import njit

from slipstack.lib.rig.scene import DofSpec, ObjectSpec
from slipstack.lib.weber import JIT

__all__ = ["PlanarBody", "mid_point_twist"]


class PlanarBody:
    """The object's planar dynamics.

    Args:
        obj: mass, inertia, initial pose.
        dof: free coordinates and optional pivot.
    """

    def __init__(self, obj: ObjectSpec, dof: DofSpec) -> None:
        x, y, theta = obj.pose
        self.origin = complex(x, y)
        self.theta = float(theta)
        self.v_ref = 0j
        self.omega = 0.0
        self._origin0 = self.origin
        self._theta0 = self.theta
        self._pivot = None if dof.pivot_m is None else complex(*dof.pivot_m)
        self._free = tuple(i for i, n in enumerate(("x", "y", "theta")) if n in dof.free)
        self.mass = obj.mass_kg
        if self._pivot is None:
            self.inertia = obj.inertia_kgm2
        else:
            self.inertia = obj.inertia_kgm2 + obj.mass_kg * abs(self.origin - self._pivot) ** 2
        self.free_mask = tuple(float(i in self._free) for i in range(3))
        """1.0 for a free coordinate among (v_x, v_y, ω), else 0.0."""

    @property
    def free(self) -> tuple[int, ...]:
        """Indices of the free coordinates among (v_x, v_y, ω)."""
        return self._free

    @property
    def reference(self) -> complex:
        """The reference point ``r``: the pivot, else the centre of mass (complex, m)."""
        return self.origin if self._pivot is None else self._pivot

    @property
    def com_velocity(self) -> complex:
        """Velocity of the centre of mass in ``F`` (complex, m/s)."""
        if self._pivot is None:
            return self.v_ref
        return 1j * self.omega * (self.origin - self._pivot)

    def body_point(self, p0: complex) -> complex:
        """Current position of the body point that was at ``p0`` at t = 0 (complex, m)."""
        return self.origin + cmath.exp(1j * (self.theta - self._theta0)) * (p0 - self._origin0)

    def displacement(self) -> tuple[complex, float]:
        """Change of the centre of mass position and angle since t = 0."""
        return self.origin - self._origin0, self.theta - self._theta0

    def kinetic_energy(self) -> float:
        """``½ ξᵀ M ξ`` (J)."""
        return 0.5 * (self.mass * abs(self.v_ref) ** 2 + self.inertia * self.omega**2)

    @property
    def origin_velocity(self) -> complex:
        """Velocity of the body point over the pad origin, ``v_r − i ω r`` (complex, m/s)."""
        return self.v_ref - 1j * self.omega * self.reference

    def commit(self, dt: float, v_mid: complex, omega_mid: float) -> None:
        """Take the step: end twist ``2ξ̄ − ξ_n``, pose moved by ``dt·ξ̄``."""
        self.v_ref = 2.0 * v_mid - self.v_ref
        self.omega = 2.0 * omega_mid - self.omega
        self.theta += dt * omega_mid
        if self._pivot is None:
            self.origin += dt * v_mid
        else:
            self.origin = self._pivot + cmath.exp(1j * (self.theta - self._theta0)) * (
                self._origin0 - self._pivot)


@njit(**JIT)
def mid_point_twist(dt: float, mass: float, inertia: float, free_x: float, free_y: float, free_r: float,
                    r: complex, v_ref: complex, omega: float, s: float, sp: complex, spp: float, s_rot: float,
                    force: complex, tau: float) -> tuple[complex, float]:
    """One implicit mid-point velocity step of the body; returns the mid-point twist ``(v̄_r, ω̄)``.

    Args:
        dt: step (s).
        mass, inertia: ``M``'s diagonal (kg, kg·m² about ``r``).
        free_x, free_y, free_r: :attr:`PlanarBody.free_mask`.
        r: the reference point (complex, m); v_ref, omega: the twist ``ξ_n`` at the
            start of the step (complex m/s, rad/s).
        s, sp, spp: ``Σ D`` (N·s/m), ``Σ D p`` (N·s), ``Σ D |p|²`` (N·m·s) of the
            linearised point forces, about the pad origin.
        s_rot: rotational damping (N·m·s/rad).
        force, tau: explicit force (complex N) and torque about the pad origin (N·m).

    The constrained coordinates stay zero. Pure: :meth:`PlanarBody.commit` takes the
    step (the caller may re-solve with corrected damping first).
    """
    sd = sp - r * s  # Σ D (p − r)
    srr = spp - 2.0 * (r.conjugate() * sp).real + (r.real * r.real + r.imag * r.imag) * s + s_rot
    tau -= (r.conjugate() * force).imag
    # K = [[s, 0, −sd_y], [0, s, sd_x], [−sd_y, sd_x, srr]]; A = M + dt/2·K;
    # b = dt·(g − K ξ_n). Eliminate the rotation by its Schur complement.
    vx, vy, w = v_ref.real, v_ref.imag, omega
    kx, ky = -sd.imag, sd.real
    h = 0.5 * dt
    a = mass + h * s
    bx = dt * (force.real - s * vx - kx * w)
    by = dt * (force.imag - s * vy - ky * w)
    dx = dy = dw = 0.0
    if free_r:
        px, py = h * kx * free_x, h * ky * free_y
        c = inertia + h * srr - (px * px + py * py) / a
        bt = dt * (tau - kx * vx - ky * vy - srr * w) - (px * bx * free_x + py * by * free_y) / a
        dw = bt / c
        bx -= px * dw
        by -= py * dw
    if free_x:
        dx = bx / a
    if free_y:
        dy = by / a
    return complex(vx + 0.5 * dx, vy + 0.5 * dy), w + 0.5 * dw
