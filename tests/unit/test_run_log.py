"""The run's log file on a full disk or a missing folder: the launch goes on, the terminal says why."""

from __future__ import annotations

from pathlib import Path

import pytest

from slipstack.lib.errors import ConfigError
from slipstack.launch.run_log import RunLog

FULL_DEVICE = Path("/dev/full")  # every write fails with ENOSPC, as on a full disk


@pytest.mark.skipif(not FULL_DEVICE.exists(), reason="needs Linux's /dev/full")
def test_a_full_disk_never_raises_and_the_terminal_keeps_every_line():
    shown: list[str] = []
    log = RunLog(shown.append, FULL_DEVICE)
    for k in range(3):
        log(f"[rig] line {k}")
        log.held(f"[rig] held {k}")
    log.close()
    assert [line for line in shown if line.startswith("[rig]")] == [f"[rig] line {k}" for k in range(3)]
    warnings = [line for line in shown if "cannot write the run's log" in line]
    assert len(warnings) == 1 and "No space left on device" in warnings[0], shown


def test_a_missing_folder_is_refused_not_created(tmp_path):
    path = tmp_path / "no" / "such" / "x.log"
    with pytest.raises(ConfigError, match="recording:=PATH"):
        RunLog(lambda line: None, path)
    assert not (tmp_path / "no").exists()


def test_the_folder_of_the_default_recording_is_made(tmp_path):
    log = RunLog(lambda line: None, tmp_path / "runs" / "x.log")
    log("[launch] hello")
    log.close()
    assert (tmp_path / "runs" / "x.log").read_text().endswith("[launch] hello\n")
