"""A node's ``nice`` reaches its autogroup (each node runs in a session of its own)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from slipstack.launch.priority import AUTOGROUP_PATH, set_autogroup_nice

pytestmark = pytest.mark.skipif(not AUTOGROUP_PATH.exists(), reason="kernel without scheduling autogroups")


def _autogroup_nice_of_child(nice: int) -> int:
    """Start a process in a new session as the launcher does, with ``nice``; its autogroup's nice."""
    child = subprocess.run(
        [sys.executable, "-c", "print(open('/proc/self/autogroup').read())"],
        start_new_session=True, preexec_fn=lambda: set_autogroup_nice(nice), capture_output=True, text=True,
        check=True, timeout=30)
    return int(child.stdout.split("nice")[1])


def test_a_nice_reaches_the_autogroup_of_the_nodes_session() -> None:
    assert _autogroup_nice_of_child(7) == 7


def test_a_nice_in_a_missing_file_is_reported_not_raised(tmp_path) -> None:
    assert set_autogroup_nice(5, tmp_path / "absent" / "autogroup") is False
