"""``slipstack launch FILE --lockstep``: every shipped launch file runs on the simulated
clock through the real command line, the same recording comes out twice, and a launch
on real devices is refused with what to do instead."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from slipstack.launch.cli import main
from slipstack.launch.launch_file import launch_files_dir
from slipstack.messages import decode
from slipstack.nodes.recording.bag_io import read_recording

SHIPPED = sorted(p.stem for p in launch_files_dir().glob("*.toml") if p.stem != "hardware")
SHORT_S = "0.15"


@pytest.fixture(autouse=True)
def _run_root(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SLIPSTACK_RUN_ROOT", str(tmp_path / "runs"))
    monkeypatch.chdir(tmp_path)


def _launch(*args: str) -> int:
    return main(["launch", *args, "--lockstep"])


@pytest.mark.parametrize("name", SHIPPED)
def test_every_shipped_launch_file_runs_in_lockstep(name: str, tmp_path: Path, capsys) -> None:
    recording = tmp_path / "run.mcap"
    record = [f"recording:={recording}"] if name != "demo" else []
    assert _launch(name, f"duration_s:={SHORT_S}", "check:=false", *record) == 0
    out = capsys.readouterr().out
    assert "[lockstep] 0.15 s simulated" in out or "[lockstep] duration 0.15 s reached" in out, out[-2000:]
    if name == "demo":
        return
    frames = list(read_recording(recording))
    # every F/T stream (the gripper's: one per finger, finger0/ft/wrench, finger1/ft/wrench)
    streams = {f.topic for f in frames if f.topic.split("/")[-2:] == ["ft", "wrench"]}
    assert streams, sorted({f.topic for f in frames})
    for topic in streams:
        wrenches = [decode(f.payload) for f in frames if f.topic == topic]
        # the driver decoded the rig's device bytes: the stream is up and the samples carry the pad's load
        assert sum(w.status == "ok" for w in wrenches) > 20, (topic, [w.status for w in wrenches[:5]])
    assert any(f.topic == "rig/truth" for f in frames)
    assert "[monitor] ==== slipstack run summary ====" in out


def test_a_lockstep_launch_keeps_its_lines_in_the_log_file(tmp_path: Path, capsys) -> None:
    """--log-file as the real-time launch honours it (lock-step wrote no log at all)."""
    log = tmp_path / "lockstep.log"
    assert main(["launch", "demo", f"duration_s:={SHORT_S}", "--lockstep", "--log-file", str(log)]) == 0
    shown = [line for line in capsys.readouterr().out.splitlines() if line.startswith("[lockstep]")]
    kept = log.read_text()
    assert shown and all(line in kept for line in shown), (shown, kept[-2000:])


def test_bag_info_gives_a_lockstep_recording_s_times_on_the_simulated_clock(tmp_path: Path, capsys) -> None:
    """Log times of a lock-step run are simulated ns from its start (docs/modules.md, launch/lockstep.py):
    bag info showed them as dates in 1970."""
    recording = tmp_path / "run.mcap"
    # check:=false: a 0.15 s cut is no run to judge (fig15 with its check: tests/e2e/test_stack.py)
    assert _launch("fig15", f"duration_s:={SHORT_S}", "check:=false", f"recording:={recording}") == 0
    capsys.readouterr()
    assert main(["bag", "info", str(recording)]) == 0
    out = capsys.readouterr().out
    assert "1970" not in out, out
    assert "start:      0.000 s, simulated clock" in out and "end:        0.149 s, simulated clock" in out, out


@pytest.mark.parametrize("name", ["fig15", "fig10", "default"])
def test_a_launch_starts_by_holding_what_the_finger_holds(name: str, tmp_path: Path, capsys) -> None:
    # Issue 29: every launch began with 2 N commands (f_nom, from the first verdict's measured
    # force before the sensors were trusted) while the finger held 3-4 N; a real finger already
    # holding an object would have let it go. check:=false: a 0.3 s cut is no run to judge.
    recording = tmp_path / "start.mcap"
    assert _launch(name, "duration_s:=0.3", "check:=false", f"recording:={recording}") == 0
    finger, held = None, []
    for f in read_recording(recording, ["grip/state", "grip/command"]):
        msg = decode(f.payload)
        if f.topic == "grip/state":
            finger = msg
        elif not held or held[-1].reason == "fail-safe":
            held.append(msg)  # the commands until the first on valid data, and that one
    assert finger is not None and held, "no report from the finger or no command"
    first_report = next(decode(f.payload) for f in read_recording(recording, ["grip/state"]))
    assert first_report.mode == "initial"
    assert held[0].f_n_desired >= first_report.f_n_command, (held[0], first_report)
    assert all(c.f_n_desired == held[0].f_n_desired for c in held if c.reason == "fail-safe")  # held, not squeezed


def test_a_scene_with_a_pad_runs_on_the_f_t_sensor_alone(tmp_path: Path, capsys) -> None:
    # tactile:=false on fig15 (a scene with a pad): the rig serves no tactile device, so it
    # must not wait for a tactile driver that the launch does not start
    recording = tmp_path / "ft_only.mcap"
    assert _launch("fig15", "tactile:=false", "duration_s:=0.3", "check:=false", f"recording:={recording}") == 0
    topics = [f.topic for f in read_recording(recording)]
    assert topics.count("ft/wrench") > 100 and topics.count("rig/truth") > 50, sorted(set(topics))
    assert "tactile/frame" not in topics


def test_fig15_lockstep_writes_the_same_recording_twice(tmp_path: Path, capsys) -> None:
    runs = []
    for k in range(2):
        path = tmp_path / f"fig15-{k}.mcap"
        assert _launch("fig15", "duration_s:=0.4", f"recording:={path}", "check:=false") == 0
        runs.append([(f.topic, f.log_time_ns, f.payload) for f in read_recording(path)])
    topics = {topic for topic, _, _ in runs[0]}
    assert {"ft/wrench", "tactile/frame", "slip", "grip/command", "rig/truth"} <= topics
    assert len(runs[0]) > 500
    assert runs[0] == runs[1]


def test_the_gripper_lockstep_writes_the_same_recording_twice(tmp_path: Path, capsys) -> None:
    """Both fingers' streams, the grasp node, the gripper driver over TCP to the emulated WSG 50:
    a pivot (goal at 0.1 s) in lock-step repeats byte for byte."""
    runs = []
    for k in range(2):
        path = tmp_path / f"gripper-{k}.mcap"
        assert _launch("gripper", "scene:=grasp_pivot", "goal:=pivot", "goal_at_s:=0.1", "duration_s:=0.5",
                       f"recording:={path}", "check:=false") == 0
        runs.append([(f.topic, f.log_time_ns, f.payload) for f in read_recording(path)])
    topics = {topic for topic, _, _ in runs[0]}
    assert {"finger0/ft/wrench", "finger1/ft/wrench", "finger0/slip", "finger1/slip", "grip/command",
            "grasp/state", "gripper/state", "rig/grasp"} <= topics, sorted(topics)
    states = [decode(p) for topic, _, p in runs[0] if topic == "grasp/state"]
    assert any(s.mode == "pivot" for s in states)  # the goal reached the grasp node within the run
    assert runs[0] == runs[1]


def test_a_launch_on_real_devices_is_refused_with_what_to_do(tmp_path: Path, capsys) -> None:
    assert _launch("hardware", "recording:=x.mcap") != 0
    err = capsys.readouterr().err
    assert "--lockstep runs simulated devices only" in err and "node ft_driver reads the device 'rdt://" in err
    assert "sim: before the URL" in err and "launch without --lockstep" in err
    assert not Path("x.mcap").exists()
    assert not any((tmp_path / "runs").glob("*/*.json"))  # no run directory left behind


def test_a_lockstep_launch_needs_an_end(capsys) -> None:
    """Simulated devices but no rig to finish the run and no duration: refused, saying how to end it."""
    assert _launch("hardware", "ft_url:=sim:rdt://127.0.0.1:49152", "tactile:=false", "record:=false") != 0
    assert "a lock-step run needs an end" in capsys.readouterr().err


def test_a_graph_over_two_machines_runs_in_lockstep_as_on_one(tmp_path: Path, capsys) -> None:
    """two_hosts.toml places fig15's nodes on two machines; in lock-step every machine's nodes
    run in this one process, and placement changes nothing: the same recording as fig15's."""
    runs = []
    for name in ("fig15", "two_hosts"):
        path = tmp_path / f"{name}.mcap"
        assert _launch(name, "duration_s:=0.3", f"recording:={path}", "check:=false") == 0
        runs.append([(f.topic, f.log_time_ns, f.payload) for f in read_recording(path)])
    assert {"ft/wrench", "slip", "grip/command"} <= {topic for topic, _, _ in runs[0]}
    assert runs[0] == runs[1]


