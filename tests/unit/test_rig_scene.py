"""Scene files: the shipped paper scenes load and run; bad files name the bad key."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

import slipstack.launch
from slipstack.lib.errors import ConfigError
from slipstack.lib.rig.scene import load_scene, parse_scene
from slipstack.lib.samples import FtSample, TactileSample
from slipstack.lib.rig.simulator import Simulator, Truth

SCENES = Path(slipstack.launch.__file__).parent / "scenes"
PAPER = ["fig4a", "fig4b", "fig10", "fig11", "fig12", "fig13", "fig14", "fig15", "default"]


def minimal() -> dict:
    return {
        "object": {"mass_kg": 0.2},
        "contact": {"model": "flat"},
        "dof": {"free": ["x"]},
        "disturbance": {"segments": [{"kind": "ramp", "duration_s": 1.0, "force_N": [1.0, 0.0]}]},
    }


FT_ONLY = {"fig10", "fig11", "fig12"}  # the paper's F/T-only experiments simulate no tactile pad


@pytest.mark.parametrize("name", PAPER)
def test_shipped_scene_loads_and_streams_the_sensors_it_needs(name):
    path = SCENES / f"{name}.toml"
    assert path.read_text().startswith("# "), "scene files start with a comment header"
    scene = load_scene(path)
    assert scene.name == name
    sim = Simulator(dataclasses.replace(scene, duration_s=0.02))
    kinds = {type(s) for s in sim}
    assert kinds == ({FtSample, Truth} if name in FT_ONLY else {FtSample, TactileSample, Truth})


def test_paper_scene_degrees_of_freedom():
    assert load_scene(SCENES / "fig13.toml").dof.free == ("theta",)
    assert load_scene(SCENES / "fig13.toml").dof.pivot_m is not None
    assert load_scene(SCENES / "fig14.toml").dof.free == ("x", "y", "theta")
    assert load_scene(SCENES / "fig10.toml").dof.free == ("x",)


def test_defaults_fill_in():
    scene = parse_scene(minimal())
    assert scene.pad.rows == 16 and scene.sim.step_us == 1000
    assert scene.contact.mu_s == 0.45 and scene.finger.f_max_N == 20.0
    assert scene.disturbance.segments[0].target == (1.0, 0.0, 0.0)


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["contact"].update(mu_z=1), "contact.mu_z: unknown key"),
    (lambda d: d["contact"].update(mu_s=0.3, mu_d=0.4), "contact.mu_d: must be <="),
    (lambda d: d["contact"].update(model="sphere"), "contact.model: must be one of"),
    (lambda d: d["object"].update(mass_kg="heavy"), "object.mass_kg: must be a number"),
    (lambda d: d["object"].update(mass_kg=-1.0), "object.mass_kg: must be >"),
    (lambda d: d.pop("dof"), "dof: missing required key"),
    (lambda d: d["dof"].update(free=["z"]), "dof.free"),
    (lambda d: d["dof"].update(pivot_m=[0.0, 0.0]), "dof.pivot_m"),
    (lambda d: d["disturbance"]["segments"][0].update(kind="jump"),
     r"disturbance.segments\[0\].kind"),
    (lambda d: d["disturbance"]["segments"][0].pop("force_N"), "needs a target"),
    (lambda d: d["disturbance"]["segments"].append({"kind": "sine", "duration_s": 1.0}),
     r"segments\[1\].frequency_hz: missing"),
    (lambda d: d.update(sensors={"tactile": {"dead_taxels": [[16, 0]]}}),
     "sensors.tactile.dead_taxels"),
    (lambda d: d.update(sensors={"ft": {"rate_hz": 0}}), "sensors.ft.rate_hz"),
    (lambda d: d.update(finger={"f_initial_N": 30.0}), "finger.f_initial_N: must be <="),
    (lambda d: d.update(extra=1), "extra: unknown key"),
])
def test_config_errors_name_the_key(edit, message):
    data = minimal()
    edit(data)
    with pytest.raises(ConfigError, match=message):
        parse_scene(data, source="bad.toml")


def test_toml_syntax_and_missing_file(tmp_path):
    bad = tmp_path / "broken.toml"
    bad.write_text("[object\nmass_kg = 1")
    with pytest.raises(ConfigError, match="broken.toml: TOML syntax error"):
        load_scene(bad)
    with pytest.raises(ConfigError, match="cannot read scene file"):
        load_scene(tmp_path / "nope.toml")
