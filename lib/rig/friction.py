"""Per-taxel elastic friction ("bristle") model with stick, slip and slip weakening.

Each taxel patch ``i`` in contact (``φ_i > 0``) carries an elastic tangential
deflection ``z_i`` (complex ``x + i·y``, metres, pad frame ``F``): the displacement of
the object's surface point relative to where it stuck. Vectors are complex numbers.

- **Stick**: ``ż_i = u_i`` (``u_i`` the object's surface velocity over taxel ``i``)
  and the force on the object is ``q_i = −k z_i − c u_i`` with ``k = k_t h²``,
  ``c = c_t h²`` (rubber shear stiffness and damping per taxel).
- **Stick → slip** when ``|q_i| > μ_s,i φ_i`` (static limit).
- **Slip**: ``q_i = −μ_i(s_i) φ_i u_i/|u_i|`` opposing the slip velocity, with slip
  weakening ``μ_i(s) = μ_d,i + (μ_s,i − μ_d,i) exp(−s/d_c)``, ``s_i`` the distance slid
  since the patch last stuck (a Dieterich-type characteristic slip distance ``d_c``:
  the static→dynamic drop of the paper's Fig. 4 happens over a slip distance, not
  instantly). The bristle rests at ``z_i = −q_i/k``.
- **Slip → stick** when the relative velocity reverses within a step, or falls below
  ``stick_speed`` while decelerating.

Because the contact edges carry less pressure (Hertz) or larger lever arms (torsion),
they reach their limit first: partial slip precedes gross slip.

Integration (one step of ``dt``, with the body, lib/rig/simulator.py): the forces are
linear in the step's mid-point velocity ``ū_i``: ``q_i = e_i − D_i ū_i`` where

- stick: ``e_i = −k z_i``, ``D_i = c + k dt/2`` — the implicit mid-point rule for the
  spring-damper (``−k (z_n + z_{n+1})/2 − c ū`` with ``z_{n+1} = z_n + dt ū``);
- slip: ``e_i = 0``, ``D_i = μ_i φ_i / max(ŝ_i, v_reg)`` — Coulomb friction with its
  magnitude set from ``ŝ_i``, the mid-step speed extrapolated from the last two steps
  (not below the start-of-step speed), and its direction from ``ū``, so the friction
  power ``q_i·ū_i = −D_i |ū_i|² ≤ 0`` exactly.

The body solves one small linear system for ``ū`` (:mod:`slipstack.lib.rig.body`).
The mid-point rule is A-stable and conserves the stored elastic energy of the linear
stick dynamics exactly, so the step is stable at any contact stiffness; accuracy
needs ``ω_c dt`` well below 1 (``ω_c`` the stiffest contact mode).
"""

from __future__ import annotations

import numpy as np

from slipstack.lib.rig import bristle_kernels as kernels
from slipstack.lib.rig.scene import ContactSpec

__all__ = ["BristleField"]


