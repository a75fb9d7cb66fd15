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
        self.mu_s = spec.mu_s * factor
        self.mu_d = spec.mu_d * factor
        self._d_c = spec.slip_weakening_m
        self._v_stick = spec.stick_speed_m_s
        self._v_reg = spec.regularisation_speed_m_s
        n = n_taxels
        self.z = np.zeros(n, dtype=complex)
        self.s = np.zeros(n)
        self.sliding = np.zeros(n, dtype=bool)
        self.phi = np.zeros(n)
        self.q = np.zeros(n, dtype=complex)
        self._contact = np.zeros(n, dtype=bool)
        self._n_sliding = 0
        self._cap_static = np.zeros(n)
        self._cap_dynamic = np.zeros(n)
        self._cap_weakening = np.zeros(n)
        self._cap_slide = np.zeros(n)  # slip cap μ(s)·φ (N); the static cap while none slides
        self._cap_slide_tol = np.full(n, np.inf)  # 1.001·cap of slipping taxels, inf elsewhere
        self._cap_stick = np.zeros(n)  # static cap of sticking taxels, inf for slipping ones
        self._slide_mask = np.zeros(n)
        self._dt_slide_mask = np.zeros(n)
        self._share_weights = np.zeros((n, 2))  # (φ_i, φ_i·slide_i)
        self._stick_damping = np.zeros(n)  # D_i of sticking taxels in contact, else 0
        self._stick_stiffness = np.zeros(n)  # -k for sticking taxels in contact, else 0
        self._speed_n = np.zeros(n)  # |u_n| at the start of the step (m/s)
        self._speed_avg = np.zeros(n)  # |ū| of the last velocity checked by limit_slip_damping (m/s)
        self._u_prev: np.ndarray | None = None
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

    def set_normal_forces(self, phi: np.ndarray) -> None:
        """Take new normal forces ``φ_i`` (N). Taxels leaving contact relax to z = 0."""
        # z of taxels out of contact is not kept (it follows the body for free); a taxel
        # entering contact starts relaxed, one leaving releases its energy.
        if kernels.take_normal_forces(phi, self.mu_s, self.mu_d, self._contact, self.z, self.s, self.sliding,
                                      self._cap_static, self._cap_dynamic, self._cap_weakening):
            self._n_sliding = int(self.sliding.sum())
        self.phi = phi
        self._update_caps()
        self._update_stick_arrays()

    def begin(self, u_n: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """Linearised contact forces for the coming step: ``q_i = e_i − D_i ū_i``.

        Args:
            u_n: surface velocity over each taxel at the start of the step (complex,
                m/s); only needed while some taxel slides (``n_sliding > 0``), else None.

        Returns:
            ``(D, e)``: damping coefficients (N·s/m, shape (N,)) and explicit forces
            (complex N, shape (N,)). ``D`` is a new array whenever its values may have
            changed (the caller may key cached sums of it on its identity).
        """
        e = self._stick_stiffness * self.z
        if self._n_sliding == 0:
            self._u_prev = None
            return self._stick_damping, e
        u_prev, self._u_prev = self._u_prev, u_n
        if u_prev is None:
            u_prev = u_n
        # Expected mid-step speed: extrapolate when accelerating (else the force would
        # exceed the cap by |ū|/|u_n|), never below |u_n| (decelerating: force ≤ cap).
        damping = np.empty(self.phi.shape[0])
        kernels.linearise_sliding(u_n, u_prev, self.sliding, self._cap_slide, self._stick_damping,
                                  self._v_reg, self._speed_n, damping)
        return damping, e

    def limit_slip_damping(self, D: np.ndarray, u_avg: np.ndarray) -> np.ndarray | None:
        """Damping that keeps every slipping patch at or below its cap, if needed.

        ``D_i`` of a slipping taxel came from a predicted speed; if the solved speed
        ``|ū_i|`` is larger (a centre of rotation sweeping past the taxel), its force
        ``D_i |ū_i|`` would exceed ``μ_i φ_i``. Returns a corrected copy with
        ``D_i = μ_i φ_i / |ū_i|`` for those taxels (re-solve the step with it), or
        None when no patch exceeds its cap by more than 0.1 %.
        """
        if self._n_sliding == 0:
            return None
        fixed = np.empty_like(D)
        if kernels.limit_slip_damping(D, u_avg, self._cap_slide_tol, self._cap_slide, self._speed_avg, fixed):
            return fixed
        return None

    def finish(self, D: np.ndarray, e: np.ndarray, u_avg: np.ndarray, u_n: np.ndarray) -> np.ndarray:
        """Advance deflections and stick/slip states with the step's mid-point velocity.

        Args:
            D, e: as returned by :meth:`begin` for this step.
            u_avg: mid-point surface velocity ``ū_i`` (complex, m/s); while some taxel
                slides, the one last given to :meth:`limit_slip_damping`.
            u_n: start-of-step surface velocity (complex, m/s), as given to :meth:`begin`.

        Returns:
            ``q``: the force each patch exerts on the object during the step (complex N).
        """
        q = np.empty_like(u_avg)
        z_new = np.empty_like(u_avg)
        kernels.advance(e, D, u_avg, self.z, self.dt, q, z_new)
        self.q = q
        changed = False
        self._slip_share = 0.0
        if self._n_sliding:
            changed = self._advance_sliding(u_avg, u_n, z_new)
        # only sticking taxels have a finite cap here
        if kernels.release_over_cap(q, self._cap_stick, self._cap_static, self.k, z_new, self.sliding, self.s):
            changed = True
        self.z = z_new
        if changed:
            self._n_sliding = int(self.sliding.sum())
            self._update_caps()
            self._update_stick_arrays()
        return q

    def _advance_sliding(self, u_avg: np.ndarray, u_n: np.ndarray, z_new: np.ndarray) -> bool:
        """Slip distance, weakening and re-sticking of sliding taxels; edits z_new."""
        speed = self._speed_avg  # |u_avg|, from limit_slip_damping
        total, slipping = (speed @ self._share_weights).tolist()
        if total > 0.0:
            self._slip_share = min(1.0, slipping / total)
        else:
            f_n = float(self.phi.sum())
            self._slip_share = float(self.phi @ self._slide_mask) / f_n if f_n > 0.0 else 0.0
        self.s += speed * self._dt_slide_mask
        self._update_caps()
        # A sliding bristle rests deflected along the slip velocity, where its spring
        # force −k z equals the slip force −μφ û (at zero speed it relaxes, which only
        # releases energy).
        return kernels.finish_sliding(u_avg, u_n, speed, self._speed_n, self.sliding, self._cap_slide,
                                      1.0 / self.k, self._v_stick, z_new, self.s) > 0

    def _update_caps(self) -> None:
        if self._n_sliding:
            # the weakening factor stays numpy's exp (its rounding differs from libm's)
            weakening = np.exp(self.s * (-1.0 / self._d_c))
            kernels.slide_caps(self._cap_dynamic, self._cap_weakening, weakening, self.sliding,
                               self._cap_slide, self._cap_slide_tol)
        else:
            np.copyto(self._cap_slide, self._cap_static)

    def _update_stick_arrays(self) -> None:
        # a new array, so that a caller's sums keyed on its identity are redone
        self._stick_damping = np.empty(self.phi.shape[0])
        kernels.stick_arrays(self.sliding, self._contact, self.phi, self._cap_static,
                             self.c + 0.5 * self.k * self.dt, self.k, self.dt, self._cap_stick,
                             self._slide_mask, self._dt_slide_mask, self._share_weights,
                             self._stick_damping, self._stick_stiffness)
