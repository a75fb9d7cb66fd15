"""The run root is the user's alone, and nothing is written through a planted symlink."""

from __future__ import annotations

import json
import os
import stat

import pytest

from slipstack.launch.launch_file import load_launch_file
from slipstack.lib.errors import ConfigError
from slipstack.nodes.runtime.graph_info import find_run_dir, write_graph
from slipstack.nodes.runtime.transport import make_run_dir, run_root


@pytest.fixture
def root(tmp_path, monkeypatch):
    """``$SLIPSTACK_RUN_ROOT`` set to a path that does not exist yet."""
    path = tmp_path / "root"
    monkeypatch.setenv("SLIPSTACK_RUN_ROOT", str(path))
    return path


def test_a_missing_run_root_is_made_private(root):
    assert run_root() == root
    assert stat.S_IMODE(root.stat().st_mode) == 0o700
    run = make_run_dir()
    assert run.parent == root and stat.S_IMODE(run.stat().st_mode) == 0o700


@pytest.mark.parametrize("mode", [0o777, 0o755, 0o1777, 0o710])
def test_a_run_root_open_to_others_is_refused(root, mode):
    root.mkdir()
    root.chmod(mode)
    with pytest.raises(ConfigError, match=rf"run root {root} is open to other users \(mode {mode:04o}\).*"
                                          rf"Chmod 700 {root}, or set \$SLIPSTACK_RUN_ROOT"):
        make_run_dir()
    assert list(root.iterdir()) == []


def test_a_run_root_that_is_a_file_or_a_broken_link_is_refused(root, tmp_path):
    root.write_text("squatted")
    with pytest.raises(ConfigError, match=rf"run root {root} is not a directory.*Remove {root}"):
        run_root()
    root.unlink()
    root.symlink_to(tmp_path / "nowhere")
    with pytest.raises(ConfigError, match=rf"run root {root} cannot be used .*remove it"):
        run_root()


def test_graph_json_is_not_written_through_planted_symlinks(root, tmp_path):
    run = make_run_dir()
    victims = {name: tmp_path / f"victim-{name}" for name in ("graph.json", "graph.json.tmp")}
    for name, victim in victims.items():
        victim.write_text("do not touch")
        victim.chmod(0o600)
        (run / name).symlink_to(victim)
    write_graph(run, {"launcher_pid": None, "nodes": {}})
    assert all(v.read_text() == "do not touch" for v in victims.values())
    assert not (run / "graph.json").is_symlink()
    assert json.loads((run / "graph.json").read_text()) == {"launcher_pid": None, "nodes": {}}
    assert stat.S_IMODE((run / "graph.json").stat().st_mode) == 0o600


def test_spec_files_are_not_written_through_planted_symlinks(root, tmp_path):
    from slipstack.launch.launcher import Launcher

    run = make_run_dir()
    victim = tmp_path / "victim"
    victim.write_text("do not touch")
    (run / "relay.spec.json").symlink_to(victim)
    lf = load_launch_file("demo", builtins={"run_dir": str(run)})
    launcher = Launcher(lf, run, echo=lambda line: None)
    launcher.control.close(linger=0)
    assert victim.read_text() == "do not touch"
    assert json.loads((run / "relay.spec.json").read_text())["name"] == "relay"


def test_a_directory_named_current_is_a_clear_error(root):
    run = make_run_dir()
    (root / "current").mkdir()
    with pytest.raises(ConfigError, match=rf"{root}/current is not a symlink to a run directory; remove it"):
        write_graph(run, {"nodes": {}})
    assert (root / "current").is_dir()


def test_current_points_at_the_newest_run(root):
    first, second = make_run_dir(), make_run_dir()
    write_graph(first, {"nodes": {}})
    write_graph(second, {"nodes": {}})
    assert (root / "current").resolve() == second.resolve()
    assert find_run_dir() == second.resolve()


def test_a_graph_whose_launcher_is_gone_is_stale(root):
    run = make_run_dir()
    gone = os.fork()
    if gone == 0:
        os._exit(0)
    os.waitpid(gone, 0)
    write_graph(run, {"launcher_pid": gone, "launcher_start_ticks": 1, "nodes": {}})
    with pytest.raises(ConfigError, match=rf"no running graph \(launcher pid {gone} is gone; run directory "
                                          rf"{run.resolve()} is stale\)"):
        find_run_dir()


def test_a_reused_launcher_pid_is_not_taken_for_the_launcher(root):
    """Our own pid, alive, but with another start time: not the process that wrote the graph."""
    from slipstack.nodes.runtime.graph_info import process_start_ticks

    run = make_run_dir()
    write_graph(run, {"launcher_pid": os.getpid(), "launcher_start_ticks": process_start_ticks(os.getpid()) + 1,
                      "nodes": {}})
    with pytest.raises(ConfigError, match="is stale"):
        find_run_dir()
    write_graph(run, {"launcher_pid": os.getpid(), "launcher_start_ticks": process_start_ticks(os.getpid()),
                      "nodes": {}})
    assert find_run_dir() == run.resolve()


def test_finished_run_directories_keep_their_reports_and_only_the_newest_are_kept(root):
    from slipstack.nodes.runtime.run_dir import KEEP_FINISHED_RUNS, finish_run_dir

    runs = []
    for k in range(KEEP_FINISHED_RUNS + 3):
        run = make_run_dir()
        (run / "graph.json").write_text("{}")
        (run / "node.pub").write_text("")
        (run / "launch_events.json").write_text("{}")
        finish_run_dir(run, keep=("launch_events.json",))
        os.utime(run / ".finished", (k, k))  # oldest first
        runs.append(run)
    assert sorted(p.name for p in runs[-1].iterdir()) == [".finished", "launch_events.json"]
    live = make_run_dir()
    assert live.is_dir()
    assert [r for r in runs if r.exists()] == runs[-KEEP_FINISHED_RUNS:]
    assert KEEP_FINISHED_RUNS == 20  # the documented 20 (docs/modules.md, run_dir.py)


def test_a_run_root_is_made_with_its_missing_parents(tmp_path, monkeypatch):
    root = tmp_path / "a" / "b" / "root"
    monkeypatch.setenv("SLIPSTACK_RUN_ROOT", str(root))
    assert run_root() == root and stat.S_IMODE(root.stat().st_mode) == 0o700


def test_finishing_removes_folders_and_links_but_never_what_a_link_points_to(root, tmp_path):
    from slipstack.nodes.runtime.run_dir import finish_run_dir, remove_run_dir, write_private_file

    run = make_run_dir()
    (run / "logs").mkdir()
    (run / "logs" / "node.log").write_text("x")
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "keep.txt").write_text("y")
    (run / "linked").symlink_to(outside, target_is_directory=True)
    assert write_private_file(run, "report.json", "{}") == run / "report.json"
    finish_run_dir(run, keep=("report.json",))
    assert sorted(p.name for p in run.iterdir()) == [".finished", "report.json"]
    assert (outside / "keep.txt").read_text() == "y"
    remove_run_dir(run)
    remove_run_dir(run)  # a second clean-up (the launcher's, after an error) finds nothing and does not raise
    assert not run.exists()
