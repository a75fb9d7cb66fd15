"""The operator's day with a real run: what a short simulated run and a hardware
launch without its device print, record and export (each test the exact commands a user types).

One short run of the default stack (3 s scene, every topic recorded) is shared by the tests
of this module.
"""

from __future__ import annotations

import base64
import json
import os
import re
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from progress_deadline import run

from slipstack.launch.launch_file import launch_files_dir
from slipstack.messages import TactileFrame, decode
from slipstack.nodes.recording.bag_io import read_recording

pytestmark = pytest.mark.e2e

PY = sys.executable


def slipstack(*args: str, env: dict | None = None, timeout: float = 120.0) -> subprocess.CompletedProcess:
    """``slipstack ARGS``, given ``timeout`` s of the time its processes could run (not wall time)."""
    return run([PY, "-m", "slipstack.launch.cli", *args], timeout, env=env or dict(os.environ))


LOG_LEVELS = "warning,monitor=info"  # docs/operating.md's example: the recorder's and the rig's info lines not shown


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    """``slipstack launch scene:=SHORT recording:=R record_topics:= summary:=S check:=false
    --log-level warning,monitor=info`` on the default scene cut to 3 s: (folder,
    its output, the recording)."""
    folder = tmp_path_factory.mktemp("run")
    text = (launch_files_dir().parent / "scenes" / "default.toml").read_text()
    scene = folder / "short.toml"
    scene.write_text(re.sub(r"(?m)^duration_s = .*$", "duration_s = 3.0", text, count=1))
    recording = folder / "r.mcap"
    env = dict(os.environ, SLIPSTACK_RUN_ROOT=str(folder / "root"), PYTHONUNBUFFERED="1")
    out = slipstack("launch", f"scene:={scene}", f"recording:={recording}", "record_topics:=",
                    f"summary:={folder / 'summary.json'}", "check:=false", "--log-level", LOG_LEVELS, env=env)
    assert out.returncode == 0, out.stdout + out.stderr
    return folder, out.stdout + out.stderr, recording


# -- Foxglove opens the export: tight schemas, one clock, the pad as an image -------------------
def test_exported_recording_meets_its_own_schemas_and_shows_the_pad(short_run):
    jsonschema = pytest.importorskip("jsonschema")
    folder, _, recording = short_run
    exported = folder / "foxglove.mcap"
    out = slipstack("bag", "export", str(recording), "-o", str(exported))
    assert out.returncode == 0, out.stderr

    counts, violations, first_violation = Counter(), Counter(), {}
    publish_minus_log, images, scenes = [], [], []
    with open(exported, "rb") as fh:
        reader = make_reader(fh)
        metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
        validators = {}
        for schema, channel, msg in reader.iter_messages():
            if schema.id not in validators:
                doc = json.loads(schema.data)
                jsonschema.Draft202012Validator.check_schema(doc)
                validators[schema.id] = (doc, jsonschema.Draft202012Validator(doc))
            doc, validator = validators[schema.id]
            body = json.loads(msg.data)
            counts[schema.name] += 1
            for error in validator.iter_errors(body):
                violations[schema.name] += 1
                first_violation.setdefault(schema.name, f"{list(error.path)}: {error.message[:200]}")
            if schema.name.startswith("slipstack/"):
                assert channel.topic.startswith("/slipstack/"), channel.topic  # as live: one layout fits both
                # tight: every declared field is required, nothing else is allowed
                assert set(doc["required"]) == set(doc["properties"]) == set(body), schema.name
                assert doc["additionalProperties"] is False
                stamp = body["header"]["stamp"]
                assert abs(stamp["sec"] * 10**9 + stamp["nsec"] - msg.log_time) < 60 * 10**9  # wall clock
            publish_minus_log.append(msg.publish_time - msg.log_time)
            if schema.name == "foxglove.RawImage":
                images.append((channel.topic, body))
            if schema.name == "foxglove.SceneUpdate":
                scenes.append((channel.topic, body))
    assert not violations, first_violation
    assert {"slipstack/TactileFrame", "slipstack/Slip", "slipstack/Diagnostics", "slipstack/RigTruth",
            "slipstack/Wrench", "slipstack/GripCommand"} <= set(counts), counts
    # one clock: publish times on the wall clock like the log times (within a minute, not 50 years)
    assert max(abs(d) for d in publish_minus_log) < 60 * 10**9
    # the recorded clock offset is kept
    original = {m.name: dict(m.metadata) for m in make_reader(open(recording, "rb")).iter_metadata()}
    assert metadata["slipstack.clock"] == original["slipstack.clock"]

    # the pad as an image: as many as tactile frames, each decoding to the frame's pressures
    assert len(images) == counts["slipstack/TactileFrame"] > 0
    frames = [decode(f.payload) for f in read_recording(recording, ["tactile/frame"])]
    topic, image = images[-1]
    assert topic == "/pad/pressure" and image["encoding"] == "32FC1" and image["frame_id"] == "pad"
    pixels = np.frombuffer(base64.b64decode(image["data"]), dtype="<f4").reshape(image["height"], image["width"])
    last: TactileFrame = frames[-1]
    np.testing.assert_array_equal(pixels, last.pressure_pa.reshape(last.rows, last.cols))
    assert pixels.max() > 0  # the pad is pressed

    # the contact in 3-D: the force arrow of the last pad-frame wrench, in the pad frame
    wrenches = [w for w in (decode(f.payload) for f in read_recording(recording, ["ft/wrench"])) if w.frame == "pad"]
    assert wrenches and scenes and all(topic == "/pad/scene" for topic, _ in scenes)
    (entity,) = scenes[-1][1]["entities"]
    (arrow,) = entity["arrows"]
    assert entity["frame_id"] == "pad"
    assert arrow["shaft_length"] + arrow["head_length"] == pytest.approx(0.01 * np.linalg.norm(wrenches[-1].force))


