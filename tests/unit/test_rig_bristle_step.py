"""The plant step (one compiled call: bristles and body) against the numpy chain it replaced.

More in docs/modules.md, `tests/unit/test_rig_bristle_step.py`.
"""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings, strategies as st

from slipstack.lib.rig import bristle_kernels as kernels
from slipstack.lib.rig.body import mid_point_twist
from slipstack.lib.rig.friction import BristleField
from slipstack.lib.rig.scene import ContactSpec

_N = 36  # a 6 x 6 pad
_POSITIONS = ((np.arange(_N) % 6 - 2.5) + 1j * (np.arange(_N) // 6 - 2.5)) * 1.25e-3
_reference_twist = getattr(mid_point_twist, "py_func", mid_point_twist)  # interpreted, as PlanarBody.solve ran
_RTOL = 1e-12
"""Relative to each compared array's largest magnitude (see the module docstring)."""


class _ChainedField:
    """The 1637698 step: one kernel call per operation, the weakening recomputed each time."""

    def __init__(self, field: BristleField, d_c: float, v_stick: float, v_reg: float) -> None:
        n = field.phi.shape[0]
        self.k, self.c, self.dt = field.k, field.c, field.dt
        self.mu_s, self.mu_d = field.mu_s.copy(), field.mu_d.copy()
        self._d_c, self._v_stick, self._v_reg = d_c, v_stick, v_reg
        self.z = np.zeros(n, dtype=complex)
        self.s = np.zeros(n)
        self.sliding = np.zeros(n, dtype=bool)
        self.phi = np.zeros(n)
        self.q = np.zeros(n, dtype=complex)
        self._contact = np.zeros(n, dtype=bool)
        self.n_sliding = 0
        self._cap_static, self._cap_dynamic, self._cap_weakening = np.zeros(n), np.zeros(n), np.zeros(n)
        self._cap_slide = np.zeros(n)
        self._cap_slide_tol = np.full(n, np.inf)
        self._cap_stick = np.zeros(n)
        self._slide_mask, self._dt_slide_mask = np.zeros(n), np.zeros(n)
        self._stick_damping, self._stick_stiffness = np.zeros(n), np.zeros(n)
        self._speed_n, self._speed_avg = np.zeros(n), np.zeros(n)
        self._u_prev = None
        self.slip_share = 0.0

    def set_normal_forces(self, phi):
        if kernels.take_normal_forces(phi, self.mu_s, self.mu_d, self._contact, self.z, self.s, self.sliding,
                                      self._cap_static, self._cap_dynamic, self._cap_weakening):
            self.n_sliding = int(self.sliding.sum())
        self.phi = phi
        self._update_caps()
        self._update_stick_arrays()

    def begin(self, u_n):
        e = self._stick_stiffness * self.z
        if self.n_sliding == 0:
            self._u_prev = None
            return self._stick_damping, e
        u_prev, self._u_prev = self._u_prev, u_n
        if u_prev is None:
            u_prev = u_n
        damping = np.empty(self.phi.shape[0])
        kernels.linearise_sliding(u_n, u_prev, self.sliding, self._cap_slide, self._stick_damping,
                                  self._v_reg, self._speed_n, damping)
        return damping, e

    def limit_slip_damping(self, D, u_avg):
        if self.n_sliding == 0:
            return None
        fixed = np.empty_like(D)
        if kernels.limit_slip_damping(D, u_avg, self._cap_slide_tol, self._cap_slide, self._speed_avg, fixed):
            return fixed
        return None

    def finish(self, D, e, u_avg, u_n):
        q, z_new = np.empty_like(u_avg), np.empty_like(u_avg)
        kernels.advance(e, D, u_avg, self.z, self.dt, q, z_new)
        self.q = q
        changed = False
        self.slip_share = 0.0
        if self.n_sliding:
            changed = self._advance_sliding(u_avg, u_n, z_new)
        if kernels.release_over_cap(q, self._cap_stick, self._cap_static, self.k, z_new, self.sliding, self.s):
            changed = True
        self.z = z_new
        if changed:
            self.n_sliding = int(self.sliding.sum())
            self._update_caps()
            self._update_stick_arrays()
        return q

    def _advance_sliding(self, u_avg, u_n, z_new):
        speed = self._speed_avg
        used = np.minimum(1.0, np.abs(self.q) / np.where(self._slide_mask > 0, self._cap_slide, 1.0))
        total, slipping = float(speed @ self.phi), float(speed @ (self.phi * self._slide_mask * used))
        if total > 0.0:
            self.slip_share = min(1.0, slipping / total)
        else:
            f_n = float(self.phi.sum())
            self.slip_share = float(self.phi @ self._slide_mask) / f_n if f_n > 0.0 else 0.0
        self.s += speed * self._dt_slide_mask
        self._update_caps()
        return kernels.finish_sliding(u_avg, u_n, speed, self._speed_n, self.sliding, self._cap_slide,
                                      1.0 / self.k, self._v_stick, z_new, self.s) > 0

    def _update_caps(self):
        if self.n_sliding:
            weakening = np.exp(self.s * (-1.0 / self._d_c))
            kernels.slide_caps(self._cap_dynamic, self._cap_weakening, weakening, self.sliding,
                               self._cap_slide, self._cap_slide_tol)
        else:
            np.copyto(self._cap_slide, self._cap_static)

    def _update_stick_arrays(self):
        self._stick_damping = np.empty(self.phi.shape[0])
        kernels.stick_arrays(self.sliding, self._contact, self.phi, self._cap_static,
                             self.c + 0.5 * self.k * self.dt, self.k, self.dt, self._cap_stick,
                             self._slide_mask, self._dt_slide_mask, self._stick_damping, self._stick_stiffness)


def _close(a, b, scale: float | None = None) -> None:
    """``a ≈ b`` within ``_RTOL`` of ``scale`` (default: ``b``'s largest finite magnitude)."""
    a, b = np.asarray(a), np.asarray(b)
    if scale is None:
        finite = np.abs(b[np.isfinite(b)])
        scale = float(finite.max(initial=0.0))
    np.testing.assert_allclose(a, b, rtol=_RTOL, atol=_RTOL * scale)


def _same(a, b) -> None:
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b), strict=True)


