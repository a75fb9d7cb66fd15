"""The launch plan is a value: what runs where, wired how, started and stopped in which
order, computed without binding a socket or writing a file."""

from __future__ import annotations

from pathlib import Path

import pytest

from slipstack.launch.launch_file import load_launch_file
from slipstack.launch.plan import plan_launch
from slipstack.lib.errors import ConfigError


def _plan(tmp_path: Path, name: str = "stack", **args: str):
    run_dir = tmp_path / "run"
    return plan_launch(load_launch_file(name, args, builtins={"run_dir": str(run_dir)}), run_dir)


def test_planning_binds_nothing_and_writes_nothing(tmp_path: Path) -> None:
    plan = _plan(tmp_path)
    assert list(tmp_path.iterdir()) == []
    assert plan.processes["control"].spec_path == tmp_path / "run" / "control.spec.json"


def test_a_container_hands_over_inside_and_subscribes_only_to_outside_publishers(tmp_path: Path) -> None:
    plan = _plan(tmp_path)
    members = {m["name"]: m for m in plan.processes["control"].spec["members"]}
    assert set(members) == {"fusion", "cor_estimator", "slip_detector", "grip_controller"}
    slip, grip, fusion = members["slip_detector"], members["grip_controller"], members["fusion"]
    assert slip["local"] == {"contact": ["fusion"]} and slip["subs"]["contact"] == []
    assert grip["local"] == {"slip": ["slip_detector"]}
    # fusion reads the drivers over the bus, and waits only for subscribers outside its process
    assert fusion["subs"]["ft/wrench"] == [plan.nodes["ft_driver"].endpoint]
    assert fusion["local"] == {}
    # every subscriber of `contact` is in its process (the recorder does not record it by default)
    assert "contact" not in fusion["expected_subscribers"]
    # the container starts after the processes that subscribe to it, before its drivers
    assert plan.order.index("monitor") < plan.order.index("control") < plan.order.index("ft_driver")
    assert plan.order.index("rig") < plan.order.index("ft_driver")  # the drivers start `after` the rig


def test_on_shutdown_the_simulated_world_stops_before_its_controller(tmp_path: Path) -> None:
    plan = _plan(tmp_path)
    stop = plan.stop_order(plan.order)
    assert stop[0] == "rig"
    assert stop[1:] == [n for n in reversed(plan.order) if n != "rig"]
    assert plan.node_stop_order()[0] == "rig"
    assert sorted(plan.node_order()) == sorted(plan.nodes)


def test_without_a_container_every_node_is_a_process_of_its_own(tmp_path: Path) -> None:
    plan = _plan(tmp_path, container="")
    assert set(plan.processes) == set(plan.nodes)
    assert all(not p.is_container and "members" not in p.spec for p in plan.processes.values())


def test_after_constraints_that_form_a_cycle_are_named(tmp_path: Path) -> None:
    launch = load_launch_file("demo", builtins={"run_dir": str(tmp_path)})
    by_name = {e.name: e for e in launch.nodes}
    by_name["source"].after, by_name["sink"].after = ["sink"], ["source"]
    with pytest.raises(ConfigError, match="'after' constraints form a cycle"):
        plan_launch(launch, tmp_path)


def test_a_machines_share_runs_its_nodes_and_reaches_the_others_over_tcp(tmp_path: Path) -> None:
    launch = load_launch_file("two_hosts", builtins={"run_dir": str(tmp_path / "run")})
    robot, workstation = (plan_launch(launch, tmp_path / "run", m) for m in ("robot", "workstation"))
    assert list(tmp_path.iterdir()) == []  # nothing bound or written
    assert set(robot.processes) == {"rig", "ft_driver", "tactile_driver"}
    assert "rig" not in workstation.processes and "control" in workstation.processes
    assert set(robot.nodes) == set(workstation.nodes) == {e.name for e in launch.nodes}
    driver = robot.processes["ft_driver"].spec
    assert driver["pub"].startswith("ipc://") and driver["pub_remote"].startswith("tcp://127.0.0.1:")
    # both shares compute the driver's tcp endpoint alike; the workstation connects to it there
    assert workstation.nodes["ft_driver"].endpoint == driver["pub_remote"]
    fusion = {m["name"]: m for m in workstation.processes["control"].spec["members"]}["fusion"]
    assert fusion["subs"]["ft/wrench"] == [driver["pub_remote"]]
    assert driver["expected_subscribers"]["ft/wrench"] >= 1  # fusion on the workstation is waited for
    assert workstation.order and set(workstation.order) == set(workstation.processes)


def test_without_a_machine_every_machines_nodes_are_planned_here(tmp_path: Path) -> None:
    """The lock-step run: every node of a graph over machines, in one place, on ipc."""
    launch = load_launch_file("two_hosts", builtins={"run_dir": str(tmp_path)})
    plan = plan_launch(launch, tmp_path)
    assert plan.node_order() and sorted(plan.node_order()) == sorted(plan.nodes)
    assert all(n.endpoint.startswith("ipc://") and n.remote_endpoint is None for n in plan.nodes.values())
    with pytest.raises(ConfigError, match=r"no machine 'lab'; machines: robot, workstation"):
        plan_launch(launch, tmp_path, "lab")


def test_grip_commands_verdicts_and_the_fingers_report_are_injected_only_where_the_launch_allows(tmp_path: Path):
    plan = _plan(tmp_path, "fig15")
    assert plan.nodes["rig"].inject == {}  # grip/command: only the controller commands the finger
    assert set(plan.nodes["grip_controller"].inject) == {"contact", "cor"}  # no slip, no grip/state
    assert set(plan.nodes["fusion"].inject) == {"ft/wrench", "tactile/frame"}  # sensor data: replay, tests
    own = tmp_path / "manual.toml"
    own.write_text('[launch]\nextends = "fig15.toml"\nallow_inject = ["grip/command"]\n')
    plan = _plan(tmp_path, str(own))
    assert set(plan.nodes["rig"].inject) == {"grip/command"} and "slip" not in plan.nodes["grip_controller"].inject
    own.write_text('[launch]\nextends = "fig15.toml"\nallow_inject = ["grip/comand"]\n')
    with pytest.raises(ConfigError, match=r"allow_inject names \['grip/comand'\], which no node"):
        _plan(tmp_path, str(own))
