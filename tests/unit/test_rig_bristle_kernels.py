"""The rig's compiled bristle kernels against the numpy formulas they replaced.

Each kernel of lib/rig/bristle_kernels.py must compute what the vectorised numpy code of
lib/rig/friction.py computed before (``_reference_*`` below are that code, verbatim in
substance): hand-checked values first, then hypothesis on random taxel states. The
kernels round like numpy on this project's machines (FMA); elsewhere a last-bit
difference is allowed, so the property tests compare to 4 ulp.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, strategies as st
from hypothesis.extra import numpy as hnp

from slipstack.lib.rig import bristle_kernels as kernels

_ULP = 4


def _close(actual, expected) -> None:
    actual, expected = np.asarray(actual), np.asarray(expected)
    if np.iscomplexobj(expected):
        _close(actual.real, expected.real)
        _close(actual.imag, expected.imag)
        return
    np.testing.assert_array_max_ulp(actual, expected, maxulp=_ULP)


# ---------------------------------------------------------------- hand-checked values

@pytest.mark.parametrize("z, expected", [
    (3 + 4j, 5.0), (-3 - 4j, 5.0), (0j, 0.0), (-2.5j, 2.5), (1e-310 + 0j, 1e-310),
    (complex(math.inf, math.nan), math.inf), (complex(1.0, -math.inf), math.inf),
])
def test_complex_abs_known_values(z, expected):
    assert kernels.complex_abs(z) == expected


def test_complex_abs_nan_part_is_nan():
    assert math.isnan(kernels.complex_abs(complex(math.nan, 1.0)))


def test_surface_velocity_is_translation_plus_spin_about_the_pad_origin():
    p = np.array([0.01 + 0j, 0.02j, -0.01 - 0.01j])
    out = np.empty_like(p)
    kernels.surface_velocity(0.1 + 0.2j, 2.0, p, out)  # u = v0 + i·ω·p: perp(p)·ω
    np.testing.assert_allclose(out, [0.1 + 0.22j, 0.06 + 0.2j, 0.12 + 0.18j], rtol=1e-15)


def test_linearise_sliding_extrapolates_the_speed_and_keeps_sticking_taxels():
    u_n = np.array([1.0 + 0j, 1.0 + 0j, 1e-9 + 0j])
    u_prev = np.array([0j, 2.0 + 0j, 0j])
    sliding = np.array([True, True, False])
    cap = np.array([3.0, 3.0, 3.0])
    stick = np.array([7.0, 7.0, 7.0])
    speed_n, damping = np.empty(3), np.empty(3)
    kernels.linearise_sliding(u_n, u_prev, sliding, cap, stick, 1e-3, speed_n, damping)
    # accelerating 0 → 1: mid-step speed 1.5; decelerating 2 → 1: not below |u_n| = 1
    np.testing.assert_array_equal(damping, [2.0, 3.0, 7.0])
    np.testing.assert_array_equal(speed_n[:2], [1.0, 1.0])  # |u_n| of the slipping taxels only


def test_linearise_sliding_floors_the_speed_at_the_regularisation_speed():
    damping, speed_n = np.empty(1), np.empty(1)
    kernels.linearise_sliding(np.array([0j]), np.array([0j]), np.array([True]), np.array([2.0]),
                              np.array([0.0]), 1e-3, speed_n, damping)
    assert damping[0] == 2.0 / 1e-3


def test_limit_slip_damping_caps_only_taxels_over_their_tolerance():
    damping = np.array([1.0, 1.0, 5.0])
    u_avg = np.array([2.0 + 0j, 0.5j, 3.0 + 4j])
    tol = np.array([1.5, 1.5, math.inf])  # the third sticks
    cap = np.array([1.0, 1.0, 1.0])
    speed, out = np.empty(3), np.empty(3)
    assert kernels.limit_slip_damping(damping, u_avg, tol, cap, speed, out)
    np.testing.assert_array_equal(speed, [2.0, 0.5, 5.0])
    np.testing.assert_array_equal(out, [0.5, 1.0, 5.0])
    assert not kernels.limit_slip_damping(out, u_avg, tol, cap, speed, out.copy())


def test_advance_gives_the_step_force_and_moved_deflection():
    q, z = np.empty(1, dtype=complex), np.empty(1, dtype=complex)
    kernels.advance(np.array([-1.0 + 2j]), np.array([3.0]), np.array([0.5 - 1j]), np.array([1e-4j]),
                    1e-3, q, z)
    assert q[0] == -2.5 + 5j
    assert z[0] == 0.5e-3 + (1e-4 - 1e-3) * 1j


def test_finish_sliding_rests_slipping_bristles_along_the_slip_and_resticks_reversals():
    u_avg = np.array([3.0 + 4j, -1.0 + 0j, 1e-6 + 0j, 2.0 + 0j])
    u_n = np.array([3.0 + 4j, 1.0 + 0j, 2e-6 + 0j, 2.0 + 0j])
    speed = np.abs(u_avg)
    speed_n = np.abs(u_n)
    sliding = np.array([True, True, True, False])
    cap = np.array([10.0, 10.0, 10.0, 10.0])
    z_new = np.full(4, 9.0 + 9j)
    s = np.array([1.0, 1.0, 1.0, 1.0])
    restuck = kernels.finish_sliding(u_avg, u_n, speed, speed_n, sliding, cap, 0.5, 1e-5, z_new, s)
    # z = û·cap/k: (0.6 + 0.8i)·5; the reversed one and the slow decelerating one stick
    assert restuck == 2
    np.testing.assert_allclose(z_new[:3], [3.0 + 4j, -5.0 + 0j, 5.0 + 0j], rtol=1e-15)
    assert z_new[3] == 9.0 + 9j  # a sticking taxel is left alone
    np.testing.assert_array_equal(sliding, [True, False, False, False])
    np.testing.assert_array_equal(s, [1.0, 0.0, 0.0, 1.0])


def test_release_over_cap_shrinks_the_deflection_to_the_static_cap():
    q = np.array([5.0 + 0j, 5.0 + 0j, 1.0 + 0j])
    cap_stick = np.array([4.0, math.inf, 4.0])  # the second already slips
    cap_static = np.array([4.0, 4.0, 4.0])
    z_new = np.array([-0.3 + 0.4j, 1.0 + 0j, 1.0 + 0j])
    sliding = np.array([False, True, False])
    s = np.array([2.0, 2.0, 2.0])
    assert kernels.release_over_cap(q, cap_stick, cap_static, 10.0, z_new, sliding, s) == 1
    np.testing.assert_allclose(z_new, [(-0.3 + 0.4j) * 0.8, 1.0, 1.0], rtol=1e-15)  # |z| → 0.4
    np.testing.assert_array_equal(sliding, [True, True, False])
    np.testing.assert_array_equal(s, [0.0, 2.0, 2.0])


def test_slide_caps_and_stick_arrays_known_values():
    sliding = np.array([True, False, False])
    contact = np.array([True, True, False])
    cap, tol = np.empty(3), np.empty(3)
    kernels.slide_caps(np.array([1.0, 1.0, 0.0]), np.array([0.5, 0.5, 0.0]), np.array([0.5, 1.0, 1.0]),
                       sliding, cap, tol)
    np.testing.assert_array_equal(cap, [1.25, 1.5, 0.0])
    np.testing.assert_array_equal(tol, [1.001 * 1.25, math.inf, math.inf])
    outs = [np.empty(3) for _ in range(5)]
    kernels.stick_arrays(sliding, contact, np.array([2.0, 3.0, 0.0]), np.array([1.0, 1.5, 0.0]),
                         0.7, 100.0, 1e-3, *outs)
    cap_stick, mask, dt_mask, damping, stiffness = outs
    np.testing.assert_array_equal(cap_stick, [math.inf, 1.5, 0.0])
    np.testing.assert_array_equal(mask, [1.0, 0.0, 0.0])
    np.testing.assert_array_equal(dt_mask, [1e-3, 0.0, 0.0])
    np.testing.assert_array_equal(damping, [0.0, 0.7, 0.0])
    np.testing.assert_array_equal(stiffness, [0.0, -100.0, 0.0])


# ------------------------------------------------- the numpy code the kernels replaced

def _reference_linearise(u_n, u_prev, sliding, cap_slide, stick_damping, v_reg):
    speed_n = np.abs(u_n)
    speed = np.abs(1.5 * u_n - 0.5 * u_prev)
    np.maximum(speed, speed_n, out=speed)
    np.maximum(speed, v_reg, out=speed)
    return speed_n, np.where(sliding, cap_slide / speed, stick_damping)


def _reference_limit(damping, u_avg, tol, cap_slide):
    speed = np.abs(u_avg)
    over = damping * speed > tol
    return speed, over.any(), np.where(over, cap_slide / np.maximum(speed, 1e-300), damping)


def _reference_finish(damping, e, u_avg, u_n, z, dt, speed_n, sliding, s, cap_slide, cap_stick, cap_static,
                      k, v_stick):
    """finish() and _advance_sliding() of b737fcd, the caps held fixed."""
    sliding, s = sliding.copy(), s.copy()
    q = e - damping * u_avg
    z_new = z + dt * u_avg
    speed = np.abs(u_avg)
    z_slide = u_avg * (cap_slide * (1.0 / k) / np.maximum(speed, 1e-300))
    np.copyto(z_new, z_slide, where=sliding)
    restick = ((u_avg * u_n.conj()).real <= 0.0) | ((speed < v_stick) & (speed < speed_n))
    restick &= sliding
    sliding &= ~restick
    s[restick] = 0.0
    over = np.abs(q) > cap_stick
    mag = np.abs(z_new[over])
    z_new[over] *= np.minimum(1.0, cap_static[over] / k / np.maximum(mag, 1e-300))
    sliding |= over
    s[over] = 0.0
    return q, z_new, sliding, s


_N = st.integers(1, 24)
_finite = st.floats(-1.0, 1.0, allow_nan=False, allow_subnormal=False)
_positive = st.floats(1e-6, 10.0, allow_nan=False)


def _complex_array(n):
    return hnp.arrays(np.float64, (n, 2), elements=_finite).map(lambda a: a[:, 0] + 1j * a[:, 1])


@st.composite
def _taxel_state(draw):
    n = draw(_N)
    return {
        "u_n": draw(_complex_array(n)), "u_prev": draw(_complex_array(n)), "u_avg": draw(_complex_array(n)),
        "e": draw(_complex_array(n)), "z": draw(_complex_array(n)) * 1e-4,
        "sliding": draw(hnp.arrays(bool, n)),
        "cap": draw(hnp.arrays(np.float64, n, elements=_positive)),
        "damping": draw(hnp.arrays(np.float64, n, elements=_positive)),
        "s": draw(hnp.arrays(np.float64, n, elements=st.floats(0.0, 1e-2))),
        "k": draw(st.floats(1.0, 1e5)), "v_reg": draw(st.floats(1e-9, 1e-2)), "v_stick": draw(st.floats(0.0, 0.5)),
    }


@given(st.complex_numbers(allow_nan=False, allow_infinity=False, max_magnitude=1e300))
def test_complex_abs_matches_numpy_abs(z):
    expected = float(np.abs(np.array([z]))[0])
    _close(kernels.complex_abs(z), expected)


@given(_taxel_state())
def test_linearise_sliding_matches_the_numpy_formula(t):
    n = t["u_n"].size
    speed_n, damping = np.empty(n), np.empty(n)
    kernels.linearise_sliding(t["u_n"], t["u_prev"], t["sliding"], t["cap"], t["damping"], t["v_reg"],
                              speed_n, damping)
    ref_speed_n, ref_damping = _reference_linearise(t["u_n"], t["u_prev"], t["sliding"], t["cap"],
                                                    t["damping"], t["v_reg"])
    _close(speed_n[t["sliding"]], ref_speed_n[t["sliding"]])  # finish_sliding reads no other
    _close(damping, ref_damping)


@given(_taxel_state())
def test_limit_slip_damping_matches_the_numpy_formula(t):
    n = t["u_avg"].size
    tol = np.where(t["sliding"], 1.001 * t["cap"], np.inf)
    speed, out = np.empty(n), np.empty(n)
    over = kernels.limit_slip_damping(t["damping"], t["u_avg"], tol, t["cap"], speed, out)
    ref_speed, ref_over, ref_out = _reference_limit(t["damping"], t["u_avg"], tol, t["cap"])
    assert over == ref_over
    _close(speed, ref_speed)
    _close(out, ref_out)


@given(_taxel_state(), st.floats(1e-5, 1e-3))
def test_a_step_end_matches_the_numpy_formula(t, dt):
    """advance + finish_sliding + release_over_cap, as the plant step chains them."""
    n = t["u_avg"].size
    sliding, s = t["sliding"].copy(), t["s"].copy()
    cap_static = t["cap"] * 1.2
    cap_stick = np.where(sliding, np.inf, cap_static)
    speed_n = np.abs(t["u_n"])
    q, z_new = np.empty(n, dtype=complex), np.empty(n, dtype=complex)
    kernels.advance(t["e"], t["damping"], t["u_avg"], t["z"], dt, q, z_new)
    kernels.finish_sliding(t["u_avg"], t["u_n"], np.abs(t["u_avg"]), speed_n, sliding, t["cap"],
                           1.0 / t["k"], t["v_stick"], z_new, s)
    kernels.release_over_cap(q, cap_stick, cap_static, t["k"], z_new, sliding, s)
    ref_q, ref_z, ref_sliding, ref_s = _reference_finish(
        t["damping"], t["e"], t["u_avg"], t["u_n"], t["z"], dt, speed_n, t["sliding"], t["s"], t["cap"],
        cap_stick, cap_static, t["k"], t["v_stick"])
    _close(q, ref_q)
    _close(z_new, ref_z)
    # A velocity at right angles to the last one (Re(ū·conj(u_n)) = 0 to rounding) is a tie the
    # compiled sum and numpy's complex product may round to either side: either verdict is right.
    tie = np.abs((t["u_avg"] * t["u_n"].conj()).real) <= 1e-12 * np.abs(t["u_avg"]) * np.abs(t["u_n"])
    np.testing.assert_array_equal(sliding[~tie], ref_sliding[~tie])
    np.testing.assert_array_equal(s[~tie], ref_s[~tie])


@given(_taxel_state(), st.floats(1e-5, 1e-3))
def test_caps_and_stick_arrays_match_the_numpy_formula(t, dt):
    sliding = t["sliding"]
    n = sliding.size
    contact = t["damping"] > 1.0  # any mix of contact and no contact
    phi = t["cap"] * contact
    cap_dynamic, cap_weakening = 0.6 * phi, 0.4 * phi
    weakening = np.exp(t["s"] * (-1.0 / 1e-3))
    cap, tol = np.empty(n), np.empty(n)
    kernels.slide_caps(cap_dynamic, cap_weakening, weakening, sliding, cap, tol)
    ref_cap = cap_dynamic + cap_weakening * weakening
    _close(cap, ref_cap)
    np.testing.assert_array_equal(tol, np.where(sliding, 1.001 * ref_cap, np.inf))
    c, k = 0.3, t["k"]
    outs = [np.empty(n) for _ in range(5)]
    kernels.stick_arrays(sliding, contact, phi, 1.5 * phi, c + 0.5 * k * dt, k, dt, *outs)
    mask = sliding.astype(float)
    stick = contact & ~sliding
    expected = [np.where(sliding, np.inf, 1.5 * phi), mask, dt * mask, (c + 0.5 * k * dt) * stick, -k * stick]
    for got, want in zip(outs, expected):
        np.testing.assert_array_equal(got, want)


def test_take_normal_forces_restarts_taxels_entering_or_leaving_contact():
    phi = np.array([2.0, 0.0, 1.0])
    contact = np.array([True, True, False])  # the second leaves, the third enters
    z = np.array([1e-4 + 1e-4j, 2e-4 + 0j, 3e-4j])
    s = np.array([1e-3, 2e-3, 3e-3])
    sliding = np.array([True, True, True])
    caps = [np.empty(3) for _ in range(3)]
    assert kernels.take_normal_forces(phi, np.full(3, 0.5), np.full(3, 0.25), contact, z, s, sliding, *caps) == 2
    np.testing.assert_array_equal(contact, [True, False, True])
    np.testing.assert_array_equal(z, [1e-4 + 1e-4j, 0j, 0j])
    np.testing.assert_array_equal(s, [1e-3, 0.0, 0.0])
    np.testing.assert_array_equal(sliding, [True, False, False])
    for got, want in zip(caps, ([1.0, 0.0, 0.5], [0.5, 0.0, 0.25], [0.5, 0.0, 0.25])):
        np.testing.assert_array_equal(got, want)


@given(_taxel_state())
def test_take_normal_forces_matches_the_numpy_formula(t):
    """set_normal_forces() of b737fcd."""
    n = t["s"].size
    phi = t["cap"] * (t["damping"] > 1.0)
    old_contact = t["u_n"].real > 0.0
    mu_s, mu_d = 0.5 + t["s"], 0.3 + t["s"]
    contact, z, s, sliding = old_contact.copy(), t["z"].copy(), t["s"].copy(), t["sliding"].copy()
    caps = [np.empty(n) for _ in range(3)]
    n_changed = kernels.take_normal_forces(phi, mu_s, mu_d, contact, z, s, sliding, *caps)
    ref_contact = phi > 0.0
    changed = old_contact ^ ref_contact
    ref_z, ref_s, ref_sliding = t["z"].copy(), t["s"].copy(), t["sliding"].copy()
    ref_z[changed], ref_s[changed], ref_sliding[changed] = 0.0, 0.0, False
    assert n_changed == changed.sum()
    for got, want in zip((contact, z, s, sliding), (ref_contact, ref_z, ref_s, ref_sliding)):
        np.testing.assert_array_equal(got, want)
    for got, want in zip(caps, (mu_s * phi, mu_d * phi, mu_s * phi - mu_d * phi)):
        np.testing.assert_array_equal(got, want)
