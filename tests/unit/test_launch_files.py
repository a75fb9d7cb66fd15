"""Every shipped launch file loads, and starts only the nodes its scene needs."""

from __future__ import annotations

import pytest

from slipstack.launch.launch_file import launch_files_dir, load_launch_file
from slipstack.lib.errors import ConfigError

FILES = sorted(p.stem for p in launch_files_dir().glob("*.toml"))


@pytest.mark.parametrize("name", FILES)
def test_shipped_launch_file_loads(name):
    lf = load_launch_file(name, builtins={"run_dir": "/tmp/slipstack-test"})
    assert lf.nodes and lf.description
    assert len({e.name for e in lf.nodes}) == len(lf.nodes)


@pytest.mark.parametrize("name", ["fig10", "fig11", "fig12"])
def test_ft_only_scenes_start_no_tactile_driver_and_no_cor_estimator(name):
    types = {e.type for e in load_launch_file(name, builtins={"run_dir": "/tmp/x"}).nodes}
    assert "tactile_driver" not in types and "cor_estimator" not in types
    assert {"rig", "ft_driver", "fusion", "slip_detector", "grip_controller"} <= types


def test_overrides_are_typed_and_unknown_ones_are_named():
    lf = load_launch_file("fig15", {"controller": "false", "delta": "0.2"}, builtins={"run_dir": "/tmp/x"})
    assert "grip_controller" not in {e.type for e in lf.nodes}
    assert next(e for e in lf.nodes if e.type == "slip_detector").params["delta"] == 0.2
    with pytest.raises(ConfigError, match="no launch argument 'bogus'"):
        load_launch_file("fig15", {"bogus": "1"}, builtins={"run_dir": "/tmp/x"})
    with pytest.raises(ConfigError, match="launch argument controller: must be true or false"):
        load_launch_file("fig15", {"controller": "maybe"}, builtins={"run_dir": "/tmp/x"})


def test_a_list_argument_is_read_from_the_command_line():
    for text, want in (("[]", []), ("", []), ("[ft/wrench, slip]", ["ft/wrench", "slip"]), ("slip", ["slip"])):
        lf = load_launch_file("default", {"record_topics": text}, builtins={"run_dir": "/tmp/x"})
        assert next(e for e in lf.nodes if e.type == "recorder").params["topics"] == want


def test_the_default_recording_has_the_cor_so_tau_c_and_tau_t_can_be_drawn_afterwards():
    for name in ("stack", "fig13", "fig14", "fig15"):
        lf = load_launch_file(name, builtins={"run_dir": "/tmp/x"})
        assert "cor" in next(e for e in lf.nodes if e.type == "recorder").params["topics"]


def test_law_14_increment_is_a_launch_argument_and_a_typo_is_refused():
    from slipstack.nodes.grip_controller import GripControllerParams

    lf = load_launch_file("fig15", {"increment": "per_taxel"}, builtins={"run_dir": "/tmp/x"})
    params = next(e for e in lf.nodes if e.type == "grip_controller").params
    assert params["increment"] == "per_taxel"
    assert GripControllerParams(**params).increment == "per_taxel"
    with pytest.raises(ConfigError, match="increment must be one of total, per_taxel"):
        GripControllerParams(law="linear", increment="per-taxel")


def test_the_detection_experiments_run_at_constant_force_by_default_as_in_the_paper():
    for name in ("fig13", "fig14"):
        lf = load_launch_file(name, builtins={"run_dir": "/tmp/x"})
        assert lf.args["controller"] is False and lf.args["check"] is False, name
        assert not any(e.type == "grip_controller" for e in lf.nodes), name  # no node to raise the grip
        controlled = load_launch_file(name, {"controller": "true"}, builtins={"run_dir": "/tmp/x"})
        assert controlled.args["check"] is True, name  # with the controller, a slide fails the run


