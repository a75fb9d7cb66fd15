"""Bad input a user may give gets one line saying what to do, not a traceback, a hang or a
change on disk (each case a user's command line from issue 29)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from slipstack.lib.calibration import Calibration
from slipstack.lib.errors import ConfigError
from slipstack.lib.rig.scene import load_scene
from slipstack.nodes.recording.bag_io import claim_recording_path
from slipstack.nodes.runtime import run_dir

DEEP = "[" * 5000 + "]" * 5000


def _slipstack(*args: str, cwd: Path, timeout: float = 60.0) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "slipstack.launch.cli", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=timeout, env=dict(os.environ, SLIPSTACK_RUN_ROOT=str(cwd / "root")))


def test_deeply_nested_toml_is_a_syntax_error_in_every_file_kind(tmp_path):
    launch = tmp_path / "deep.toml"
    launch.write_text(f'[launch]\ndescription = "x"\n[args]\nx = {DEEP}\n')
    out = _slipstack("launch", str(launch), cwd=tmp_path)
    assert out.returncode == 2 and "Traceback" not in out.stderr, out.stderr[-2000:]
    assert "nested too deeply" in out.stderr
    scene = tmp_path / "scene.toml"
    scene.write_text(f"x = {DEEP}\n")
    with pytest.raises(ConfigError, match="nested too deeply"):
        load_scene(scene)
    with pytest.raises(ConfigError, match="nested too deeply"):
        Calibration.from_toml(f"counts = {DEEP}\n")


@pytest.mark.parametrize("where, extra", [("/proc/self", []), ("/proc/self", ["--machine", "a", "--machine", "b"]),
                                          ("papers", [])])
def test_keys_into_a_folder_that_is_not_theirs_are_refused_and_it_is_left_alone(tmp_path, where, extra):
    if where == "papers":  # a folder of other files (the keys made it mode 0700 and wrote into it)
        (tmp_path / where).mkdir(mode=0o755)
        (tmp_path / where / "notes.txt").write_text("mine")
        where = str(tmp_path / where)
    mode, entries = os.stat(where).st_mode, sorted(os.listdir(where))
    out = _slipstack("keys", where, *extra, cwd=tmp_path)
    assert out.returncode == 2 and "Traceback" not in out.stderr, out.stderr[-2000:]
    assert "give a new one" in out.stderr or "give a new directory" in out.stderr, out.stderr
    assert os.stat(where).st_mode == mode and sorted(os.listdir(where)) == entries


def test_a_summary_path_that_is_a_directory_or_in_no_folder_is_refused_before_the_launch(tmp_path):
    for summary, said in ((tmp_path, "is a directory; give a file in it"), (tmp_path / "no" / "s.json", "does not exist")):
        out = _slipstack("launch", "fig15", f"summary:={summary}", "record:=false", cwd=tmp_path)
        assert out.returncode == 2 and said in out.stderr and "Traceback" not in out.stderr, out.stderr[-2000:]


def test_a_sensor_rate_beyond_any_sensor_is_refused_not_run_forever(tmp_path):
    out = _slipstack("launch", "fig15", "--lockstep", "ft_rate_hz:=1e12", "record:=false", cwd=tmp_path)
    assert out.returncode == 2 and "ft_rate_hz must be 0 (the scene's) up to 10000 Hz" in out.stderr, out.stderr


def test_a_recording_in_a_missing_tree_is_refused_and_no_folder_is_made(tmp_path):
    out = _slipstack("launch", "fig15", "--lockstep", f"recording:={tmp_path}/nonexistent/dir/x.mcap", cwd=tmp_path)
    assert out.returncode == 2 and "does not exist" in out.stderr, out.stderr[-2000:]
    assert not (tmp_path / "nonexistent").exists()
    out = _slipstack("launch", "fig15", f"recording:={tmp_path}/nonexistent/dir/x.mcap", cwd=tmp_path)
    assert out.returncode == 2 and "Traceback" not in out.stderr and not (tmp_path / "nonexistent").exists()
    claim_recording_path(tmp_path / "runs" / "x.mcap")  # the default runs/ folder is made, one level
    assert (tmp_path / "runs" / "x.mcap").is_file()


@pytest.mark.skipif(os.getuid() != 0, reason="making a link owned by another user needs root")
def test_a_run_root_reached_through_another_users_link_says_so(tmp_path, monkeypatch):
    target = tmp_path / "mine"
    target.mkdir(mode=0o700)
    link = tmp_path / "root"
    link.symlink_to(target)
    os.lchown(link, 12345, 12345)
    monkeypatch.setenv(run_dir.RUN_ROOT_ENV, str(link))
    with pytest.raises(ConfigError, match=r"is a symbolic link owned by uid 12345, not by you \(uid 0\)"):
        run_dir.run_root()
