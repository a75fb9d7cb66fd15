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