@pytest.mark.parametrize("name", ["default", "hardware"])
def test_an_ft13_law_on_the_command_line_takes_beta_from_the_material(name):
    """``slipstack launch law:=ft13``: the launch argument ``beta_m`` keeps its default 0 ("from
    data"), which the F/T-only laws read as the material's β_s (was: refused, "beta_m must be > 0")."""
    from slipstack.nodes.grip_controller import GripControllerParams
    from slipstack.nodes.material_param import resolve_material

    for law in ("ft13", "ft13_sigma"):
        lf = load_launch_file(name, {"law": law}, builtins={"run_dir": "/tmp/x"})
        params = next(e for e in lf.nodes if e.type == "grip_controller").params
        assert params["beta_m"] == 0.0
        assert GripControllerParams(**params).beta_m == resolve_material(params["material"]).beta_s_m > 0


def test_a_namespace_puts_every_topic_of_the_node_under_it_and_a_remap_wins(tmp_path):
    path = tmp_path / "two.toml"
    path.write_text('''[launch]
description = "two slip detectors"

[[node]]
name = "left"
type = "slip_detector"
namespace = "finger0"

[[node]]
name = "right"
type = "slip_detector"
namespace = "finger1"
remap = { "slip" = "right_slip" }
''')
    left, right = load_launch_file(path, builtins={"run_dir": "/tmp/x"}).nodes
    assert left.remap == {"contact": "finger0/contact", "slip": "finger0/slip"}
    assert right.remap == {"contact": "finger1/contact", "slip": "right_slip"}
    with pytest.raises(ConfigError, match="namespace"):
        path.write_text(path.read_text().replace('"finger1"', '"/finger1"'))
        load_launch_file(path, builtins={"run_dir": "/tmp/x"})


def test_the_gripper_graph_runs_each_finger_under_its_namespace():
    lf = load_launch_file("gripper", builtins={"run_dir": "/tmp/x"})
    remaps = {e.name: e.remap for e in lf.nodes}
    assert remaps["ft_driver0"]["ft/wrench"] == "finger0/ft/wrench"
    assert remaps["ft_driver1"]["ft/wrench"] == "finger1/ft/wrench"
    assert remaps["fusion1"]["tactile/frame"] == "finger1/tactile/frame"
    assert remaps["slip_detector0"]["slip"] == "finger0/slip" and remaps["grasp"] == {}
def test_the_values_an_argument_comment_lists_are_the_codes():
    """Shell completion offers the ``a | b`` an argument's comment lists (launch/launch_command.py):
    they must be the values the nodes accept."""
    from slipstack.launch.launch_command import _CHOICES
    from slipstack.launch.launch_file import arg_comments, default_launch_file
    from slipstack.lib.grip_laws import LAWS
    from slipstack.nodes.cor_estimator import SOLVERS
    from slipstack.nodes.grip_controller import INCREMENTS
    from slipstack.nodes.rig import FT_PROTOCOLS, TACTILE_PROTOCOLS
    from slipstack.nodes.slip_detector import KNOWN_COR_METHOD, SLIP_TESTS

    comments = arg_comments(default_launch_file())
    listed = {name: {v.strip() for v in m.group(0).split("|")} for name, text in comments.items()
              if (m := _CHOICES.search(text))}
    assert listed["law"] == set(LAWS)
    assert listed["method"] == {*SLIP_TESTS, KNOWN_COR_METHOD}
    assert listed["cor_solver"] == set(SOLVERS)
    assert listed["ft_protocol"] == set(FT_PROTOCOLS) and listed["tactile_protocol"] == set(TACTILE_PROTOCOLS)
    assert listed["increment"] == set(INCREMENTS)
    assert listed["rig_material"] == {p.stem for p in (default_launch_file().parents[1] / "materials").glob("*.toml")}


def test_an_indented_comment_line_continues_the_argument_above_it():
    """stack.toml's band comment runs on over an indented line; --show-args gave that line to
    f_nom_n (no comment of its own), and the gripper's gripper_driver line to gripper_port."""
    from slipstack.launch.launch_file import arg_comments, default_launch_file

    comments = arg_comments(default_launch_file())
    assert "f_nom_n" not in comments
    assert comments["band"].endswith("identified its kind, and release once the load proves a stick; fixed: delta")
    assert comments["record_topics"].endswith("[] records every topic (contact too: ~2 MB/s more)")
    gripper = arg_comments(default_launch_file().with_name("gripper.toml"))
    assert "gripper_port" not in gripper
    assert gripper["gripper_driver"].endswith("false: the rig's fingers follow grip/command directly")