def test_exported_schemas_refuse_what_decoding_refuses(short_run):
    jsonschema = pytest.importorskip("jsonschema")
    folder, _, recording = short_run
    exported = folder / "schemas.mcap"
    assert slipstack("bag", "export", str(recording), "-o", str(exported)).returncode == 0
    with open(exported, "rb") as fh:
        found = {}
        for schema, _, msg in make_reader(fh).iter_messages():
            found.setdefault(schema.name, (json.loads(schema.data), json.loads(msg.data)))
    grip_schema, grip = found["slipstack/GripCommand"]
    slip_schema, slip = found["slipstack/Slip"]
    bad = [(grip_schema, {**grip, "f_n_desired": -5.0}), (grip_schema, {**grip, "f_n_desired": "12"}),
           (grip_schema, {k: v for k, v in grip.items() if k != "law"}), (grip_schema, {**grip, "extra": 1}),
           (slip_schema, {**slip, "state": "bogus"}), (slip_schema, {**slip, "verdicts": {"exact": [1.0]}}),
           (slip_schema, {**slip, "f_t": [0.0]})]
    for schema, body in bad:
        assert list(jsonschema.Draft202012Validator(schema).iter_errors(body)), body
    assert "unit: N" in grip_schema["properties"]["f_n_desired"]["description"]


# -- counts with denominators; no truth lines without a rig ---------------------------
def test_the_simulated_run_summary_gives_counts_with_their_denominators(short_run):
    """The terminal shows the short form (at most 12 lines of 100 characters); the run's log
    file keeps the long form, every count with its denominator."""
    _, output, recording = short_run
    shown = output[output.index("[monitor] ==== slipstack run summary ===="):].split("\n[launch]")[0].splitlines()
    assert len(shown) <= 12 and max(map(len, shown)) <= 100, shown
    assert any(re.match(r"\[monitor\] control: \d+ commands; fail-safe [\d.]+% \(\d+ of \d+\)", ln) for ln in shown)
    assert "detail:" not in output
    log = recording.with_suffix(".log").read_text()
    summary = "\n".join(ln.split("[monitor] detail: ", 1)[1] for ln in log.splitlines() if "[monitor] detail: " in ln)
    assert re.search(r"slip episodes: \d+ detected of \d+ true", summary), summary
    assert re.search(r"slip flag without true slip: [\d.]+% of \d+ sticking frames", summary), summary
    assert re.search(r"fail-safe while running [\d.-]+%? \(\d+ of \d+\)", summary), summary
    assert not re.search(r"-\d+ of -\d+", summary), summary  # no negative counts
    for line in summary.splitlines():
        if "frames lost at" in line:  # on a loaded machine: each count with what it is out of
            assert re.search(r"\d+ of \d+ \(", line), line
            assert "=" not in line, line  # no bare counter names (in.ft/wrench.lost=497)


