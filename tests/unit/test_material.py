"""Material files: the thresholds rule, the file format, and the nodes' ``material`` parameter."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from slipstack.lib.errors import ConfigError
from slipstack.lib.material import (
    DELTA_MIN,
    NOISE_FLOOR,
    Material,
    detector_thresholds,
    load_material,
    material_toml,
    parse_material,
)
from slipstack.launch.launch_file import load_launch_file
from slipstack.nodes.cor_estimator import CorParams
from slipstack.nodes.grip_controller import GripControllerParams
from slipstack.nodes.slip_detector import SlipDetectorParams

MATERIALS_DIR = Path(__file__).resolve().parents[2] / "launch" / "materials"


def test_band_is_the_lower_prediction_bound_of_the_identified_onsets() -> None:
    # Coulomb: 3 onsets 0.99-1.0 (range 0.01): the edge 0.01/4 below the lowest, less 3 sigma.
    coulomb = Material("c", mu_s=0.45, mu_d=0.45, onset_gamma=(0.995, 0.99, 1.0),
                       gamma_noise_stick=0.004, gamma_noise_slide=0.006)
    t = detector_thresholds(coulomb)
    assert t.delta == pytest.approx(1.0 - (0.99 - 0.01 / 4 - 3 * 0.004))
    # release: mu_d/mu_s - 4 sigma_slide = 0.976, capped at the band edge 0.9755
    assert t.gamma_release == pytest.approx(0.9755)
    # A weakening contact whose identified onsets are 0.85 and 0.97: the band follows them
    # (it used to reach the sliding level 0.6 whatever the data), the release level sits
    # under the sliding level.
    weak = Material("w", mu_s=0.5, mu_d=0.3, onset_gamma=(0.85, 0.97), gamma_noise_stick=0.005,
                    gamma_noise_slide=0.01)
    t = detector_thresholds(weak)
    assert t.delta == pytest.approx(1.0 - (0.85 - 0.12 / 3 - 0.015))
    assert t.gamma_release == pytest.approx(0.6 - 0.04)
    assert t.gamma_resume == pytest.approx(0.6 - 0.02)  # mu_d/mu_s - 2 sigma_slide
    # Without onsets: the worst case, the sliding level less 3 sigma.
    t = detector_thresholds(Material("n", mu_s=0.5, mu_d=0.3, gamma_noise_stick=0.005))
    assert t.delta == pytest.approx(0.4 + 0.015)
    # An onset below the sliding level (a compliant contact's partial slip): the data decide.
    t = detector_thresholds(Material("m", mu_s=0.45, mu_d=0.43, onset_gamma=(0.9,), gamma_noise_stick=0.005))
    assert t.delta == pytest.approx(0.1 + 0.015)
    # A torque ramp's lower sliding level (beta_d/beta_s) counts too.
    t = detector_thresholds(Material("b", mu_s=0.45, mu_d=0.45, beta_s_m=1e-3, beta_d_m=0.8e-3,
                                     gamma_noise_slide=0.005))
    assert t.gamma_release == pytest.approx(0.8 - 0.02)


def test_release_never_above_the_band_edge_and_noise_floor() -> None:
    # Noise-free record: the floor keeps the band open; Coulomb release capped at 1 - delta.
    t = detector_thresholds(Material("c", mu_s=0.45, mu_d=0.45, onset_gamma=(1.0,), gamma_noise_stick=0.0,
                                     gamma_noise_slide=0.0))
    assert t.delta == pytest.approx(max(3 * NOISE_FLOOR, DELTA_MIN))
    assert t.gamma_release <= 1.0 - t.delta
    assert t.gamma_release <= t.gamma_resume <= 1.0 - t.delta
    # Without onset episodes the sliding level stands in for the lowest onset.
    t = detector_thresholds(Material("r", mu_s=0.45, mu_d=0.36))
    assert t.delta == pytest.approx(1.0 - (0.8 - 3 * NOISE_FLOOR))


def test_file_round_trip_and_errors(tmp_path: Path) -> None:
    m = Material("rubber", mu_s=0.4527, mu_d=0.3612, provenance='rig "rubber"', mu_s_se=0.001, beta_s_m=1.3e-3,
                 onset_gamma=(0.98, 0.91), gamma_noise_stick=0.007)
    path = tmp_path / "m.toml"
    path.write_text(material_toml(m, "a comment"))
    back = load_material(path)
    assert back.mu_s == pytest.approx(m.mu_s) and back.onset_gamma == m.onset_gamma
    assert back.provenance == m.provenance and math.isnan(back.beta_d_m)
    with pytest.raises(ConfigError, match="material.mu_d: missing"):
        parse_material({"material": {"mu_s": 0.4}}, source="x.toml")
    with pytest.raises(ConfigError, match="x.toml: material.mu_x: unknown key"):
        parse_material({"material": {"mu_s": 0.4, "mu_d": 0.3, "mu_x": 1}}, source="x.toml")
    with pytest.raises(ConfigError, match="mu_d must lie in"):
        parse_material({"material": {"mu_s": 0.4, "mu_d": 0.5}}, source="x.toml")
    with pytest.raises(ConfigError, match="slipstack identify"):
        parse_material({"mu_s": 0.4}, source="x.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text("[material\n")
    with pytest.raises(ConfigError, match="bad.toml: TOML syntax error"):
        load_material(bad)


@pytest.mark.parametrize("path", sorted(MATERIALS_DIR.glob("*.toml")), ids=lambda p: p.stem)
def test_shipped_materials_load_with_provenance(path: Path) -> None:
    m = load_material(path)
    assert m.provenance and "provisional" not in m.provenance
    assert math.isfinite(m.beta_s_m) and m.onset_gamma
    # identified with model errors, written apart from the standard errors
    assert all(math.isfinite(v) and v >= 0 for v in (m.mu_s_model, m.mu_d_model, m.beta_s_model_m, m.beta_d_model_m))


def test_node_params_take_the_material_and_explicit_values_win(tmp_path: Path) -> None:
    m = Material("mine", mu_s=0.6, mu_d=0.3, beta_s_m=2e-3, onset_gamma=(0.9,), gamma_noise_stick=0.005,
                 gamma_noise_slide=0.01)
    path = tmp_path / "mine.toml"
    path.write_text(material_toml(m))
    t = detector_thresholds(m)
    p = SlipDetectorParams(material=str(path))
    assert (p.mu, p.delta, p.gamma_release) == pytest.approx((0.6, t.delta, t.gamma_release))
    assert p.gamma_resume == pytest.approx(t.gamma_resume) and p.gamma_resume > p.gamma_release
    p = SlipDetectorParams(material=str(path), delta=0.05, mu=0.5)
    assert (p.mu, p.delta, p.gamma_release) == pytest.approx((0.5, 0.05, t.gamma_release))
    g = GripControllerParams(material=str(path), law="ft13")
    assert (g.mu, g.beta_m, g.delta) == pytest.approx((0.6, 2e-3, t.delta))
    assert CorParams(material=str(path)).mu == pytest.approx(0.6)
    with pytest.raises(ConfigError, match="cannot find 'nosuch'"):
        SlipDetectorParams(material="nosuch")


def test_every_stack_launch_file_takes_material(tmp_path: Path) -> None:
    path = tmp_path / "mine.toml"
    path.write_text(material_toml(Material("mine", mu_s=0.6, mu_d=0.3)))
    for name in ("default", "fig15", "fig11", "fig4a", "hardware"):
        lf = load_launch_file(name, {"material": str(path)}, builtins={"run_dir": "/tmp/x"})
        for entry in lf.nodes:
            if entry.type in ("slip_detector", "grip_controller", "cor_estimator"):
                assert entry.params["material"] == str(path), (name, entry.name)


def test_the_band_is_at_most_half_of_the_sliding_capacity() -> None:
    # A contact that slides at a fifth of its static friction, no onsets: 1 - (0.2 - 3 * noise)
    # is over 0.8; the band stops at DELTA_MAX = 0.5 (docs/modules.md, lib/material.py).
    assert detector_thresholds(Material("steep", mu_s=0.5, mu_d=0.1)).delta == 0.5


@pytest.mark.parametrize("mu_s", [0.0, -0.1, math.inf, math.nan])
def test_mu_s_must_be_finite_and_positive(mu_s: float) -> None:
    with pytest.raises(ConfigError, match="mu_s must be a finite number > 0"):
        Material("bad", mu_s=mu_s, mu_d=0.1)


def test_each_material_bound_admits_its_edge_and_refuses_past_it() -> None:
    slack = Material("slack", mu_s=0.45, mu_d=0.45 * (1 + 1e-9))  # mu_d = mu_s within the stated rounding
    assert slack.sliding_level == 1.0  # never above 1, though mu_d / mu_s is
    noisy = Material("noisy", mu_s=0.45, mu_d=0.45 * (1 + 1e-9), beta_s_m=0.010, beta_d_m=0.011)
    assert noisy.sliding_level == 1.0  # nor where beta_d / beta_s is too (identified within their errors)
    assert Material("top", mu_s=0.45, mu_d=0.3, onset_gamma=(1.5,)).onset_gamma == (1.5,)
    for kwargs, what in [({"mu_d": 0.0}, "mu_d"), ({"onset_gamma": (0.0,)}, "onset_gamma"),
                         ({"onset_gamma": (math.nextafter(1.5, 2.0),)}, "onset_gamma"),
                         ({"onset_gamma": (2.0,)}, "onset_gamma")]:
        with pytest.raises(ConfigError, match=f"{what} (entries )?must"):
            Material("bad", **{"mu_s": 0.45, "mu_d": 0.3, **kwargs})


def test_a_zero_beta_s_is_taken_as_not_identified() -> None:
    assert Material("flat", mu_s=0.5, mu_d=0.4, beta_s_m=0.0, beta_d_m=0.0).sliding_level == pytest.approx(0.8)


def test_onsets_above_one_put_the_band_edge_at_one() -> None:
    # Every identified onset above gamma = 1 (the load passed the static limit before slipping):
    # the edge is 1 less the onsets' spread below the lowest (0.1 / 3) and 3 x the noise floor.
    late = Material("late", mu_s=0.45, mu_d=0.45, onset_gamma=(1.2, 1.3))
    assert detector_thresholds(late).delta == pytest.approx(0.1 / 3 + 3 * 0.002, abs=1e-12)


@pytest.mark.parametrize("data, message", [
    ({"material": {"mu_s": "0.45", "mu_d": 0.3}}, "material.mu_s: must be a number"),
    ({"material": {"mu_s": True, "mu_d": 0.3}}, "material.mu_s: must be a number"),
    ({"material": {"mu_s": 0.45, "mu_d": 0.3}, "extra": {}}, "exactly one table"),
    ({"material": {"mu_s": 0.45, "mu_d": 0.3, "name": 5}}, "must be strings"),
    ({"material": {"mu_s": 0.45, "mu_d": 0.3, "onset_gamma": 0.9}}, "must be a list of numbers"),
    ({"material": {"mu_s": 0.45, "mu_d": 0.3, "onset_gamma": [True]}}, "must be a list of numbers"),
])
def test_a_file_of_the_wrong_types_is_refused_naming_the_key(data: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_material(data, source="m.toml")


@pytest.mark.parametrize("key, value", [("mu_s", 4.5), ("mu_d", 0.001), ("beta_s_m", 3.44), ("beta_d_m", -1e-3)])
def test_a_material_file_with_an_implausible_coefficient_is_refused_naming_it(key: str, value: float) -> None:
    """A typo (mu_s = 4.5 for 0.45, beta in mm) was loaded silently; refused, with what to do.
    A file identify --force wrote (marked refused) still loads: the detector says so."""
    table = {"mu_s": 0.45, "mu_d": 0.3, "beta_s_m": 3e-3, "beta_d_m": 2e-3, key: value}
    with pytest.raises(ConfigError, match=rf"m.toml: material.{key} = {value:g} lies outside the plausible .* "
                                          r"\(docs/materials.md\): a typo\? .*slipstack identify"):
        parse_material({"material": table}, source="m.toml")
    assert getattr(parse_material({"material": {**table, "refused": "why"}}, source="m.toml"), key) == value
    edges = parse_material({"material": {"mu_s": 3.0, "mu_d": 0.02, "beta_s_m": 0.1, "beta_d_m": 0.0}})
    assert (edges.mu_s, edges.mu_d, edges.beta_s_m) == (3.0, 0.02, 0.1)  # the range is inclusive


@pytest.mark.parametrize("cls, kwargs", [(SlipDetectorParams, {"mu": 4.5}), (SlipDetectorParams, {"delta": 0.9}),
                                         (SlipDetectorParams, {"beta_m": 3.44}), (CorParams, {"mu": 0.0101}),
                                         (GripControllerParams, {"beta_m": 3.44, "law": "ft13"}),
                                         (GripControllerParams, {"mu": 45.0})])
def test_an_implausible_friction_parameter_is_refused_naming_it(cls: type, kwargs: dict) -> None:
    name, value = next(iter(kwargs.items()))
    with pytest.raises(ConfigError, match=rf"{name} := {value:g} lies outside the plausible .*: a typo\? Correct "
                                          rf"it, or leave {name} at nan"):
        cls(**kwargs)
    assert getattr(cls(**{**kwargs, name: {"mu": 3.0, "delta": 0.5, "beta_m": 0.1}[name]}), name) > 0  # edges


def test_identify_refuses_an_implausible_coefficient() -> None:
    from slipstack.analysis.identify_cli import _implausible

    reasons = _implausible(Material("slick", mu_s=4.5, mu_d=3.6), {}, [], [])
    assert any(r.startswith("mu_s = 4.5 lies outside the plausible") for r in reasons), reasons
    assert any(r.startswith("mu_d = 3.6 lies outside") for r in reasons), reasons
    assert _implausible(Material("ok", mu_s=0.45, mu_d=0.36), {}, [], []) == []
