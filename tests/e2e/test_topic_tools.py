"""``slipstack topic`` end to end: the demo graph launched for real, the CLI as a subprocess."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import msgpack
import numpy as np
import pytest
import zmq

from slipstack.messages import Header, Wrench, encode
from slipstack.nodes.tools.topic_hz import rate_stats
from slipstack.nodes.tools.topic_pub import Injector
from slipstack.nodes.tools.topic_tools import resolve_topic
from slipstack.nodes.tools.topic_yaml import parse_flow

from .conftest import LaunchedGraph, pid_alive

pytestmark = pytest.mark.e2e

WRENCH_COLUMNS = ["header.stamp_ns", "header.seq", "header.pub_ns", "force.0", "force.1", "force.2",
                  "torque.0", "torque.1", "torque.2", "frame", "device_seq", "status"]


@pytest.fixture(scope="module")
def demo():
    """One demo graph (1 kHz source -> relay -> sink) shared by this module's tests; it
    runs until the module is done (no fixed lifetime a slow machine could outlast)."""
    with tempfile.TemporaryDirectory(prefix="sst-", dir="/tmp") as root:
        g = LaunchedGraph(["demo", "duration_s:=0"], Path(root))
        try:
            g.wait_ready()
            yield g
        finally:
            code = g.stop(signal.SIGINT)
            assert code == 0, g.log()


def _ok(out: subprocess.CompletedProcess) -> str:
    assert out.returncode == 0, f"exit {out.returncode}\n{out.stderr}"
    return out.stdout


def test_list_and_info_describe_the_demo_graph(demo):
    assert _ok(demo.cli("topic", "list")).split() == ["diagnostics", "ft/relayed", "ft/wrench"]
    assert "ft/wrench [slipstack/Wrench]" in _ok(demo.cli("topic", "list", "-t")).splitlines()
    graph = demo.graph()
    verbose = _ok(demo.cli("topic", "list", "-v"))
    assert f"ft/wrench [slipstack/Wrench] 1 publisher: source ({graph['nodes']['source']['pub']})" in verbose
    assert "diagnostics [slipstack/Diagnostics] 3 publishers" in verbose
    info = _ok(demo.cli("topic", "info", "/ft/wrench", "-v"))
    assert info.startswith("Type: slipstack/Wrench\nPublisher count: 1\n")
    assert "Subscription count: 1" in info
    assert graph["nodes"]["relay"]["inject"]["ft/wrench"] in info


def test_unknown_topic_is_a_config_error_listing_the_known_ones(demo):
    out = demo.cli("topic", "info", "ft/wrnch")
    assert out.returncode == 2
    assert "unknown topic 'ft/wrnch'" in out.stderr and "ft/relayed, ft/wrench" in out.stderr
    # echo waits for a topic that may be published later, and says at once which ones are
    out = demo.cli("topic", "echo", "ft/wrnch", "--once", "--timeout", "1")
    assert out.returncode == 1
    assert "waiting for ft/wrnch (not in the graph yet; its topics: diagnostics, ft/relayed, ft/wrench)" in out.stderr


def test_echo_once_prints_one_yaml_block(demo):
    text = _ok(demo.cli("topic", "echo", "ft/wrench", "--once", "--timeout", "30"))
    lines = text.splitlines()
    assert lines[0] == "header:" and lines[-1] == "---" and lines.count("---") == 1
    force = parse_flow(next(ln for ln in lines if ln.startswith("force: ")).split(": ", 1)[1])
    assert len(force) == 3 and force[1:] == [0.0, 10.0] and abs(force[0]) <= 2.0  # demo: f_z 10 N, f_x 2 N sine
    assert "torque: [0.0, 0.0, 0.0]" in lines and "frame: sensor" in lines
    no_arr = _ok(demo.cli("topic", "echo", "ft/wrench", "--once", "--no-arr", "--timeout", "30"))
    assert "force: '<array float64 (3,)>'" in no_arr.splitlines()


def test_echo_field_and_csv_follow_consecutive_samples(demo):
    stamps = [int(v) for v in _ok(demo.cli("topic", "echo", "ft/wrench", "--field", "header.stamp_ns",
                                            "--count", "3", "--timeout", "30")).split() if v != "---"]
    # consecutive samples: later stamps (how much later depends on the load: a source
    # catching up after a stall sends its late ticks back to back)
    assert len(stamps) == 3 and all(b > a for a, b in zip(stamps, stamps[1:])), stamps

    rows = _ok(demo.cli("topic", "echo", "ft/wrench", "--csv", "--count", "5", "--timeout", "30")).splitlines()
    assert rows[0].split(",") == WRENCH_COLUMNS and len(rows) == 6
    table = [dict(zip(WRENCH_COLUMNS, r.split(","))) for r in rows[1:]]
    seqs = [int(r["header.seq"]) for r in table]
    assert seqs == list(range(seqs[0], seqs[0] + 5))  # no loss at 1 kHz
    assert [int(r["device_seq"]) for r in table] == [int(table[0]["device_seq"]) + k for k in range(5)]
    row_stamps = [int(r["header.stamp_ns"]) for r in table]
    assert all(b > a for a, b in zip(row_stamps, row_stamps[1:])), row_stamps
    assert all(float(r["force.2"]) == 10.0 and r["status"] == "ok" for r in table)


def _rates(text: str) -> list[float]:
    return [float(m) for m in re.findall(r"average rate: ([0-9.]+)", text)]


def test_hz_reports_the_1khz_rate(demo):
    """Rates over 2000-sample windows (2 s at 1 kHz), so that a stall of the machine
    shifts a window's ends by a small share of its span, by receive time and by stamp."""
    cmd = [sys.executable, "-m", "slipstack.launch.cli", "topic", "hz", "ft/wrench", "--window", "2000",
           "--duration", "4.5"]
    by_stamps = subprocess.Popen([*cmd, "--use-stamps"], env=demo.env, stdout=subprocess.PIPE, text=True)
    out = _ok(demo.cli(*cmd[3:]))
    assert by_stamps.wait(30) == 0
    received, stamped = _rates(out), _rates(by_stamps.stdout.read())
    assert len(received) >= 2 and len(stamped) >= 2 and "window: " in out, (out, stamped)
    # hz measures what is on the wire: receive times agree with the source's own stamps ...
    assert received[-1] == pytest.approx(stamped[-1], rel=0.1), (received, stamped)
    # ... and the source stamps at most 1 kHz; a starved source skips late ticks (counted
    # on its diagnostics), so only a generous lower bound holds on a busy machine
    assert 500.0 <= stamped[-1] <= 1010.0, f"receive times {received}, source stamps {stamped}"


