"""Per-taxel elastic friction ("bristle") model with stick, slip and slip weakening.

Each taxel patch ``i`` in contact (``φ_i > 0``) carries an elastic tangential
deflection ``z_i`` (complex ``x + i·y``, metres, pad frame ``F``): the displacement of
the object's surface point relative to where it stuck. Vectors are complex numbers.

More in docs/modules.md, `lib/rig/friction.py`.
"""

from __future__ import annotations

import numpy as np

from slipstack.lib.rig import bristle_kernels as kernels
from slipstack.lib.rig.plant_kernel import N_CONSTANTS, force_sums, plant_step
from slipstack.lib.rig.scene import ContactSpec

__all__ = ["BristleField", "friction_coefficients"]


def friction_coefficients(spec: ContactSpec, rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``(μ_s, μ_d)`` of ``n`` taxels: ``spec``'s times a factor ``1 + mu_spread·N(0,1)`` each
    (clipped to [0.5, 1.5]), drawn from ``rng``: the surface's heterogeneity."""
    factor = np.clip(1.0 + spec.mu_spread * rng.standard_normal(n), 0.5, 1.5)
    return spec.mu_s * factor, spec.mu_d * factor


class BristleField:
    """Bristle states of all taxels of a pad (vectorised over taxels).

    The per-taxel loops, and a whole step with the body's solve, run in compiled
    kernels (:mod:`slipstack.lib.rig.bristle_kernels`, :mod:`slipstack.lib.rig.plant_kernel`);
    this object owns the state they update in place.

    Args:
        spec: friction parameters.
        taxel_area_m2: ``h²`` (m²).
        dt_s: internal step (s).
        rng: draws the per-taxel friction factors ``1 + mu_spread·N(0,1)``.
        positions: taxel centres ``p_i`` (complex, m, pad frame), shape (N,).
        friction: ``(μ_s, μ_d)`` per taxel, shape (N,) each, instead of drawing them from
            ``spec`` and ``rng`` (:func:`friction_coefficients`; a gripper's two fingers).
    """

    def __init__(self, spec: ContactSpec, taxel_area_m2: float, dt_s: float,
                 rng: np.random.Generator, positions: np.ndarray,
                 friction: tuple[np.ndarray, np.ndarray] | None = None) -> None:
        self.k = spec.stiffness_N_per_m3 * taxel_area_m2
        self.c = spec.damping_Ns_per_m3 * taxel_area_m2
        self.dt = dt_s
        n = positions.shape[0]
        mu_s, mu_d = friction_coefficients(spec, rng, n) if friction is None else friction
        self._v_stick = spec.stick_speed_m_s
        self._v_reg = spec.regularisation_speed_m_s
        # the per-taxel state the kernels share, one row per quantity (rows and units:
        # lib/rig/bristle_kernels.py); the attributes below are views of rows
        self._taxels = np.zeros((kernels.N_TAXEL_ROWS, n))
        self._flags = np.zeros((kernels.N_FLAG_ROWS, n), dtype=bool)
        self._vectors = np.zeros((kernels.N_VECTOR_ROWS, n), dtype=complex)
        t = self._taxels
        t[kernels.MU_S] = mu_s
        t[kernels.MU_D] = mu_d
        t[kernels.CAP_SLIDE_TOL] = np.inf
        t[kernels.WEAKENING] = 1.0
        self._vectors[kernels.POSITION] = positions
        self.mu_s, self.mu_d, self.s, self.phi = t[kernels.MU_S], t[kernels.MU_D], t[kernels.SLIP], t[kernels.PHI]
        self.sliding, self._contact = self._flags[kernels.SLIDING], self._flags[kernels.CONTACT]
        self.z, self.q = self._vectors[kernels.DEFLECTION], self._vectors[kernels.FORCE]
        self._n_sliding = 0
        self._has_prev = False  # U_PREV holds the last step's u_n (some taxel slid then)
        self._neg_inv_d_c = -1.0 / spec.slip_weakening_m
        self._stick_damping_value = self.c + 0.5 * self.k * self.dt  # D_i of a sticking taxel (N·s/m)
        self._slip_share = 0.0

    @property
    def n_sliding(self) -> int:
        """Number of taxels in the slip state."""
        return self._n_sliding

    @property
    def slip_share(self) -> float:
        """Share of the friction capacity in use by slipping taxels, in [0, 1].

        ``Σ_slip φ_i |ū_i| min(1, |q_i|/cap_i) / Σ φ_i |ū_i|`` over the last step: the
        share of the frictional dissipation ``D(ξ) = Σ μ φ_i |u_i|`` (docs/math.md §4)
        due to slipping patches, each at the share of its cap it transmits. Weighting by
        the slip speed discounts the taxels near a centre of rotation, which stick during
        a gross rotation because they barely move; weighting by the transmitted share
        discounts a patch in the slip state whose motion stops within the step (the
        step-rate stick–slip switching of a contact held near its capacity). With the
        object at rest it falls back to the share of ``f_n``; 0 with no contact.
        """
        return self._slip_share

    def load_of(self, taxels: slice) -> tuple[complex, float]:
        """``(Σ q_i, Σ p_i × q_i)`` over ``taxels`` in the last step: the force (complex N) and
        torque about the pad origin (N·m) those patches exerted on the object (one finger's share)."""
        return force_sums(self.q[taxels], self._vectors[kernels.POSITION][taxels])

    def elastic_twist(self) -> tuple[complex, float]:
        """The rigid displacement ``(t, ω)`` (complex m, rad; ``u(p) = t + i·ω·p``) nearest the
        deflections of the taxels in contact: how far the object is off the pose at which its
        contact last stuck, elastically (lib/rig/bristle_kernels.py ``elastic_twist``)."""
        return kernels.elastic_twist(self.z, self._vectors[kernels.POSITION], self._contact)

    def potential_energy(self) -> float:
        """Elastic energy stored in the bristles ``Σ ½ k |z_i|²`` (J)."""
        return 0.5 * self.k * kernels.deflection_square_sum(self.z, self._contact)

    def plant_constants(self, mass: float, inertia: float, free_mask: tuple[float, float, float]) -> np.ndarray:
        """The ``constants`` of :meth:`step` for a body of ``mass`` (kg), ``inertia``
        (kg·m² about its reference point) and free mask (``PlanarBody.free_mask``)."""
        constants = np.array([self.k, self.dt, self._stick_damping_value, self._v_reg, self._v_stick,
                              self._neg_inv_d_c, mass, inertia, *free_mask])
        return constants.reshape(N_CONSTANTS)  # a wrong count fails here, not in the kernel

    def set_normal_forces(self, f_n: float, shape: np.ndarray) -> None:
        """Take new normal forces ``φ_i = f_n·shape_i`` (N; ``f_n ≥ 0``, ``shape`` the
        normalised pressure). Taxels leaving contact relax to z = 0."""
        # z of taxels out of contact is not kept (it follows the body for free); a taxel
        # entering contact starts relaxed, one leaving releases its energy.
        self._n_sliding = kernels.new_normal_forces(f_n, shape, self._n_sliding, self._stick_damping_value, self.k,
                                                    self.dt, self._taxels, self._flags, self._vectors)

    def step(self, constants: np.ndarray, reference: complex, v_ref: complex, omega: float, s_ext: float,
             sp_ext: complex, spp_ext: float, s_rot: float, force_ext: complex,
             tau_ext: float) -> tuple[complex, float, complex, float]:
        """One step of the bristles with the body (:func:`~slipstack.lib.rig.plant_kernel.plant_step`).

        Args:
            constants: :meth:`plant_constants`.
            reference, v_ref, omega: the body's reference point (complex, m) and twist
                at the start of the step (complex m/s, rad/s).
            s_ext, sp_ext, spp_ext, s_rot: external damping about the pad origin
                (N·s/m, N·s, N·m·s) and rotational damping (N·m·s/rad).
            force_ext, tau_ext: external force (complex N) and torque about the pad origin (N·m).

        Returns:
            ``(v̄_r, ω̄, Σ q, Σ p × q)``: the body's mid-point twist to commit, and the sums
            of the forces the patches exerted on the object (complex N, N·m).
        """
        n_sliding = self._n_sliding
        self._n_sliding, v_mid, w_mid, self._slip_share, f_q, tau_q = plant_step(
            self._taxels, self._flags, self._vectors, constants, n_sliding, self._has_prev, reference, v_ref, omega,
            s_ext, sp_ext, spp_ext, s_rot, force_ext, tau_ext)
        self._has_prev = n_sliding > 0
        return v_mid, w_mid, f_q, tau_q
