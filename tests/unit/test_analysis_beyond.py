"""The figures beyond the paper (analysis/beyond.py, analysis/grip_oracle.py): the oracle
over a run, the limit surfaces' errors, and which detector settings are on the Pareto front."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("matplotlib")  # analysis/figures.py draws with it

from slipstack.analysis.beyond import _pressures, limit_error  # noqa: E402
from slipstack.analysis.grip_oracle import oracle_series  # noqa: E402
from slipstack.analysis.replay import Quality  # noqa: E402
from slipstack.analysis.sensitivity import Score, dominated  # noqa: E402
from slipstack.lib.pad import PadGeometry  # noqa: E402
from slipstack.nodes.rig import load_scene_by_name  # noqa: E402


def test_the_oracle_holds_the_load_exactly_is_zero_without_one_and_scales_with_it():
    from slipstack.lib.limit_set import load_factor
    from slipstack.lib.rig.contact import PressureModel

    scene = load_scene_by_name("fig14")  # tilted flat face: the pressure's shape does not change with f_n
    x, y, theta = scene.object.pose
    loads = np.array([[1.0, 0.0], [0.0, 0.0], [2.0, 0.0], [0.3, -0.4]])
    k = len(loads)
    o = oracle_series(scene, np.full(k, x), np.full(k, y), np.full(k, theta), np.array([3.0, 3.0, 3.0, 6.0]), loads,
                      np.zeros(k))
    mu_s = scene.contact.mu_s
    assert o.least[1] == 0.0 and o.frozen[1] == 0.0
    # off-centre pressure: zero torque about the pad origin twists the contact, so more than |f_t|/mu_s
    assert o.least[0] > 1.0 / mu_s and o.least[2] == pytest.approx(2 * o.least[0], rel=1e-6)
    np.testing.assert_allclose(o.least, o.frozen, rtol=1e-6)  # the shape scales: fixed point = frozen shape
    pressure = PressureModel(scene.contact, scene.pad, scene.object.pose)
    for f, load in zip(o.least[[0, 3]], loads[[0, 3]]):  # at the oracle's force the true pressure just holds
        phi = pressure.phi_uncached(float(f), complex(x, y), theta)
        assert load_factor(phi, scene.pad.positions, load, 0.0, mu_s).gamma == pytest.approx(1.0, rel=1e-5)


def test_the_linear_surface_never_says_stick_too_late_on_a_centred_pressure_and_the_ellipse_does():
    pad = PadGeometry()
    pressures = _pressures(pad, 10.0)
    for name in ("uniform", "Hertzian, a = 8 mm"):
        e = limit_error(pressures[name], pad.positions, 0.5, n=41, f_t_directions=2)
        assert e.linear.min() >= 0.0, name  # (5) is conservative: the exact set holds its diamond
        assert e.elliptic.min() < -0.03, name  # (6) bulges beyond the exact set on combined loads
        # on the axes (pure force, pure torque) all three agree: the exact boundary is at radius 1
        np.testing.assert_allclose(e.exact[[0, 20, -1]], 1.0, rtol=2e-3)
    off = limit_error(pressures["off-centre Hertzian, a = 5 mm at (4, 2) mm"], pad.positions, 0.5, n=41,
                      f_t_directions=2)
    assert off.linear.min() < -0.2  # a pure force about the pad origin twists an off-centre contact


def _score(label: str, us: float, missed: int, false: float, delays_ms=(-10.0,)) -> Score:
    """2 episodes over 1000 sticking frames, ``false`` of them flagged."""
    return Score(label, us, Quality(2, missed, tuple(int(d * 1e6) for d in delays_ms), int(false * 1000), 0, 1000))


def test_a_setting_is_dominated_only_by_one_at_least_as_good_in_every_respect():
    cheap_noisy = _score("coulomb", 10, 0, 0.2)
    dear_clean = _score("exact", 50, 0, 0.05)
    worse = _score("tactile_cor", 900, 0, 0.05)
    blind = _score("decoupled", 5, 2, 0.0, delays_ms=())
    scores = [cheap_noisy, dear_clean, worse, blind]
    assert [dominated(s, scores) for s in scores] == [False, False, True, False]
    assert dominated(_score("tactile_cor_robust", 60, 1, 0.05), scores)


def test_a_warning_is_on_time_not_better_than_on_time():
    """The front ranks lateness, max(delay, 0): flagging 400 ms before the onset does not beat a
    test that flags at the onset; the early one pays in false alarms instead."""
    early = _score("linear_ls", 50, 0, 0.3, delays_ms=(-400.0, -350.0))
    on_time = _score("exact", 50, 0, 0.3, delays_ms=(0.0, 0.0))
    assert early.lateness_p50_ms == on_time.lateness_p50_ms == 0.0
    assert not dominated(on_time, [early, on_time]) and not dominated(early, [early, on_time])
    late = _score("coulomb", 50, 0, 0.3, delays_ms=(5.0, 9.0))
    assert dominated(late, [early, late])