_TAXEL_ROWS = {"_cap_static": kernels.CAP_STATIC, "_cap_dynamic": kernels.CAP_DYNAMIC,
               "_cap_weakening": kernels.CAP_WEAKENING, "_cap_slide": kernels.CAP_SLIDE,
               "_cap_stick": kernels.CAP_STICK, "_dt_slide_mask": kernels.DT_SLIDE_MASK,
               "_stick_stiffness": kernels.STICK_STIFFNESS, "_slide_mask": kernels.SLIDE_MASK,
               "_stick_damping": kernels.STICK_DAMPING, "s": kernels.SLIP, "phi": kernels.PHI}


def _check_state(fused: BristleField, chained: _ChainedField) -> None:
    for name in ("sliding", "_contact"):
        _same(getattr(fused, name), getattr(chained, name))
    _close(fused.z, chained.z)
    _close(fused.q, chained.q)
    for name, row in _TAXEL_ROWS.items():
        _close(fused._taxels[row], getattr(chained, name))
    sliding = chained.sliding
    _close(fused._taxels[kernels.CAP_SLIDE_TOL][sliding], chained._cap_slide_tol[sliding])  # read where slipping
    assert fused.n_sliding == chained.n_sliding
    _close(fused.slip_share, chained.slip_share)
    _close(fused._taxels[kernels.WEAKENING], np.exp(fused.s * fused._neg_inv_d_c))  # kept in step with s


def _surface_velocity(v, omega):
    return v + 1j * omega * _POSITIONS


def _reference_step(chained, dt, body, twist, external):
    """Simulator._step of 1637698 after the motor's load: numpy sums, Python solve."""
    mass, inertia, free, r = body
    v_ref, omega = twist
    s_ext, sp_ext, spp_ext, s_rot, force_ext, tau_ext = external
    lever4 = np.column_stack([np.ones(_N), _POSITIONS.real, _POSITIONS.imag, np.abs(_POSITIONS) ** 2])

    def damping_sums(D):
        s, sx, sy, spp = D @ lever4
        return s + s_ext, complex(sx, sy) + sp_ext, spp + spp_ext

    u_n = _surface_velocity(v_ref - 1j * omega * r, omega) if chained.n_sliding else None
    D, e = chained.begin(u_n)
    force = e.sum() + force_ext
    tau = float((_POSITIONS.conjugate() * e).imag.sum()) + tau_ext
    for _ in range(4):
        v_mid, w_mid = _reference_twist(dt, mass, inertia, *free, r, v_ref, omega, *damping_sums(D), s_rot, force, tau)
        u_avg = _surface_velocity(v_mid - 1j * w_mid * r, w_mid)
        fixed = chained.limit_slip_damping(D, u_avg)
        if fixed is None:
            break
        D = fixed
    q = chained.finish(D, e, u_avg, u_n)
    return v_mid, w_mid, q.sum(), float((_POSITIONS.conjugate() * q).imag.sum())