def test_lockstep_refuses_a_machine_with_what_to_do(tmp_path: Path, capsys) -> None:
    assert _launch("two_hosts", "--machine", "robot", "recording:=x.mcap") != 0
    err = capsys.readouterr().err
    assert "--lockstep runs every machine's nodes in this one process; drop --machine" in err
    assert not Path("x.mcap").exists()
    assert not any((tmp_path / "runs").glob("*/*.json"))  # no run directory left behind


def test_a_lockstep_recording_that_exists_is_refused_and_kept(tmp_path: Path, capsys) -> None:
    existing = tmp_path / "take1.mcap"
    existing.write_bytes(b"precious")
    assert _launch("fig15", f"recording:={existing}") != 0
    assert "take1.mcap exists; pass recording:=NEW.mcap" in capsys.readouterr().err
    assert existing.read_bytes() == b"precious"


def test_a_lockstep_recording_it_cannot_write_is_refused_before_the_run(tmp_path: Path, capsys) -> None:
    """The recording is written by a child process; a path it could not write fails at once, saying
    what to do, rather than after the whole scene has run."""
    (tmp_path / "a_file").write_text("not a folder")
    # --log-file elsewhere: the log beside that recording is refused first, in the same words
    # as the real-time launch's (tests/e2e/test_operator_cli.py)
    assert _launch("fig15", f"recording:={tmp_path / 'a_file' / 'run.mcap'}", "--log-file", str(tmp_path / "run.log")) != 0
    out, err = capsys.readouterr()
    assert "cannot write the recording" in err and "in a folder you may write" in err
    assert "simulated in" not in out  # refused before the run


