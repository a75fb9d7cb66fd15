"""The operator's day: the exact commands a new user types, as subprocesses.

Each test is one thing a new user does: the command, its exit code and the words it prints.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.e2e

PY = sys.executable


def slipstack(*args: str, timeout: float = 60.0, env: dict | None = None) -> subprocess.CompletedProcess:
    """``slipstack ARGS`` as a subprocess (never hangs the suite: a hard timeout)."""
    return subprocess.run([PY, "-m", "slipstack.launch.cli", *args], capture_output=True, text=True,
                          timeout=timeout, env=env or dict(os.environ))


# -- slipstack run NODE ----------------------------------------------------------------
def test_run_without_pub_and_without_a_graph_publishes_on_a_default_endpoint(tmp_path):
    """``slipstack run wrench_source`` with no graph running: it refused to start without --pub;
    it publishes on an endpoint in the run root and says which, for a consumer's --sub."""
    import signal

    import zmq

    root = tmp_path / "root"
    root.mkdir(mode=0o700)
    env = dict(os.environ, SLIPSTACK_RUN_ROOT=str(root))
    proc = subprocess.Popen([PY, "-m", "slipstack.launch.cli", "run", "wrench_source"], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        said = proc.stderr.readline()
        assert said.startswith(f"wrench_source-{proc.pid}: no running graph; publishing ft/wrench, diagnostics on "
                               f"ipc://{root}/wrench_source-{proc.pid}.pub"), said
        sub = zmq.Context.instance().socket(zmq.SUB)
        sub.connect(f"ipc://{root}/wrench_source-{proc.pid}.pub")
        sub.setsockopt(zmq.SUBSCRIBE, b"ft/wrench")
        assert sub.poll(30_000), "no ft/wrench on the default endpoint"
        assert sub.recv_multipart()[0] == b"ft/wrench"
        sub.close(linger=0)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(30) == 0, proc.stderr.read()
    finally:
        proc.kill()
        proc.wait()


def test_run_without_pub_attaches_to_the_running_graph(launch):
    """``slipstack run relay --name relay2`` beside the demo graph: it subscribes to the graph's
    ft/wrench and its ft/relayed is seen by the graph's tools; its registration goes when it stops."""
    import signal

    g = launch("demo")
    graph = g.wait_ready()
    proc = subprocess.Popen([PY, "-m", "slipstack.launch.cli", "run", "relay", "--name", "relay2"], env=g.env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        said = proc.stderr.readline()
        assert said.startswith(f"relay2: the graph in {graph['run_dir']}; publishing ft/relayed, diagnostics on "), said
        assert said.rstrip().endswith("; inputs from ft/wrench"), said
        info = g.cli("topic", "info", "ft/relayed", "-v").stdout
        assert "Publisher count: 2" in info and "Node name: relay2" in info, info
        out = g.cli("topic", "echo", "diagnostics", "--once", "--field", "counters.in.ft/wrench.received",
                    "--filter", "m.node == 'relay2'", "--timeout", "30")
        assert out.returncode == 0 and float(out.stdout.split()[0]) > 0, out  # it receives the graph's samples
        proc.send_signal(signal.SIGINT)
        assert proc.wait(30) == 0, proc.stderr.read()
    finally:
        proc.kill()
        proc.wait()
    assert "relay2" not in g.cli("node", "list").stdout


def test_run_driver_without_url_names_the_missing_parameter():
    out = slipstack("run", "ft_driver")
    assert out.returncode == 2, out
    assert len(out.stderr.splitlines()) == 1, out.stderr
    assert "missing parameter url" in out.stderr and "url:=" in out.stderr
    assert "__init__" not in out.stderr and "positional argument" not in out.stderr


# -- bag and report error paths ----------------------------------------------------------
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
    from slipstack.nodes.recording.bag_io import RecordingWriter

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


# -- discoverability ------------------------------------------------------------------------
def test_show_args_prints_each_arguments_comment():
    out = slipstack("launch", "hardware", "--show-args")
    assert out.returncode == 0, out.stderr
    lines = {ln.split(" := ")[0]: ln for ln in out.stdout.splitlines()}
    assert lines["sensor_offset_m"].endswith("# F/T sensor origin in the pad frame (m)")
    assert "# or robotiq:///dev/ttyUSB0" in lines["ft_url"]  # a '#' after a value holding '?' and '='
    assert "#" not in lines["pad_rows"]  # no comment, none invented


def test_launch_of_an_unknown_file_lists_the_shipped_ones():
    out = slipstack("launch", "nosuch")
    assert out.returncode == 2, out
    assert "Shipped launch files:" in out.stderr and "fig15" in out.stderr and "hardware" in out.stderr


@pytest.mark.parametrize("args", [["controller=false"], ["demo", "controller=false"]])
def test_one_equals_sign_hints_the_launch_argument_form(args):
    out = slipstack("launch", *args)
    assert out.returncode == 2, out
    assert "controller:=false" in out.stderr


def test_every_bag_verb_has_help_text():
    out = slipstack("bag", "--help")
    for verb in ("record", "play", "info", "export"):
        line = next(ln for ln in out.stdout.splitlines() if ln.strip().startswith(verb))
        assert len(line.split()) > 1, line


def test_run_help_describes_every_node_in_plain_whole_sentences():
    """``slipstack run --help``: one line per node type, its docstring's first paragraph
    without reStructuredText (was: ``slip``, :class:`~slipstack…` and a recorder line cut mid-sentence)."""
    from slipstack.nodes.catalog import NODE_TYPES

    out = slipstack("run", "--help")
    assert out.returncode == 0, out.stderr
    described = {ln.split(":", 1)[0].strip(): ln.split(":", 1)[1].strip()
                 for ln in out.stdout.split("node types and their parameters:")[1].splitlines()
                 if ln.startswith("  ") and not ln.startswith("      ")}
    assert set(described) == set(NODE_TYPES)
    for node, text in described.items():
        assert "``" not in text and ":class:" not in text and text.endswith("."), (node, text)
    assert described["recorder"].endswith("the one slipstack bag record attaches to).")


def test_run_node_help_shows_that_nodes_parameters_only():
    """``slipstack run rig --help`` as a ROS user types it: the rig's parameters, not all 14 nodes'."""
    out = slipstack("run", "rig", "--help")
    assert out.returncode == 0, out.stderr
    described = [ln.split(":", 1)[0].strip() for ln in out.stdout.split("node types and their parameters:")[1]
                 .splitlines() if ln.startswith("  ") and not ln.startswith("      ")]
    assert described == ["rig"] and "watchdog_grip_n (float" in out.stdout, out.stdout


def test_run_dir_help_names_both_variables_like_the_docs():
    readme = (Path(__file__).parents[2] / "docs" / "operating.md").read_text()
    for args in (["topic", "list", "--help"], ["bag", "record", "--help"]):
        text = " ".join(slipstack(*args).stdout.split())
        assert "$SLIPSTACK_RUN_DIR" in text and "$SLIPSTACK_RUN_ROOT/current" in text, text
    assert "$SLIPSTACK_RUN_DIR" in readme and "$SLIPSTACK_RUN_ROOT/current" in readme


@pytest.mark.parametrize("args", [["--help"], ["topic", "list"], ["launch", "--help"]])
def test_help_and_topic_list_start_without_the_numeric_stack(args, tmp_path):
    """Start-up cost is what is imported (a load-independent check): no numpy, scipy, numba
    or node types for ``--help``, ``topic list`` and ``launch --help`` (measured: ~0.06-0.1 s,
    from 1.5 s; ``launch --help`` imported the whole launcher, 0.64 s of CPU)."""
    probe = ("import sys, runpy\n"
             f"sys.argv = ['slipstack', *{args!r}]\n"
             "try:\n    runpy.run_module('slipstack.launch.cli', run_name='__main__')\n"
             "except SystemExit:\n    pass\n"
             "heavy = sorted(m for m in ('numpy', 'scipy', 'numba', 'zmq', 'slipstack.nodes.runtime.node') if m in sys.modules)\n"
             "print('HEAVY', heavy, file=sys.stderr)\n")
    env = dict(os.environ, SLIPSTACK_RUN_ROOT=str(tmp_path))  # topic list: no graph here, a one-line error
    out = subprocess.run([PY, "-c", probe], capture_output=True, text=True, timeout=60, env=env)
    assert "HEAVY []" in out.stderr, out.stderr


# -- a wrong device path, as a user types it -------------------------------------------------------------------
def test_hardware_launch_with_a_wrong_device_path_says_so(launch):
    """``slipstack launch hardware.toml ft_url:=robotiq:///dev/ttyNOPE tactile:=false record:=false``:
    an error line from ft_driver on the terminal and ``disconnected`` with the error on diagnostics."""
    g = launch("hardware.toml", "ft_url:=robotiq:///dev/ttyNOPE", "tactile:=false", "record:=false")
    g.wait_ready()
    out = g.cli("topic", "echo", "diagnostics", "--once", "--timeout", "20", "--filter", "m.node == 'ft_driver'")
    assert out.returncode == 0, out.stderr
    assert "status: \"disconnected: robotiq:///dev/ttyNOPE" in out.stdout, out.stdout
    assert "No such file or directory" in out.stdout
    errors = [ln for ln in g.log().splitlines() if ln.startswith("[ft_driver] error:") and "ttyNOPE" in ln]
    assert len(errors) == 1, g.log()


# -- shell completion -----------------------------------------------------------------------
def _completions(line: str, tmp_path: Path) -> list[str]:
    """What the shell gets for ``line<TAB>`` (argcomplete's protocol, answers in a file)."""
    answers = tmp_path / "completions"
    env = dict(os.environ, _ARGCOMPLETE="1", COMP_LINE=line, COMP_POINT=str(len(line)),
               _ARGCOMPLETE_STDOUT_FILENAME=str(answers), SLIPSTACK_RUN_ROOT=str(tmp_path))
    out = slipstack(env=env)
    assert out.returncode == 0, out.stderr
    return [w.strip() for w in answers.read_text().split("\x0b")]


def test_the_shell_completes_commands_verbs_and_launch_files(tmp_path):
    assert "export" in _completions("slipstack bag ex", tmp_path)
    assert {"topic", "completion"} <= set(_completions("slipstack ", tmp_path))
    assert {"bw", "hz", "delay", "echo"} <= set(_completions("slipstack topic ", tmp_path))
    assert {"fig15", "fig10", "fig11"} <= set(_completions("slipstack launch fig1", tmp_path))
    script = slipstack("completion", "bash")
    assert script.returncode == 0 and "complete" in script.stdout and "slipstack" in script.stdout, script


def test_the_shell_completes_launch_arguments_and_their_values_without_the_numeric_stack(tmp_path):
    """``slipstack launch law:=<TAB>`` offered nothing (and took 6.3 s at load 10, importing the
    node stack): it offers the file's arguments, then their values."""
    assert "law:=" in _completions("slipstack launch la", tmp_path)
    assert {"law:=exact", "law:=linear", "law:=tactile14"} <= set(_completions("slipstack launch law:=", tmp_path))
    assert _completions("slipstack launch fig15 controller:=", tmp_path) == ["controller:=true", "controller:=false"]
    assert "scene:=fig15" in _completions("slipstack launch scene:=fig1", tmp_path)
    line = "slipstack launch method:=tactile_cor_"
    env = dict(os.environ, _ARGCOMPLETE="1", COMP_LINE=line, COMP_POINT=str(len(line)), PYTHONPROFILEIMPORTTIME="1",
               _ARGCOMPLETE_STDOUT_FILENAME=str(tmp_path / "answers"), SLIPSTACK_RUN_ROOT=str(tmp_path))
    out = slipstack(env=env)
    imported = {ln.split("|")[-1].strip() for ln in out.stderr.splitlines() if ln.startswith("import time:")}
    assert imported and not imported & {"numpy", "zmq", "numba", "slipstack.nodes.runtime.node"}, sorted(imported)
    assert (tmp_path / "answers").read_text().split("\x0b") == ["method:=tactile_cor_robust", "method:=tactile_cor_known"]


# -- progress on large files --------------------------------------------------------------
@pytest.fixture
def large_recording(tmp_path):
    """A 5 MB recording: tactile frames of random pressures (zstd cannot shrink them)."""
    import numpy as np

    from slipstack.lib.progress import PROGRESS_MIN_BYTES
    from slipstack.messages import Header, TactileFrame, encode
    from slipstack.nodes.recording.bag_io import RecordingWriter

    rng = np.random.default_rng(1)
    path = tmp_path / "large.mcap"
    with RecordingWriter(path, wall_minus_monotonic_ns=0) as w:
        for k in range(5000):
            frame = TactileFrame(pressure_pa=rng.random(256, dtype=np.float32), saturated=np.zeros(256, bool),
                                 dead=np.zeros(256, bool), header=Header(k * 4_000_000, k, k * 4_000_000, {}))
            w.write("tactile/frame", encode(frame), 10**18 + k * 4_000_000)
    assert path.stat().st_size > PROGRESS_MIN_BYTES
    return path


def _on_a_terminal(*args: str) -> tuple[subprocess.CompletedProcess, str]:
    """``slipstack ARGS`` with stderr on a pseudo-terminal (as a user at a shell sees it)."""
    import fcntl
    import pty
    import struct
    import termios

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # a 100-column terminal
    try:
        proc = subprocess.run([PY, "-m", "slipstack.launch.cli", *args], stdout=subprocess.PIPE, stderr=slave,
                              text=True, timeout=120)
        os.close(slave)
        chunks = []
        while True:
            try:
                chunk = os.read(master, 65536)
            except OSError:  # the terminal's other end is closed: all read
                break
            if not chunk:
                break
            chunks.append(chunk)
    finally:
        os.close(master)
    return proc, b"".join(chunks).decode(errors="replace")


@pytest.mark.parametrize("verb", ["info", "export"])
def test_bag_info_and_export_of_a_large_file_show_progress_on_a_terminal(verb, large_recording, tmp_path):
    extra = ["-o", str(tmp_path / "out.mcap")] if verb == "export" else []
    proc, terminal = _on_a_terminal("bag", verb, str(large_recording), *extra)
    assert proc.returncode == 0, terminal
    assert f"bag {verb}:" in terminal and "%" in terminal, terminal  # the bar, with its label
    assert "5000" in proc.stdout, proc.stdout  # the result, unchanged, on stdout
    extra = ["-o", str(tmp_path / "quiet.mcap")] if verb == "export" else []  # an export never overwrites
    quiet = slipstack("bag", verb, str(large_recording), *extra)  # not a terminal: no bar
    assert quiet.returncode == 0 and "%|" not in quiet.stderr, quiet.stderr


# -- the check judges the control path, not the recorder --------------------------------------
def _short_scene(folder: Path, seconds: float) -> Path:
    """The default scene cut to ``seconds``."""
    from slipstack.launch.launch_file import launch_files_dir

    text = (launch_files_dir().parent / "scenes" / "default.toml").read_text()
    scene = folder / "short.toml"
    scene.write_text(re.sub(r"(?m)^duration_s = .*$", f"duration_s = {seconds}", text, count=1))
    return scene


def test_a_dead_recorder_is_reported_and_does_not_fail_the_check(launch, tmp_path):
    """The default launch (check on) with its recorder killed 1 s into a 6 s scene: the
    launch says so and the summary names it, and the check judges only the control path
    (it used to end with "CHECK FAILED: recorder died and was not restarted")."""
    import signal
    import time

    g = launch(f"scene:={_short_scene(tmp_path, 6.0)}", f"recording:={tmp_path / 'r.mcap'}")
    graph = g.wait_ready()
    time.sleep(1.0)
    os.kill(graph["nodes"]["recorder"]["pid"], signal.SIGKILL)
    code = g.proc.wait(timeout=120)
    out = g.log()
    assert "[launch] recorder died and was not restarted (respawn = false): it only observes" in out, out[-3000:]
    assert "HEALTH: recorder silent for the last" in out and "(observer)" in out, out[-3000:]
    failed = [ln for ln in out.splitlines() if "CHECK FAILED" in ln]
    assert not any("recorder" in ln for ln in failed), failed
    assert code == (1 if failed else 0), (code, failed)  # a busy machine may fail it on the control path
    closing = out.rstrip().splitlines()[-1]  # the verdict, in short words, and where the long form is
    assert closing.endswith(f"(details: {tmp_path / 'r.log'})") and len(closing) < 200, closing


# -- outputs: a path that cannot be written, one that exists, a damaged input ------------------
@pytest.mark.parametrize("command", [["bag", "export", "{rec}", "-o", "{out}.mcap"], ["report", "{rec}", "-o", "{out}.png"],
                                     ["identify", "{rec}", "-o", "{out}.toml"],
                                     ["reproduce", "--quick", "--only", "fig4a", "--out", "{out}"]])
def test_an_output_that_cannot_be_written_is_one_clear_line(command, recording, tmp_path):
    """The output's folder is a file (a path nobody can write, root included): each command used
    to end in a traceback (FileNotFoundError, NotADirectoryError, PermissionError)."""
    blocker = tmp_path / "afile"
    blocker.write_text("")
    args = [a.format(rec=recording, out=blocker / "out") for a in command]
    out = slipstack(*args, timeout=120)
    assert out.returncode == 2, out
    assert "Traceback" not in out.stderr and len(out.stderr.strip().splitlines()) == 1, out.stderr
    assert f"{blocker} is a file, not a folder" in out.stderr and "you may write" in out.stderr, out.stderr


@pytest.mark.parametrize("command", [["bag", "export", "{rec}", "-o", "{out}"], ["identify", "{rec}", "-o", "{out}"]])
def test_export_and_identify_never_overwrite_unless_asked(command, recording, tmp_path):
    """Like ``bag record``: an existing output is refused (they used to overwrite it); ``--overwrite`` replaces it."""
    existing = tmp_path / ("old.jsonl" if command[0] == "bag" else "old.toml")
    existing.write_text("keep me\n")
    out = slipstack(*[a.format(rec=recording, out=existing) for a in command])
    assert out.returncode == 2, out
    assert f"{existing} exists" in out.stderr and "--overwrite" in out.stderr, out.stderr
    assert existing.read_text() == "keep me\n"
    if command[0] == "bag":
        forced = slipstack(*[a.format(rec=recording, out=existing) for a in command], "--overwrite")
        assert forced.returncode == 0, forced.stderr
        assert existing.read_text().count("\n") == 50  # the recording's 50 messages, one a line


def test_a_failed_identification_leaves_no_material_file(recording, tmp_path):
    out = slipstack("identify", str(recording), "-o", str(tmp_path / "mine.toml"))
    assert out.returncode == 2, out  # the recording has no friction ramp
    assert not (tmp_path / "mine.toml").exists()


def test_exporting_a_damaged_recording_says_so_and_exits_1(recording, tmp_path):
    """A recording cut short (as by kill -9): what can be read is exported, and the command
    says what was damaged and exits 1 (it used to exit 0 without a word)."""
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(recording.read_bytes()[: recording.stat().st_size - 200])
    out = slipstack("bag", "export", str(cut), "-o", str(tmp_path / "cut.jsonl"))
    assert out.returncode == 1, out
    assert f"{cut} is damaged (" in out.stderr and "`slipstack bag info`" in out.stderr, out.stderr
    written = int(out.stdout.split(": ")[1].split()[0])
    assert (tmp_path / "cut.jsonl").read_text().count("\n") == written


# -- node list while the graph starts -------------------------------------------------------------
def test_node_list_shows_the_nodes_already_up_while_the_graph_starts(launch):
    """The default graph starts its processes one after another (seconds, numba kernels
    loading) and the first already publish. ``node list`` used to show every node as
    ``pid None down`` until the last was ready."""
    import time

    g = launch()
    graph = g.run_root / "current" / "graph.json"
    listings = []
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and g.proc.poll() is None:
        if graph.exists():
            out = g.cli("node", "list", timeout=30)
            listings.append(out.stdout)
            if out.returncode == 0 and not out.stdout.startswith("graph starting"):
                break
        time.sleep(0.05)
    starting = [text for text in listings if text.startswith("graph starting")]
    assert starting, listings  # it was seen while starting
    assert any(re.search(r"monitor  \[monitor\] pid \d+ running", text) for text in starting), starting
    assert all("None" not in text and "down" not in text for text in starting), starting
    assert "not started yet" in starting[0], starting[0]


# -- a graph kept up for interactive use ----------------------------------------------------------
def test_duration_inf_keeps_the_graph_up_after_the_scene_until_ctrl_c(launch, tmp_path):
    """``slipstack launch duration_s:=inf``: the world holds its last load after the scene and the
    graph stays up (for topic echo, Foxglove ...) until Ctrl-C; it was refused ("must be finite"),
    and a longer finite duration_s still ended with the scene."""
    import signal
    import time

    # check:=false: its verdict (fail-safe share) depends on the machine's load, not on the duration;
    # the default check is judged in test_a_dead_recorder_is_reported_and_does_not_fail_the_check
    g = launch(f"scene:={_short_scene(tmp_path, 1.0)}", "duration_s:=inf", "record:=false", "check:=false")
    g.wait_ready()
    time.sleep(4.0)  # well past the 1 s scene
    assert g.proc.poll() is None, g.log()[-3000:]
    out = g.cli("topic", "echo", "rig/truth", "--once", "--field", "f_n_applied", "--timeout", "20")
    assert out.returncode == 0, out.stderr  # the rig still runs the world
    code = g.stop(signal.SIGINT, timeout=60)
    log = g.log_path.read_text()
    assert code == 0, log[-3000:]
    assert "[monitor] ==== slipstack run summary ====" in log


def test_lockstep_refuses_an_endless_duration():
    out = slipstack("launch", "--lockstep", "duration_s:=inf")
    assert out.returncode == 2, out
    assert "give a finite duration_s" in out.stderr


def test_version_says_the_installed_one():
    from importlib.metadata import version

    out = slipstack("--version")
    assert out.returncode == 0 and out.stdout == f"slipstack {version('slipstack')}\n", out


# -- a running node's parameters ------------------------------------------------------------------
def test_param_get_and_set_on_a_running_node(launch):
    """ros2's ``param get/set``: the value in effect, and a new one the node's process restarts
    with (the launcher writes it into the run spec); refused, with why, where it cannot be."""
    g = launch("demo")
    g.wait_ready()
    assert g.cli("param", "get", "source", "rate_hz").stdout == "1000.0\n"
    listing = g.cli("param", "list", "source").stdout
    assert "rate_hz = 1000.0  # publish rate (Hz)" in listing and "f_n = 10.0" in listing, listing
    out = g.cli("param", "set", "source", "rate_hz", "250")
    assert out.returncode == 0, out.stderr
    assert "source: rate_hz := 250; restarting node source (wrench_source)" in out.stdout, out.stdout
    assert "source is back: ok" in out.stdout, out.stdout
    assert g.cli("param", "get", "source", "rate_hz").stdout == "250.0\n"  # as the node reads it (was '250')
    assert g.graph()["nodes"]["source"]["restarts"] == 1
    wrong = g.cli("param", "set", "source", "rate_hz", "fast")
    assert wrong.returncode == 2 and "source.rate_hz: must be a number, got 'fast'" in wrong.stderr, wrong.stderr
    assert "param set: source rate_hz := '250'" in g.log() and "rate_hz := 'fast'" not in g.log()
    # a value of the right type that the node refuses: said at once, the running process untouched
    # (it restarted into a crash loop, then the launch abandoned it)
    refused = g.cli("param", "set", "source", "rate_hz", "0")
    assert refused.returncode == 2 and "source refuses rate_hz := 0" in refused.stderr, refused.stderr
    assert g.graph()["nodes"]["source"]["restarts"] == 1


def test_param_set_is_refused_for_a_process_that_may_not_restart(launch):
    g = launch("demo", "respawn:=false")
    g.wait_ready()
    out = g.cli("param", "set", "relay", "nosuch", "1")
    assert out.returncode == 2 and "unknown parameter(s) nosuch" in out.stderr, out.stderr
    out = g.cli("param", "set", "source", "rate_hz", "250")
    assert out.returncode == 2, out
    assert "its process may not be restarted (respawn = false in the launch file)" in out.stderr, out.stderr
    assert g.graph()["nodes"]["source"]["restarts"] == 0


def test_a_launch_that_failed_to_start_does_not_pass_its_check(launch, tmp_path):
    """The recorder cannot write its recording, so the graph never runs. The monitor saw nothing
    wrong in its empty run, and the launch used to end with "[launch] check passed"."""
    blocker = tmp_path / "afile"
    blocker.write_text("")
    g = launch(f"recording:={blocker / 'r.mcap'}", "--log-file", str(tmp_path / "run.log"))
    assert g.proc.wait(timeout=120) == 1, g.log()[-3000:]
    closing = g.log().rstrip().splitlines()[-1]
    assert closing.startswith("[launch] CHECK FAILED: the launch failed (node recorder (recorder) exited with code")


def test_a_run_log_that_cannot_be_written_is_one_clear_line(tmp_path):
    blocker = tmp_path / "afile"
    blocker.write_text("")
    out = slipstack("launch", f"recording:={blocker / 'r.mcap'}", env=dict(os.environ, SLIPSTACK_RUN_ROOT=str(tmp_path)))
    assert out.returncode == 2 and "Traceback" not in out.stderr, out.stderr
    assert f"cannot write the run's log {blocker / 'r.log'} ({blocker} is a file, not a folder)" in out.stderr
