"""A full disk under the recording and the run's log never stops the control path.

fig15 runs in real time with its recording (and so the run's log beside it) on a
filesystem of 256 KiB that fills a few seconds into the scene: a tmpfs mounted in a
mount namespace of the test's own (``unshare --user --map-root-user --mount``; no
root needed where the kernel allows user namespaces, skipped where it does not). The
object must be held as on any run, and the terminal, the recording's loss count and
the summary must say that the disk was full."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

pytestmark = pytest.mark.e2e

FULL_BYTES = 256 * 1024
SLIP_BOUND_MM = 0.5  # fig15's own check: the controlled object slides less
TURN_BOUND_DEG = 0.5


def _can_mount_tmpfs(folder) -> bool:
    probe = subprocess.run(["unshare", "--user", "--map-root-user", "--mount", "--fork", "sh", "-c",
                            f"mount -t tmpfs -o size=64k none {folder}"], capture_output=True)
    return probe.returncode == 0


def test_fig15_holds_on_a_full_disk_and_says_so(run_root):
    disk = run_root / "disk"
    disk.mkdir()
    if not _can_mount_tmpfs(disk):
        pytest.skip("this kernel allows no user namespace with a mount of its own (unshare -rm)")
    summary = run_root / "summary.json"
    recording = disk / "fig15.mcap"
    # the launch, inside the namespace, on the full filesystem: `exec` keeps the launcher the test's child
    script = (f"mount -t tmpfs -o size={FULL_BYTES} none {disk} && exec {sys.executable} -m slipstack.launch.cli "
              f"launch fig15 recording:={recording} summary:={summary}")
    out = subprocess.run(["unshare", "--user", "--map-root-user", "--mount", "--fork", "sh", "-c", script],
                         capture_output=True, text=True, timeout=300,
                         env=dict(os.environ, SLIPSTACK_RUN_ROOT=str(run_root / "r"), PYTHONUNBUFFERED="1"))
    log = out.stdout + out.stderr
    assert "Traceback" not in log, log[-4000:]
    s = json.loads(summary.read_text())
    assert s["slip_distance_mm"] < SLIP_BOUND_MM and abs(s["slip_angle_deg"]) < TURN_BOUND_DEG, (s, log[-3000:])
    assert "cannot write the run's log" in log and "No space left on device" in log, log[-3000:]
    assert "cannot write the recording" in log, log[-3000:]
    loss = s["recording_loss"]["ft/wrench"]
    assert loss["not_written"] > 0 and loss["missing"] >= loss["not_written"], loss
    assert any(h["short"] == "recorder cannot write its file (No space left on device)" for h in s["health"]), s