def test_pub_reaches_the_subscriber_through_its_injection_endpoint(demo):
    echo = subprocess.Popen(
        [sys.executable, "-m", "slipstack.launch.cli", "topic", "echo", "ft/relayed", "--field", "force",
         "--filter", "m.force[0] == 7.25", "--count", "3", "--timeout", "60"],
        env=demo.env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    # echo subscribes at some point of a busy machine's choosing: publish until it has
    # seen three of our messages (each one goes through the relay's injection endpoint)
    pub = subprocess.Popen(
        [sys.executable, "-m", "slipstack.launch.cli", "topic", "pub", "ft/wrench", "slipstack/Wrench",
         "{force: [7.25, 0, 1]}", "--times", "600", "--rate", "10"],
        env=demo.env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    try:
        out, err = echo.communicate(timeout=70)
    finally:
        pub.send_signal(signal.SIGINT)
        pub_out, pub_err = pub.communicate(timeout=30)
    assert echo.returncode == 0, err
    assert out.split("\n---\n")[:3] == ["[7.25, 0.0, 1.0]"] * 3
    published = pub_out.splitlines()
    assert len(published) >= 3 and published == [f"publishing #{k} on ft/wrench" for k in range(1, len(published) + 1)]


@pytest.mark.parametrize("verb", [["topic", "pub", "ft/wrench", "{force: [7.25, 0, 1]}", "--rate", "10"],
                                  ["topic", "echo", "ft/relayed", "--field", "force"],
                                  ["topic", "hz", "ft/relayed"]])
def test_a_tool_started_with_ctrl_c_ignored_still_stops_on_it(demo, verb):
    # a job a script starts with `cmd &` inherits SIGINT ignored: the tool must stop on it anyway
    # and leave nothing registered in the run directory
    tool = subprocess.Popen([sys.executable, "-m", "slipstack.launch.cli", *verb], env=demo.env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    try:
        out = tool.stdout.readline()  # it runs: its first line of output
        assert out, tool.stderr.read()
        tool.send_signal(signal.SIGINT)
        tool.communicate(timeout=30)
    finally:
        tool.kill()
    assert tool.returncode == 0
    assert not list(demo.run_root.glob(f"*/tool-*-{tool.pid}.json"))


def test_malformed_injected_frames_are_rejected_and_counted_by_the_node(demo):
    graph = demo.graph()
    injector = Injector(resolve_topic(graph, "ft/wrench"))
    try:
        assert injector.wait_for_subscribers(5.0) == 1
        injector.send(b"\xc1 not msgpack")
        injector.send(msgpack.packb(["slipstack/Wrench", 1, [0, 0, 0, {}], [[1.0, 2.0]]]))
    finally:
        injector.close()
    out = _ok(demo.cli("topic", "echo", "diagnostics", "--field", "counters", "--once", "--timeout", "30",
                       "--filter", "m.node == 'relay' and m.counters.get('in.ft/wrench.rejected', 0) >= 2"))
    counters = {k: float(v) for k, v in (ln.split(": ") for ln in out.splitlines() if ": " in ln)}
    assert counters["in.ft/wrench.rejected"] == 2
    assert counters["in.ft/wrench.received"] > 2
    relay = demo.graph()["nodes"]["relay"]
    assert pid_alive(relay["pid"]) and relay["restarts"] == 0
    assert "seq:" in _ok(demo.cli("topic", "echo", "ft/relayed", "--once", "--timeout", "30"))


def test_echo_reports_rejects_gaps_and_restarts_per_publisher(tmp_path):
    """A hand-made graph whose only publisher is this test: exact control of the frames."""
    run = Path(tempfile.mkdtemp(prefix="sse-", dir="/tmp"))
    ep = f"ipc://{run}/fake.pub"
    (run / "graph.json").write_text(json.dumps({"nodes": {"fake": {
        "type": "x", "pid": None, "pub": ep, "inputs": {}, "outputs": {"ft/wrench": Wrench.TYPE}}}}))
    pub = zmq.Context.instance().socket(zmq.XPUB)
    pub.setsockopt(zmq.LINGER, 0)
    pub.bind(ep)
    echo = subprocess.Popen(
        [sys.executable, "-m", "slipstack.launch.cli", "topic", "echo", "ft/wrench", "--field", "header.seq",
         "--count", "4", "--timeout", "30", "--run-dir", str(run)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    try:
        assert pub.poll(60_000) and pub.recv() == b"\x01ft/wrench"
        for frame in (0, 1, b"garbage", 5, 0, 1):
            payload = frame if isinstance(frame, bytes) else encode(Wrench(header=Header(7, frame, 7, {})))
            pub.send_multipart([b"ft/wrench", payload])
        out, err = echo.communicate(timeout=60)
    finally:
        pub.close()
        if echo.poll() is None:
            echo.kill()
    assert echo.returncode == 0, err
    assert [int(v) for v in out.split() if v != "---"] == [0, 1, 5, 0]
    assert "rejected a frame from fake: payload: not a valid MessagePack frame" in err
    assert "lost 3 message(s) from fake before seq 5" in err
    assert "fake restarted its sequence (seq 0)" in err
    assert "4 printed, 3 lost, 1 rejected" in err


def test_rate_stats_match_hand_values():
    s = rate_stats(np.array([0, 1_000_000, 2_000_000, 4_000_000], dtype=np.int64))  # periods 1, 1, 2 ms
    assert s.rate_hz == pytest.approx(750.0) and (s.min_s, s.max_s) == pytest.approx((1e-3, 2e-3))
    assert s.std_s == pytest.approx(np.std([1e-3, 1e-3, 2e-3]))


# -- echo exits on what can never print, and --timeout is a total deadline ----
@pytest.mark.parametrize("field,words", [("force.5", "force is an array of 3 value(s)"),
                                         ("status.0", "status is a single value"),
                                         # a misspelt header field printed nothing and never exited, even --once
                                         ("header.stampns", "header has no field 'stampns'; its fields: stamp_ns")])
def test_echo_a_field_no_message_can_have_is_a_clear_error(demo, field, words):
    out = demo.cli("topic", "echo", "ft/wrench", "--field", field, "--once", timeout=60)
    assert out.returncode == 2, out
    assert words in out.stderr and "Traceback" not in out.stderr, out.stderr


def test_echo_says_when_no_message_has_a_map_key(demo):
    """A key below a map (``header.sources``) may come with a later message: echo waits, and
    says so once many have come without it (it used to wait in silence)."""
    out = demo.cli("topic", "echo", "ft/wrench", "--field", "header.sources.nosuch", "--once", "--timeout", "5")
    assert out.returncode == 1, out
    assert "messages so far have no header.sources.nosuch" in out.stderr and "check the spelling" in out.stderr


def test_echo_waits_for_a_topic_published_later(demo, tmp_path):
    """``topic echo ft/later`` before anything publishes it waits, as ros2's does, and prints the
    first message once ``bag play`` publishes it (it was refused: "unknown topic")."""
    from slipstack.messages import Header, Wrench, encode
    from slipstack.nodes.recording.bag_io import RecordingWriter

    rec = tmp_path / "later.mcap"
    with RecordingWriter(rec, wall_minus_monotonic_ns=0) as w:
        for k in range(200):
            stamp = 10**9 + k * 10**7
            w.write("ft/later", encode(Wrench(force=np.array([0.0, 0.0, -4.5]), torque=np.zeros(3),
                                              header=Header(stamp, k, stamp, {}))), stamp)
    echo = subprocess.Popen([sys.executable, "-m", "slipstack.launch.cli", "topic", "echo", "ft/later", "--once",
                             "--field", "force", "--timeout", "60"], env=demo.env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    play = None
    try:
        said = echo.stderr.readline()
        assert said.startswith("topic echo: waiting for ft/later (not in the graph yet; its topics: "), said
        play = subprocess.Popen([sys.executable, "-m", "slipstack.launch.cli", "bag", "play", str(rec), "--loop"],
                                env=demo.env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        out, err = echo.communicate(timeout=60)
    finally:
        echo.kill()
        if play is not None:
            play.send_signal(signal.SIGINT)  # it unregisters its endpoint from the run directory
            play.wait(30)
    assert echo.returncode == 0, err
    assert out.startswith("[0.0, 0.0, -4.5]"), out


def test_echo_a_filter_that_raises_is_a_clear_error(demo):
    out = demo.cli("topic", "echo", "ft/wrench", "--filter", "m.nosuch > 1")
    assert out.returncode == 2, out
    assert "--filter 'm.nosuch > 1' raised AttributeError" in out.stderr, out.stderr


def test_echo_timeout_is_a_total_deadline_on_a_busy_topic(demo):
    """1 kHz keeps arriving: a per-frame timeout would never expire (the subprocess timeout would)."""
    out = demo.cli("topic", "echo", "ft/wrench", "--field", "header.seq", "--timeout", "1", timeout=30)
    assert out.returncode == 0, out.stderr
    assert len(out.stdout.split("---")) > 10


def test_echo_a_filter_that_never_matches_ends_at_the_timeout(demo):
    out = demo.cli("topic", "echo", "ft/wrench", "--filter", "m.header.seq < 0", "--timeout", "1", timeout=30)
    assert out.returncode == 1, out
    assert "none passed --filter" in out.stderr


# -- what topic pub sends is on the bus, and injectors do not fake losses ------
def _relay_counters(demo) -> dict[str, float]:
    out = _ok(demo.cli("topic", "echo", "diagnostics", "--field", "counters", "--once",
                       "--timeout", "8", "--filter", "m.node == 'relay'"))
    return {k: float(v) for k, v in (ln.split(": ") for ln in out.splitlines() if ": " in ln)}


def test_pub_is_seen_by_echo_and_bag_record_on_the_topic_itself(demo, tmp_path):
    def tool(*args):
        return subprocess.Popen([sys.executable, "-m", "slipstack.launch.cli", *args], env=demo.env,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    echo = tool("topic", "echo", "ft/wrench", "--field", "force", "--filter", "m.force[0] == 7.25",
                "--count", "3", "--timeout", "20")
    bag = tmp_path / "pub.mcap"
    record = tool("bag", "record", "ft/wrench", "-o", str(bag))
    pub = demo.cli("topic", "pub", "ft/wrench", "{force: [7.25, 0, 1]}", "--times", "60", "--rate", "20",
                   "-p", "0", timeout=60)
    assert pub.returncode == 0, pub.stderr
    out, err = echo.communicate(timeout=30)
    assert echo.returncode == 0, err
    assert out.split("\n---\n")[:3] == ["[7.25, 0.0, 1.0]"] * 3
    record.send_signal(signal.SIGINT)
    record.communicate(timeout=30)
    from slipstack.messages import decode
    from slipstack.nodes.recording.bag_io import read_recording
    injected = [f for f in read_recording(str(bag), ["ft/wrench"]) if decode(f.payload).force[0] == 7.25]
    assert len(injected) >= 3
    assert not list(demo.run_root.glob("*/tool-*.json"))  # the tools unregistered at exit


def test_two_tools_injecting_at_once_are_no_loss(demo):
    before = _relay_counters(demo)
    pubs = [subprocess.Popen([sys.executable, "-m", "slipstack.launch.cli", "topic", "pub", "ft/wrench",
                              f"{{force: [{x}, 0, 1]}}", "--times", "40", "--rate", "40", "-p", "0"],
                             env=demo.env, stderr=subprocess.PIPE, text=True) for x in (1.5, 2.5)]
    for p in pubs:
        _, err = p.communicate(timeout=60)
        assert p.returncode == 0, err
    # wait for a diagnostics report that has counted what the tools sent, however busy the machine
    received = "in.ft/wrench.received"
    for _ in range(20):
        after = _relay_counters(demo)
        if after.get(received, 0) >= before.get(received, 0) + 80:
            break
    assert after.get(received, 0) >= before.get(received, 0) + 80, (before, after)
    assert after.get("in.ft/wrench.lost", 0) == before.get("in.ft/wrench.lost", 0)


def test_bag_record_of_an_unknown_topic_names_the_known_ones(demo, tmp_path):
    """``bag record nosuch/topic`` wrote an empty file and exited 0."""
    out = demo.cli("bag", "record", "nosuch/topic", "-o", str(tmp_path / "x.mcap"), "--duration", "1")
    assert out.returncode == 2, out
    assert "nosuch/topic" in out.stderr and "ft/wrench" in out.stderr
    assert not (tmp_path / "x.mcap").exists()


def test_delay_reports_sample_to_here_latency(demo):
    """``topic delay`` (receive time - header stamp), ros2's output form."""
    out = _ok(demo.cli("topic", "delay", "ft/wrench", "--duration", "2.5", "--window", "500"))
    delays = [float(m) for m in re.findall(r"average delay: ([0-9.e-]+)s", out)]
    assert delays, out
    assert all(0 <= d < 5.0 for d in delays), out  # stamps are taken before sending: never negative
    assert "window: 500" in out


def test_node_list_and_info_show_processes_parameters_and_counters(demo):
    """``node list`` / ``node info`` (pid, rates, counters, parameters)."""
    listing = _ok(demo.cli("node", "list"))
    pids = {n: e["pid"] for n, e in demo.graph()["nodes"].items()}
    for name in ("source", "relay", "sink"):
        assert f"{name}  [" in listing and f"pid {pids[name]} running" in listing
    info = _ok(demo.cli("node", "info", "source"))
    assert "type: wrench_source" in info and "ft/wrench [slipstack/Wrench]" in info
    assert "rate_hz: 1000.0" in info  # the launch parameter, from the run spec
    assert "status: ok" in info and re.search(r"out\.ft/wrench\.published: \d+", info)
    out = demo.cli("node", "info", "nosuch")
    assert out.returncode == 2 and "relay" in out.stderr


def test_bw_reports_bytes_per_second_and_sizes(demo):
    """``topic bw``, ros2's output form: bytes per second and payload sizes."""
    from slipstack.messages import Header, Wrench, encode

    out = _ok(demo.cli("topic", "bw", "ft/wrench", "--duration", "2.5", "--window", "500"))
    found = re.findall(r"average: ([0-9.]+) (B|KB|MB)/s\n\tmean: ([0-9.]+) B min: (\d+) B max: (\d+) B window: (\d+)",
                       out)
    assert found, out
    smallest = len(encode(Wrench(), Header(0, 0, 0, {})))  # the demo's stamps and seq only make it longer
    for rate, unit, mean, low, high, window in found:
        assert smallest <= int(low) <= float(mean) <= int(high) <= smallest + 64, out
        assert float(rate) * {"B": 1, "KB": 1e3, "MB": 1e6}[unit] > 0 and int(window) <= 500, out


@pytest.mark.parametrize("values, said", [
    ("{force: [1, 2, 3], force: [4, 5, 6]}", "key 'force' given twice"),  # was: the last one, silently
    ("{force: [1, 2, 3O]}", "Wrench.force"),  # a mistyped number is a string the field refuses
    ("{force: &f [1, 2, 3], torque: *f}", "aliases"),
    ("{force: [1, 2, 3]} extra", "cannot read"),
])
def test_pub_refuses_what_is_not_meant(demo, values, said):
    """PyYAML for ``topic pub``: a typo is an error that says where, not a value."""
    out = demo.cli("topic", "pub", "ft/wrench", values, "--once")
    assert out.returncode == 2 and said in out.stderr, out


def test_pub_reads_yaml_block_style_and_comments(demo):
    out = demo.cli("topic", "pub", "ft/wrench", "force: [7.25, 0, 1e0]  # a test force\ntorque: [0, 0, 0]",
                   "--once")
    assert out.returncode == 0, out.stderr