class BristleField:
    """Bristle states of all taxels of a pad (vectorised over taxels).

    The per-taxel loops run in the compiled kernels of
    :mod:`slipstack.lib.rig.bristle_kernels`; sums over taxels stay numpy's.

    Args:
        spec: friction parameters.
        taxel_area_m2: ``h²`` (m²).
        dt_s: internal step (s).
        rng: draws the per-taxel friction factors ``1 + mu_spread·N(0,1)``.
        n_taxels: number of taxels ``N``.
    """

    def __init__(self, spec: ContactSpec, taxel_area_m2: float, dt_s: float,
                 rng: np.random.Generator, n_taxels: int) -> None:
        self.k = spec.stiffness_N_per_m3 * taxel_area_m2
        self.c = spec.damping_Ns_per_m3 * taxel_area_m2
        self.dt = dt_s
        factor = np.clip(1.0 + spec.mu_spread * rng.standard_normal(n_taxels), 0.5, 1.5)
        self._v_stick = spec.stick_speed_m_s
        self._v_reg = spec.regularisation_speed_m_s
        self._n = n = n_taxels  # arrays allocated per step: np.empty(n) (np.empty_like costs twice its time)
        # the per-taxel state the step kernels share, one row per quantity (rows and
        # units: lib/rig/bristle_kernels.py); the attributes below are views of rows
        self._taxels = np.zeros((kernels.N_TAXEL_ROWS, n))
        self._flags = np.zeros((kernels.N_FLAG_ROWS, n), dtype=bool)
        t = self._taxels
        t[kernels.MU_S] = spec.mu_s * factor
        t[kernels.MU_D] = spec.mu_d * factor
        t[kernels.CAP_SLIDE_TOL] = np.inf
        t[kernels.WEAKENING] = 1.0
        self.mu_s, self.mu_d, self.s = t[kernels.MU_S], t[kernels.MU_D], t[kernels.SLIP]
        self.sliding, self._contact = self._flags[kernels.SLIDING], self._flags[kernels.CONTACT]
        # numpy's exp takes the one to the other between two kernels
        self._weakening, self._weakening_arg = t[kernels.WEAKENING], t[kernels.WEAKENING_ARG]
        # numpy sums (BLAS) read these: arrays of their own, as before
        self.z = np.zeros(n, dtype=complex)
        self.phi = np.zeros(n)
        self.q = np.zeros(n, dtype=complex)
        self._n_sliding = 0
        self._slide_mask = np.zeros(n)
        self._share_weights = np.zeros((n, 2))  # (φ_i, φ_i·slide_i)
        self._stick_damping = np.zeros(n)  # D_i of sticking taxels in contact, else 0 (its identity keys sums)
        self._speed_avg = np.zeros(n)  # |ū| of the last velocity checked by limit_slip_damping (m/s)
        self._neg_inv_d_c = -1.0 / spec.slip_weakening_m
        self._stick_damping_value = self.c + 0.5 * self.k * self.dt  # D_i of a sticking taxel (N·s/m)
        self._u_prev: np.ndarray | None = None  # u_n of the step (and of the next one's extrapolation)
        self._slip_share = 0.0

    @property
    def n_sliding(self) -> int:
        """Number of taxels in the slip state."""
        return self._n_sliding

    @property
    def slip_share(self) -> float:
        """Share of the friction capacity in use by slipping taxels, in [0, 1].

        ``Σ_slip φ_i |ū_i| / Σ φ_i |ū_i|`` over the last step: the share of the
        frictional dissipation ``D(ξ) = Σ μ φ_i |u_i|`` (docs/math.md §4) due to slipping
        patches. Weighting by the slip speed discounts the taxels near a centre of
        rotation, which stick during a gross rotation because they barely move. With
        the object at rest it falls back to the share of ``f_n``; 0 with no contact.
        """
        return self._slip_share

    def potential_energy(self) -> float:
        """Elastic energy stored in the bristles ``Σ ½ k |z_i|²`` (J)."""
        z = self.z[self._contact]
        return 0.5 * self.k * float(np.vdot(z, z).real)

    def set_normal_forces(self, f_n: float, shape: np.ndarray) -> None:
        """Take new normal forces ``φ_i = f_n·shape_i`` (N; ``f_n ≥ 0``, ``shape`` the
        normalised pressure). Taxels leaving contact relax to z = 0."""
        # z of taxels out of contact is not kept (it follows the body for free); a taxel
        # entering contact starts relaxed, one leaving releases its energy.
        phi = np.empty(self._n)
        stick_damping = np.empty(self._n)
        n_sliding = kernels.new_normal_forces(f_n, shape, self._n_sliding, self._stick_damping_value, self.k, self.dt,
                                              self._taxels, self._flags, self.z, phi, self._slide_mask,
                                              self._share_weights, stick_damping)
        self.phi = phi
        self._take_stick_set(n_sliding, stick_damping)

    def begin(self, v_origin: complex, omega: float, positions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Linearised contact forces for the coming step: ``q_i = e_i − D_i ū_i``.

        Args:
            v_origin: velocity of the body point over the pad origin at the start of
                the step (complex, m/s).
            omega: angular rate at the start of the step (rad/s).
            positions: taxel centres ``p_i`` (complex, m).

        Returns:
            ``(D, e)``: damping coefficients (N·s/m, shape (N,)) and explicit forces
            (complex N, shape (N,)). ``D`` is a new array whenever its values may have
            changed (the caller may key cached sums of it on its identity).
        """
        e = np.empty(self._n, dtype=complex)
        if self._n_sliding == 0:
            self._u_prev = None
            # u and damping outputs are not written while nothing slides
            kernels.begin_step(self._taxels, self._flags, self.z, 0, v_origin, omega, positions, self.z, False,
                               self._stick_damping, self._v_reg, e, self.z, self._speed_avg)
            return self._stick_damping, e
        # Expected mid-step speed: extrapolate when accelerating (else the force would
        # exceed the cap by |ū|/|u_n|), never below |u_n| (decelerating: force ≤ cap).
        u_n = np.empty(self._n, dtype=complex)
        damping = np.empty(self._n)
        has_prev = self._u_prev is not None
        kernels.begin_step(self._taxels, self._flags, self.z, self._n_sliding, v_origin, omega, positions,
                           self._u_prev if has_prev else u_n, has_prev, self._stick_damping, self._v_reg, e, u_n,
                           damping)
        self._u_prev = u_n
        return damping, e

    def mid_velocity(self, v_origin: complex, omega: float, positions: np.ndarray,
                     D: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
        """Mid-point surface velocity of a solve, and the damping that keeps every
        slipping patch at or below its cap if needed.

        ``D_i`` of a slipping taxel came from a predicted speed; if the solved speed
        ``|ū_i|`` is larger (a centre of rotation sweeping past the taxel), its force
        ``D_i |ū_i|`` would exceed ``μ_i φ_i``.

        Args:
            v_origin: mid-point velocity of the body point over the pad origin (complex, m/s).
            omega: mid-point angular rate (rad/s).
            positions: taxel centres ``p_i`` (complex, m).
            D: the damping the step was solved with (N·s/m).

        Returns:
            ``(ū, fixed)``: ``ū_i`` (complex, m/s), and a corrected copy of ``D`` with
            ``D_i = μ_i φ_i / |ū_i|`` for the taxels over their cap (re-solve the step
            with it), or None when no patch exceeds its cap by more than 0.1 %.
        """
        u_avg = np.empty(self._n, dtype=complex)
        fixed = np.empty(self._n)
        if kernels.mid_step_check(v_origin, omega, positions, self._n_sliding, D, self._taxels, u_avg,
                                  self._speed_avg, fixed):
            return u_avg, fixed
        return u_avg, None

    def finish(self, D: np.ndarray, e: np.ndarray, u_avg: np.ndarray) -> np.ndarray:
        """Advance deflections and stick/slip states with the step's mid-point velocity.

        Args:
            D, e: as returned by :meth:`begin` for this step (``D`` as corrected by
                :meth:`mid_velocity`).
            u_avg: mid-point surface velocity ``ū_i`` (complex, m/s), the last one
                :meth:`mid_velocity` returned.

        Returns:
            ``q``: the force each patch exerts on the object during the step (complex N).
        """
        q = np.empty(self._n, dtype=complex)
        z_new = np.empty(self._n, dtype=complex)
        n_sliding = self._n_sliding
        self._slip_share = self._share_of_slip() if n_sliding else 0.0
        kernels.advance_step(e, D, u_avg, self.z, self.dt, n_sliding, self._speed_avg, self._neg_inv_d_c,
                             self._taxels, q, z_new)
        if n_sliding:
            # the weakening exp(−s/d_c) stays numpy's exp (its rounding differs from libm's)
            np.exp(self._weakening_arg, out=self._weakening)
        # A sliding bristle rests deflected along the slip velocity, where its spring
        # force −k z equals the slip force −μφ û (at zero speed it relaxes, which only
        # releases energy).
        stick_damping = np.empty(self._n)
        n_sliding = kernels.end_step(n_sliding, u_avg, self._u_prev if n_sliding else u_avg, self._speed_avg, q,
                                     self.phi, self._stick_damping_value, self.k, self.dt, self._v_stick,
                                     self._taxels, self._flags, z_new, self._slide_mask, self._share_weights,
                                     stick_damping)
        self.q = q
        self.z = z_new
        self._take_stick_set(n_sliding, stick_damping)
        return q

    def _share_of_slip(self) -> float:
        """:attr:`slip_share` of the step's mid-point speeds (some taxel slides)."""
        total, slipping = (self._speed_avg @ self._share_weights).tolist()
        if total > 0.0:
            return min(1.0, slipping / total)
        f_n = float(self.phi.sum())
        return float(self.phi @ self._slide_mask) / f_n if f_n > 0.0 else 0.0

    def _take_stick_set(self, n_sliding: int, stick_damping: np.ndarray) -> None:
        """Adopt a kernel's new stick set (``n_sliding ≥ 0``) and its damping array; a new
        array, so that a caller's sums keyed on its identity are redone. −1: unchanged."""
        if n_sliding >= 0:
            self._n_sliding = n_sliding
            self._stick_damping = stick_damping
