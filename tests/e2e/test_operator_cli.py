"""Issue 13 ("the operator's day"): the exact commands a new user types, as subprocesses.

Each test is one item of the issue: the command, its exit code and the words it prints.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.e2e

PY = sys.executable


def slipstack(*args: str, timeout: float = 60.0, env: dict | None = None) -> subprocess.CompletedProcess:
    """``slipstack ARGS`` as a subprocess (never hangs the suite: a hard timeout)."""
    return subprocess.run([PY, "-m", "slipstack.launch.cli", *args], capture_output=True, text=True,
                          timeout=timeout, env=env or dict(os.environ))


# -- item 2: slipstack run NODE ----------------------------------------------------------------
def test_run_without_pub_says_what_to_do_in_one_line():
    out = slipstack("run", "wrench_source")
    assert out.returncode == 2, out
    assert "Traceback" not in out.stderr and len(out.stderr.splitlines()) == 1, out.stderr
    assert "--pub ipc://" in out.stderr and "ft/wrench" in out.stderr


def test_run_driver_without_url_names_the_missing_parameter():
    out = slipstack("run", "ft_driver")
    assert out.returncode == 2, out
    assert len(out.stderr.splitlines()) == 1, out.stderr
    assert "missing parameter url" in out.stderr and "url:=" in out.stderr
    assert "__init__" not in out.stderr and "positional argument" not in out.stderr


# -- item 8: bag and report error paths ----------------------------------------------------------
@pytest.fixture
def text_file(tmp_path):
    path = tmp_path / "notes.txt"
    path.write_text("hello, not a recording\n")
    return path


@pytest.fixture
def recording(tmp_path):
    """A small real recording (RecordingWriter, as the recorder writes it)."""
    import numpy as np

    from slipstack.messages import Header, Wrench, encode
    from slipstack.nodes.bag_io import RecordingWriter

    path = tmp_path / "run.mcap"
    with RecordingWriter(path, wall_minus_monotonic_ns=1_000) as w:
        for k in range(50):
            stamp = 1_000_000_000 + k * 1_000_000
            w.write("ft/wrench", encode(Wrench(force=np.array([0.0, 0.0, -5.0]), torque=np.zeros(3),
                                               header=Header(stamp, k, stamp, {}))), stamp + 1_000)
    return path


@pytest.mark.parametrize("verb", ["info", "export"])
@pytest.mark.parametrize("content", ["text", "empty"])
def test_bag_info_and_export_refuse_what_is_not_a_recording(verb, content, text_file, tmp_path):
    path = text_file if content == "text" else tmp_path / "empty.mcap"
    if content == "empty":
        path.write_bytes(b"")
    args = ["bag", verb, str(path)] + (["-o", str(tmp_path / "out.mcap")] if verb == "export" else [])
    out = slipstack(*args)
    assert out.returncode == 2, out
    assert ("not an MCAP recording" if content == "text" else "is empty") in out.stderr
    assert not (tmp_path / "out.mcap").exists()


def test_bag_export_to_csv_is_refused_with_the_formats(recording, tmp_path):
    out = slipstack("bag", "export", str(recording), "-o", str(tmp_path / "x.csv"))
    assert out.returncode == 2, out
    assert "OUT.mcap" in out.stderr and "OUT.jsonl" in out.stderr
    assert not (tmp_path / "x.csv").exists()


def test_bag_play_rate_zero_is_refused_before_connecting(recording):
    env = dict(os.environ, SLIPSTACK_RUN_DIR="/nonexistent/run")  # connecting would fail differently
    out = slipstack("bag", "play", str(recording), "--rate", "0", env=env)
    assert out.returncode == 2, out
    assert "--rate must be > 0" in out.stderr and "no running" not in out.stderr


def test_report_to_an_unknown_figure_format_lists_the_formats(recording, tmp_path):
    out = slipstack("report", str(recording), "-o", str(tmp_path / "fig.xyz"))
    assert out.returncode == 2, out
    assert "fig.xyz" in out.stderr and ".png" in out.stderr and ".svg" in out.stderr
    assert "Traceback" not in out.stderr