def test_hardware_without_its_device_shows_disconnected_live_and_no_truth_in_the_summary(launch):
    """``slipstack launch hardware.toml ft_url:=robotiq:///dev/ttyNOPE tactile:=false record:=false``,
    then Ctrl-C: the live line names the disconnected driver; the summary prints no episode
    counts or flags without true slip (there is no rig/truth) and says why the grip was held."""
    import signal
    import time

    g = launch("hardware.toml", "ft_url:=robotiq:///dev/ttyNOPE", "tactile:=false", "record:=false")
    g.wait_ready()
    deadline = time.monotonic() + 60
    while "DISCONNECTED ft_driver" not in g.log() and time.monotonic() < deadline:
        time.sleep(0.2)
    g.stop(signal.SIGINT, timeout=60)
    log = g.log_path.read_text(errors="replace")
    status = [ln for ln in log.splitlines() if ln.startswith("[monitor] STATUS")]
    assert any("DISCONNECTED ft_driver" in ln for ln in status), "\n".join(status[-5:])
    summary = log[log.index("==== slipstack run summary ===="):]
    assert "no ground truth (real hardware)" in summary, summary
    assert "detected" not in summary and "sticking frames" not in summary, summary
    assert "HEALTH: ft_driver disconnected: robotiq:///dev/ttyNOPE" in summary, summary
    # no trusted data and no finger report: no command at all, the finger keeps its grip (issue 29,
    # item 10: the launch used to command 2 N and then ramp to f_max blind)
    assert "HEALTH: no command: no trusted sensor data, the finger kept its grip" in summary, summary


# -- a normal end is quiet; levels, and the log kept beside the recording -------
def test_a_normal_end_is_quiet_and_its_log_outlives_the_run_directory(short_run):
    folder, output, recording = short_run
    lines = output.splitlines()
    device_errors = [ln for ln in lines if re.match(r"\[(ft|tactile)_driver\] error:", ln)]
    assert not device_errors, device_errors  # the rig closed them at the end of its scene
    log_file = recording.with_suffix(".log")
    log = log_file.read_text()
    held = [ln for ln in log.splitlines() if ln.endswith("(not shown)")]
    closing = [ln for ln in lines if "devices closed as the simulated world stopped" in ln]
    if held:  # said in one line, and kept in full in the log file
        assert len(closing) == 1 and f"{len(held)} retry line(s)" in closing[0], closing
        assert all(re.search(r"\[(ft|tactile)_driver\] error: ", ln) for ln in held), held
    # the log file has what the terminal had, with times; the run directory is gone
    assert "==== slipstack run summary ====" in log and "[launch]" in log
    assert re.match(r"\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3} \[", log)
    assert not any((folder / "root").glob("run-*/graph.json"))
    # levels: monitor at info, the others at warning (the rig too: its end of scene is
    # seen by the launcher, which keeps the drivers' aftermath quiet, but not shown)
    assert any(ln.startswith("[monitor] STATUS") for ln in lines)
    assert "[rig] scene default finished" not in lines, output[-3000:]
    assert not any(ln.startswith("[recorder] wrote") for ln in lines), output[-3000:]


def test_an_unknown_log_level_is_refused_with_the_levels():
    out = slipstack("launch", "demo", "--log-level", "loud")
    assert out.returncode == 2, out
    assert "unknown level 'loud'" in out.stderr and "debug, info, warning, error" in out.stderr, out.stderr