def _writer_children() -> list[int]:
    """This process's children that are recording writers (from /proc)."""
    found = []
    for entry in Path("/proc").iterdir():
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes()
        except (OSError, ValueError):
            continue
        if int(stat.rsplit(")", 1)[1].split()[1]) == os.getpid() and b"writer_process" in cmdline:
            found.append(int(entry.name))
    return found


def test_a_run_interrupted_while_it_is_built_finishes_its_recording_and_its_writer(tmp_path: Path, monkeypatch) -> None:
    """Ctrl-C after the recording's writer started but before the run exists (here: while the
    executor is built) leaves a finished, empty recording and no writer process behind."""
    from slipstack.launch import lockstep
    from slipstack.launch.launch_file import SIM_ARG, load_launch_file
    from slipstack.nodes.devices.sim_link import SIM_PREFIX

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    path = tmp_path / "take.mcap"
    launch = load_launch_file("fig15", {"recording": str(path)}, builtins={"run_dir": str(tmp_path), SIM_ARG: SIM_PREFIX})
    monkeypatch.setattr(lockstep, "InProcessExecutor", interrupted)
    with pytest.raises(KeyboardInterrupt):
        lockstep.LockstepRun(launch, tmp_path, echo=lambda line: None)
    assert list(read_recording(path, tolerant=False)) == []  # finished: summary and footer written
    assert _writer_children() == []


def test_a_run_root_too_deep_for_sockets_still_runs_in_lockstep(tmp_path: Path, monkeypatch, capsys) -> None:
    """Lock-step binds no socket, so the 107-character limit of an ipc path does not apply to it
    (a deep checkout, or pytest-xdist's longer temporary folders, was refused); a real-time
    launch from the same run root is still refused before anything starts, saying what to do."""
    deep = tmp_path / ("d" * 90)
    deep.mkdir(mode=0o700)
    monkeypatch.setenv("SLIPSTACK_RUN_ROOT", str(deep))
    # check:=false: a 0.15 s cut is no run to judge (fig15 with its check: tests/e2e/test_stack.py)
    assert _launch("fig15", f"duration_s:={SHORT_S}", "check:=false", f"recording:={tmp_path / 'deep.mcap'}") == 0
    assert "[lockstep]" in capsys.readouterr().out
    assert main(["launch", "fig15", "duration_s:=0.1"]) == 2  # refused before anything starts; the duration bounds it if not
    assert "Linux allows 107. Set SLIPSTACK_RUN_ROOT to a shorter directory" in capsys.readouterr().err


def test_the_report_of_a_gripper_pivot_draws_every_panel_with_the_oracle(tmp_path: Path, capsys) -> None:
    """``slipstack report`` on a two-finger recording (issue 25, item 5): the motion against its
    target, the squeeze against the oracle's least holding squeeze, each finger's γ, the load
    split; a readable PNG with ink in every panel's band."""
    from matplotlib.image import imread

    from slipstack.analysis.grasp_report import _oracle, load_grasp_series

    recording, figure = tmp_path / "pivot.mcap", tmp_path / "pivot.png"
    assert _launch("gripper", "scene:=grasp_pivot", "goal:=pivot", "goal_at_s:=0.2", "duration_s:=1.0",
                   f"recording:={recording}", "check:=false") == 0  # ends 0.8 s into a 1 s pivot
    capsys.readouterr()
    assert main(["report", str(recording), "-o", str(figure)]) == 0
    out = capsys.readouterr().out
    assert "panels: motion, squeeze, load factors, load split" in out and "no oracle" not in out, out
    t, least, why = _oracle(load_grasp_series(recording))
    assert why == "" and least.size > 10 and np.all(np.isfinite(least)) and np.all(least >= 0) and least.max() > 1.0
    image = imread(figure)
    assert image.shape[0] >= 1000 and image.shape[1] >= 1000, image.shape  # 10 x 10.4 in at 110 dpi
    ink = (image[..., :3] < 0.9).any(axis=-1)
    bands = np.array_split(ink[int(0.05 * ink.shape[0]):], 4)  # below the title: one band per panel
    assert all(band.mean() > 0.02 for band in bands), [round(float(b.mean()), 4) for b in bands]
