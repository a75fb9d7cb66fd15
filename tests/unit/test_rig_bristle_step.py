"""BristleField's step (a few fused kernel calls) against the chain of kernels it replaced.

Until 1637698, :class:`~slipstack.lib.rig.friction.BristleField` called the per-taxel
kernels of lib/rig/bristle_kernels.py one by one and recomputed the slip weakening
``exp(−s/d_c)`` whenever the caps changed. ``_ChainedField`` below is that code
(verbatim in substance). Both fields are driven through the same random steps (new
normal forces, begin, cap passes, end) and must agree bit for bit at every step: the
simulated rig's recordings depend on it.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from slipstack.lib.rig import bristle_kernels as kernels
from slipstack.lib.rig.friction import BristleField
from slipstack.lib.rig.scene import ContactSpec

_N = 36  # a 6 x 6 pad
_POSITIONS = ((np.arange(_N) % 6 - 2.5) + 1j * (np.arange(_N) // 6 - 2.5)) * 1.25e-3


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
        self._share_weights = np.zeros((n, 2))
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
        total, slipping = (speed @ self._share_weights).tolist()
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
                             self._slide_mask, self._dt_slide_mask, self._share_weights,
                             self._stick_damping, self._stick_stiffness)


def _same(a, b) -> None:
    np.testing.assert_array_equal(np.asarray(a), np.asarray(b), strict=True)


_TAXEL_ROWS = {"_cap_static": kernels.CAP_STATIC, "_cap_dynamic": kernels.CAP_DYNAMIC,
               "_cap_weakening": kernels.CAP_WEAKENING, "_cap_slide": kernels.CAP_SLIDE,
               "_cap_stick": kernels.CAP_STICK, "_dt_slide_mask": kernels.DT_SLIDE_MASK,
               "_stick_stiffness": kernels.STICK_STIFFNESS}


def _check_state(fused: BristleField, chained: _ChainedField) -> None:
    for name in ("z", "s", "sliding", "phi", "q", "_contact", "_slide_mask", "_share_weights", "_stick_damping"):
        _same(getattr(fused, name), getattr(chained, name))
    for name, row in _TAXEL_ROWS.items():
        _same(fused._taxels[row], getattr(chained, name))
    sliding = chained.sliding
    _same(fused._taxels[kernels.CAP_SLIDE_TOL][sliding], chained._cap_slide_tol[sliding])  # read where slipping
    assert fused.n_sliding == chained.n_sliding
    assert fused.slip_share == chained.slip_share
    _same(fused._weakening, np.exp(fused.s * fused._neg_inv_d_c))  # kept in step with s


def _surface_velocity(v, omega):
    return v + 1j * omega * _POSITIONS


@st.composite
def _run(draw):
    """A contact and a sequence of steps: normal force and shape, start and mid velocities."""
    spec = ContactSpec(mu_s=draw(st.floats(0.3, 1.0)), mu_d=draw(st.floats(0.1, 0.3)),
                       mu_spread=draw(st.sampled_from([0.0, 0.1])),
                       slip_weakening_m=draw(st.floats(1e-6, 1e-3)),
                       stick_speed_m_s=draw(st.floats(1e-6, 1e-3)))
    speed = st.floats(-0.05, 0.05, allow_subnormal=False)
    steps = []
    for _ in range(draw(st.integers(5, 25))):
        shape = draw(st.sampled_from(["same", "new", "zero-edge"]))
        f_n = draw(st.sampled_from([None, 0.0, 0.5, 3.0, 8.0]))
        v0 = complex(draw(speed), draw(speed))
        passes = [(complex(draw(speed), draw(speed)), draw(st.floats(-5.0, 5.0))) for _ in range(draw(st.integers(1, 3)))]
        steps.append((shape, f_n, v0, draw(st.floats(-5.0, 5.0)), passes))
    return spec, draw(st.integers(0, 2**31)), steps


@settings(max_examples=60, deadline=None)
@given(_run())
def test_fused_step_matches_the_kernel_chain_bit_for_bit(run):
    spec, seed, steps = run
    dt = 1e-3
    fused = BristleField(spec, 1.5625e-6, dt, np.random.default_rng(seed), _N)
    chained = _ChainedField(fused, spec.slip_weakening_m, spec.stick_speed_m_s, spec.regularisation_speed_m_s)
    rng = np.random.default_rng(seed)
    shape = np.full(_N, 1.0 / _N)
    f_n = 3.0
    for kind, force, v0, omega, passes in steps:
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
        u_n = _surface_velocity(v0, omega) if chained.n_sliding else None
        D, e = fused.begin(v0, omega, _POSITIONS)
        D_ref, e_ref = chained.begin(u_n)
        _same(D, D_ref)
        _same(e, e_ref)
        for v_mid, w_mid in passes:
            u_avg, fixed = fused.mid_velocity(v_mid, w_mid, _POSITIONS, D)
            u_avg_ref = _surface_velocity(v_mid, w_mid)
            fixed_ref = chained.limit_slip_damping(D_ref, u_avg_ref)
            _same(u_avg, u_avg_ref)
            assert (fixed is None) == (fixed_ref is None)
            if fixed is None:
                break
            _same(fixed, fixed_ref)
            D, D_ref = fixed, fixed_ref
        _same(fused.finish(D, e, u_avg), chained.finish(D_ref, e_ref, u_avg_ref, u_n))
        _check_state(fused, chained)


def test_the_stick_damping_keeps_its_identity_while_no_taxel_enters_or_leaves_contact():
    """The simulator keys its damping sums on the array's identity: unchanged values, same array."""
    field = BristleField(ContactSpec(), 1.5625e-6, 1e-3, np.random.default_rng(1), _N)
    shape = np.full(_N, 1.0 / _N)
    field.set_normal_forces(3.0, shape)
    D, _ = field.begin(0j, 0.0, _POSITIONS)
    field.set_normal_forces(3.1, shape)
    assert field.begin(0j, 0.0, _POSITIONS)[0] is D
    shape = shape.copy()
    shape[:6] = 0.0  # the first row leaves contact
    field.set_normal_forces(3.1, shape / shape.sum())
    D_new, _ = field.begin(0j, 0.0, _POSITIONS)
    assert D_new is not D
    assert (D_new[:6] == 0.0).all() and (D_new[6:] == D[6:]).all()


@pytest.mark.parametrize("n", [1, 7, 8, 9, 256])
def test_numpy_exp_of_zero_is_one_at_every_position(n):
    """restart_weakening writes 1 where s restarted instead of asking numpy: exp(−0) = exp(0) = 1 exactly."""
    assert (np.exp(np.full(n, -0.0)) == 1.0).all() and (np.exp(np.zeros(n)) == 1.0).all()