@st.composite
def _run(draw):
    """A contact, a body, and a sequence of steps: normal force and shape, start twist, external load."""
    spec = ContactSpec(mu_s=draw(st.floats(0.3, 1.0)), mu_d=draw(st.floats(0.1, 0.3)),
                       mu_spread=draw(st.sampled_from([0.0, 0.1])),
                       slip_weakening_m=draw(st.floats(1e-6, 1e-3)),
                       stick_speed_m_s=draw(st.floats(1e-6, 1e-3)))
    free = draw(st.sampled_from([(1.0, 1.0, 1.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (1.0, 1.0, 0.0)]))
    body = (draw(st.floats(0.01, 1.0)), draw(st.floats(1e-6, 1e-3)), free,
            complex(draw(st.floats(-5e-3, 5e-3)), draw(st.floats(-5e-3, 5e-3))))
    speed = st.floats(-0.05, 0.05, allow_subnormal=False)
    load = st.floats(-5.0, 5.0, allow_subnormal=False)
    steps = []
    for _ in range(draw(st.integers(5, 25))):
        shape = draw(st.sampled_from(["same", "new", "zero-edge"]))
        f_n = draw(st.sampled_from([None, 0.0, 0.5, 3.0, 8.0]))
        twist = (complex(draw(speed), draw(speed)), draw(st.floats(-5.0, 5.0)))
        external = (draw(st.sampled_from([0.0, 2.0])), 0j, 0.0, draw(st.sampled_from([0.0, 1e-3])),
                    complex(draw(load), draw(load)), draw(load) * 1e-2)
        steps.append((shape, f_n, twist, external))
    return spec, body, draw(st.integers(0, 2**31)), steps


@settings(max_examples=60, deadline=None)
@given(_run())
def test_the_plant_step_matches_the_numpy_chain_to_the_last_bits(run):
    spec, body, seed, steps = run
    dt = 1e-3
    mass, inertia, free, r = body
    fused = BristleField(spec, 1.5625e-6, dt, np.random.default_rng(seed), _POSITIONS)
    constants = fused.plant_constants(mass, inertia, free)
    chained = _ChainedField(fused, spec.slip_weakening_m, spec.stick_speed_m_s, spec.regularisation_speed_m_s)
    rng = np.random.default_rng(seed)
    shape = np.full(_N, 1.0 / _N)
    f_n = 3.0
    for kind, force, twist, external in steps:
        if kind == "new":
            shape = rng.random(_N)
            shape /= shape.sum()
        elif kind == "zero-edge":  # taxels leave and enter contact
            shape = shape * (rng.random(_N) > 0.2)
            total = shape.sum()
            shape = shape / total if total > 0 else np.full(_N, 1.0 / _N)
        if force is not None or kind != "same":
            f_n = f_n if force is None else force
            fused.set_normal_forces(f_n, shape)
            chained.set_normal_forces(f_n * shape)
            _check_state(fused, chained)
        s_ext, sp_ext, spp_ext, s_rot, force_ext, tau_ext = external
        v_mid, w_mid, f_q, tau_q = fused.step(constants, r, *twist, s_ext, sp_ext, spp_ext, s_rot, force_ext, tau_ext)
        v_want, w_want, f_want, tau_want = _reference_step(chained, dt, body, twist, external)
        lever = np.abs(_POSITIONS - r).max()
        speed = abs(twist[0]) + lever * abs(twist[1]) + abs(v_want) + lever * abs(w_want)  # m/s
        _close(v_mid, v_want, speed)
        _close(w_mid, w_want, speed / lever)
        _close(f_q, f_want, np.abs(chained.q).sum())  # sums: relative to their terms' magnitudes
        _close(tau_q, tau_want, (np.abs(_POSITIONS) * np.abs(chained.q)).sum())
        _check_state(fused, chained)
