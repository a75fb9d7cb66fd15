"""The launcher end to end: real processes, real sockets, the CLI as a subprocess."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import msgpack
import pytest
import zmq

from slipstack.launch.priority import has_realtime_priority
from slipstack.messages import decode

from .conftest import pid_alive

pytestmark = pytest.mark.e2e


def _pids(graph: dict) -> dict[str, int]:
    return {name: n["pid"] for name, n in graph["nodes"].items()}


def _wait_until(condition, what: str, g, timeout: float = 30.0) -> None:
    """Poll ``condition`` until it holds; fail naming ``what`` with the launch log (``timeout`` s of the
    time the launch's processes could run)."""
    deadline = g.deadline(timeout)
    while not condition():
        if deadline.expired():
            pytest.fail(f"{what} after {deadline}:\n{g.log()}")
        time.sleep(0.05)


def _processes_of(run_root: Path) -> list[int]:
    """Pids of live processes whose command line names ``run_root`` (nodes and their warm standbys)."""
    found = []
    for entry in Path("/proc").iterdir():
        try:
            cmdline = (entry / "cmdline").read_bytes()
        except OSError:
            continue
        if entry.name.isdigit() and str(run_root).encode() in cmdline and pid_alive(int(entry.name)):
            found.append(int(entry.name))
    return found


def _events(g) -> dict:
    """``launch_events.json`` of the graph's (finished) run directory."""
    return json.loads((g.run_root / "current" / "launch_events.json").read_text())


def _write_launch(run_root: Path, text: str) -> str:
    path = run_root / "graph.toml"
    path.write_text(text)
    return str(path)


def _kill_and_wait_respawn(g, node: str, restarts: int) -> int:
    """SIGKILL ``node``; wait until the launcher has restarted it ``restarts`` times and it is ready; its new pid."""
    old = g.graph()["nodes"][node]["pid"]
    os.kill(old, signal.SIGKILL)

    def back() -> bool:
        now = g.graph()["nodes"][node]
        return now["restarts"] == restarts and now["pid"] != old and pid_alive(now["pid"])

    _wait_until(back, f"{node} not respawned", g)
    _wait_until(lambda: g.log().count(f"[launch] {node} ready again") == restarts, f"{node} not ready again", g)
    return g.graph()["nodes"][node]["pid"]


def _echo_once(g, topic: str) -> str:
    out = g.cli("topic", "echo", topic, "--once", "--timeout", "10")
    assert out.returncode == 0, out.stderr
    return out.stdout


def test_demo_graph_respawns_a_killed_node_and_stops_cleanly_on_each_signal(launch):
    for sig in (signal.SIGINT, signal.SIGTERM):
        g = launch("demo")
        graph = g.wait_ready()
        pids = _pids(graph)
        assert len(pids) == 3 and all(pid_alive(p) for p in pids.values())
        assert "seq:" in _echo_once(g, "ft/relayed")

        os.kill(pids["relay"], signal.SIGKILL)
        deadline = g.deadline(15)
        while not deadline.expired():
            now = g.graph()["nodes"]["relay"]
            if now["restarts"] == 1 and now["pid"] != pids["relay"] and pid_alive(now["pid"]):
                break
            time.sleep(0.05)
        else:
            pytest.fail(f"relay not respawned:\n{g.log()}")
        assert "seq:" in _echo_once(g, "ft/relayed")  # data flows again through the new relay

        all_pids = [*_pids(g.graph()).values(), g.proc.pid]
        g.proc.send_signal(sig)
        g.wait_exit(30)
        _wait_until(lambda: not any(pid_alive(p) for p in all_pids), f"processes left after {sig.name}", g)
        _wait_until(lambda: not _processes_of(g.run_root), f"standby processes left after {sig.name}", g)
        assert g.proc.returncode == 0, g.log()
        assert "[launch] respawning relay (restart 1/3) from its warm standby" in g.log()
        assert "[launch] relay: died 1x, respawned 1x" in g.log()
        events = _events(g)
        assert events["processes"]["relay"] == {"nodes": ["relay"], "died": 1, "respawned": 1, "abandoned": False}
        assert events["processes"]["source"]["died"] == 0 and events["exit_code"] == 0


def _read_diagnostics(endpoint: str, node: str, want: str, timeout: float = 10.0) -> dict:
    ctx = zmq.Context.instance()
    sub = ctx.socket(zmq.SUB)
    sub.setsockopt(zmq.LINGER, 0)
    sub.setsockopt(zmq.SUBSCRIBE, b"diagnostics")
    sub.connect(endpoint)
    try:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if sub.poll(200):
                _, payload = sub.recv_multipart()
                diag = decode(payload)
                if diag.node == node and diag.counters.get(want, 0) >= 1:
                    return diag.counters
        raise AssertionError(f"no diagnostics from {node} with {want} >= 1")
    finally:
        sub.close()


def test_malformed_frame_is_counted_and_dropped_and_the_node_keeps_running(launch):
    g = launch("demo")
    graph = g.wait_ready()
    relay = graph["nodes"]["relay"]
    ctx = zmq.Context.instance()
    pub = ctx.socket(zmq.XPUB)
    pub.setsockopt(zmq.LINGER, 0)
    pub.connect(relay["inject"]["ft/wrench"])
    assert pub.poll(5000), "relay never subscribed to the injection socket"
    pub.recv()
    pub.send_multipart([b"ft/wrench", b"\xc1 not msgpack"])
    pub.send_multipart([b"ft/wrench", msgpack.packb(["slipstack/Wrench", 1, [0, 0, 0, {}], [[1, 2]]])])
    counters = _read_diagnostics(relay["pub"], "relay", "in.ft/wrench.rejected")
    pub.close()
    assert pid_alive(relay["pid"])
    assert g.graph()["nodes"]["relay"]["restarts"] == 0
    assert "seq:" in _echo_once(g, "ft/relayed")
    assert counters["in.ft/wrench.received"] > counters["in.ft/wrench.rejected"] >= 1


def test_a_bad_parameter_stops_the_launch_naming_the_node(launch, run_root):
    bad = run_root / "bad.toml"
    bad.write_text('[[node]]\nname = "src"\ntype = "wrench_source"\nparams = { rate_hz = "fast" }\n')
    g = launch(str(bad))
    assert g.wait_exit(30) != 0
    assert "src" in g.log() and "rate_hz" in g.log()


def test_a_container_runs_its_nodes_in_one_process_hands_messages_over_and_respawns_whole(launch):
    g = launch("demo", "container:=pipeline")
    graph = g.wait_ready()
    nodes = graph["nodes"]
    assert nodes["relay"]["pid"] == nodes["sink"]["pid"] != nodes["source"]["pid"]
    assert nodes["relay"]["process"] == nodes["sink"]["process"] == "pipeline"
    # the relay still publishes on the bus for everyone else ...
    assert "seq:" in _echo_once(g, "ft/relayed")
    # ... and the sink, which has no socket to the relay, gets every message in-process
    counters = _read_diagnostics(nodes["sink"]["pub"], "sink", "in.ft/relayed.received")
    assert counters["in.ft/relayed.received"] >= 1
    assert counters.get("in.ft/relayed.lost", 0) == 0

    os.kill(nodes["sink"]["pid"], signal.SIGKILL)  # the container goes down as one
    deadline = g.deadline(15)
    while not deadline.expired():
        now = g.graph()["nodes"]
        if now["relay"]["restarts"] == now["sink"]["restarts"] == 1 and pid_alive(now["sink"]["pid"]):
            break
        time.sleep(0.05)
    else:
        pytest.fail(f"container not respawned:\n{g.log()}")
    assert now["relay"]["pid"] == now["sink"]["pid"] != nodes["sink"]["pid"]
    assert "seq:" in _echo_once(g, "ft/relayed")
    assert "in 2 processes: pipeline (relay, sink), source" in g.log()
    assert g.stop() == 0


def test_container_members_must_share_their_process_settings(launch, run_root):
    bad = run_root / "bad.toml"
    bad.write_text('[[node]]\nname = "relay"\ntype = "relay"\ncontainer = "c"\nrespawn = true\n'
                   '[[node]]\nname = "sink"\ntype = "sink"\ncontainer = "c"\n')
    g = launch(str(bad))
    assert g.wait_exit(30) != 0
    assert "relay and sink share container 'c'" in g.log()


PIPELINE = """
[[node]]
name = "source"
type = "wrench_source"
{source}
[[node]]
name = "relay"
type = "relay"
{relay}
[[node]]
name = "sink"
type = "sink"
"""


def test_the_respawn_budget_comes_back_after_a_healthy_period(launch, run_root):
    """One restart allowed, but the relay stays up longer than respawn_reset_s between deaths."""
    relay = "respawn = true\nrespawn_max_retries = 1\nrespawn_reset_s = 0.5"
    g = launch(_write_launch(run_root, PIPELINE.format(source="", relay=relay)))
    g.wait_ready()
    _kill_and_wait_respawn(g, "relay", restarts=1)
    time.sleep(1.0)  # longer than respawn_reset_s: the budget is back (a busy machine only makes it longer)
    _kill_and_wait_respawn(g, "relay", restarts=2)
    assert "seq:" in _echo_once(g, "ft/relayed")
    assert g.stop() == 0, g.log_path.read_text()
    assert "ABANDONED" not in g.log_path.read_text()
    assert _events(g)["processes"]["relay"] == {"nodes": ["relay"], "died": 2, "respawned": 2, "abandoned": False}


@pytest.mark.parametrize("relay_policy, args", [("required = true\nrespawn_standby = false", []), ("", ["check:=true"])])
def test_a_node_out_of_restarts_is_abandoned_loudly_and_ends_a_required_or_checked_launch(
        launch, run_root, relay_policy, args):
    relay = f"respawn = true\nrespawn_max_retries = 1\nrespawn_reset_s = 600\n{relay_policy}"
    g = launch(_write_launch(run_root, PIPELINE.format(source="", relay=relay)), *args)
    pids = _pids(g.wait_ready())
    os.kill(_kill_and_wait_respawn(g, "relay", restarts=1), signal.SIGKILL)
    assert g.wait_exit(30) == 1, g.log()
    log = g.log()
    assert "[launch] ABANDONED relay: it exited 2 times in a row (restarted 1x, respawn_max_retries = 1)" in log
    assert "[launch] relay: died 2x, abandoned after 1 restarts" in log
    how = "a new process" if "respawn_standby = false" in relay_policy else "its warm standby"
    assert f"[launch] respawning relay (restart 1/1) from {how}" in log
    if args:
        # no monitor in this launch: the check judges the processes alone
        assert "[launch] CHECK FAILED: relay abandoned after 1 restarts" in log and "check.json" not in log
    assert _events(g)["processes"]["relay"] == {"nodes": ["relay"], "died": 2, "respawned": 1, "abandoned": True}
    _wait_until(lambda: not any(pid_alive(p) for p in pids.values()), "nodes left running", g)


@pytest.mark.parametrize("sig, code, launch_code", [(signal.SIGTERM, 0, 0), (signal.SIGKILL, -9, 1)])
def test_a_required_node_that_exits_ends_the_launch_with_its_code(launch, run_root, sig, code, launch_code):
    g = launch(_write_launch(run_root, PIPELINE.format(source="required = true", relay="")))
    pids = _pids(g.wait_ready())
    os.kill(pids["source"], sig)
    assert g.wait_exit(30) == launch_code, g.log()
    assert f"[launch] node source (wrench_source) exited with code {code}" in g.log()
    assert f"[launch] source is required; stopping the launch (it exited with code {code})" in g.log()
    _wait_until(lambda: not any(pid_alive(p) for p in pids.values()), "nodes left running", g)


@pytest.mark.parametrize("check, code, line", [
    ({"passed": False, "problems": ["object slid 3.2 mm", "fail-safe 12 % of commands"]}, 1,
     "[launch] CHECK FAILED: object slid 3.2 mm; fail-safe 12 % of commands"),
    ({"passed": True, "problems": []}, 0, "[launch] check passed"),
])
def test_check_true_turns_the_monitors_verdict_into_the_exit_code(launch, check, code, line):
    g = launch("demo", "check:=true")
    run_dir = Path(g.wait_ready()["run_dir"])
    (run_dir / "check.json").write_text(json.dumps(check))  # what the monitor writes when it stops
    assert g.stop() == code, g.log_path.read_text()
    log = g.log_path.read_text()
    assert log.rstrip().endswith(line), log
    assert json.loads((run_dir / "check.json").read_text()) == check  # kept for a look afterwards


def test_tools_refuse_a_run_directory_whose_launcher_was_killed(launch):
    g = launch("demo")
    pids = _pids(g.wait_ready())
    g.proc.kill()
    g.proc.wait(10)
    _wait_until(lambda: not any(pid_alive(p) for p in pids.values()), "nodes outlived their launcher", g)
    _wait_until(lambda: not _processes_of(g.run_root), "standby processes outlived their launcher", g)
    for verb in (["hz", "ft/wrench"], ["echo", "ft/wrench"], ["list"]):
        out = g.cli("topic", *verb, timeout=30)
        assert out.returncode == 2, (verb, out.stdout, out.stderr)
        assert f"no running graph (launcher pid {g.proc.pid} is gone; run directory " in out.stderr
        assert "is stale" in out.stderr


def test_a_node_whose_address_is_taken_says_so_in_one_line():
    holder = socket.socket()
    holder.bind(("127.0.0.1", 0))
    holder.listen()
    port = holder.getsockname()[1]
    try:
        out = subprocess.run(
            [sys.executable, "-m", "slipstack.launch.cli", "run", "wrench_source", "--pub", f"tcp://127.0.0.1:{port}"],
            capture_output=True, text=True, timeout=60, env=dict(os.environ, SLIPSTACK_INSECURE="1"),  # tcp, no keys
        )
    finally:
        holder.close()
    assert out.returncode == 2
    assert "Traceback" not in out.stderr
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and "wrench_source: cannot bind its socket" in lines[0], out.stderr
    assert "Address already in use" in lines[0] and "stop it" in lines[0]


def test_a_realtime_priority_is_taken_where_permitted_or_the_launch_says_it_was_not(launch, run_root):
    text = ('[[node]]\nname = "source"\ntype = "wrench_source"\nrealtime_priority = 2\n'
            '[[node]]\nname = "sink"\ntype = "sink"\n')
    g = launch(_write_launch(run_root, text))
    pids = _pids(g.wait_ready())
    if has_realtime_priority(pids["source"]):
        assert os.sched_getparam(pids["source"]).sched_priority == 2
        assert "not granted" not in g.log()
    else:
        assert "node source (wrench_source): realtime_priority 2 not granted" in g.log()
    assert not has_realtime_priority(pids["sink"])
    assert g.stop() == 0


def _standby_of(g, process: str) -> int | None:
    """The pid of ``process``'s warm standby, once the launcher has started it."""
    for pid in _processes_of(g.run_root):
        try:
            args = (Path("/proc") / str(pid) / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if b"--standby" in args and f"{process}.spec.json".encode() in b" ".join(args):
            return pid
    return None


def _all_threads_fifo_at(pid: int, priority: int) -> bool:
    tids = [int(t) for t in os.listdir(f"/proc/{pid}/task")]
    return all(has_realtime_priority(t) and os.sched_getparam(t).sched_priority == priority for t in tids)


def test_a_warm_standby_prepares_at_normal_scheduling_and_takes_the_realtime_priority_when_woken(launch, run_root):
    """A standby imports its node's modules and loads its kernels (about a second of CPU) while
    the graph runs: under SCHED_FIFO it took a core from the real-time nodes for 100 ms and more at
    a launch's start (the simulated finger's command watchdog fired). It waits at normal
    scheduling, and the node it becomes runs at its realtime_priority once ready, every thread."""
    relay = "respawn = true\nrealtime_priority = 2"
    g = launch(_write_launch(run_root, PIPELINE.format(source="", relay=relay)))
    pids = _pids(g.wait_ready())
    if not has_realtime_priority(pids["relay"]):
        pytest.skip("SCHED_FIFO is not permitted here (root, CAP_SYS_NICE or ulimit -r)")
    _wait_until(lambda: _standby_of(g, "relay") is not None, "no warm standby for relay", g)
    standby = _standby_of(g, "relay")
    assert not has_realtime_priority(standby)
    assert _kill_and_wait_respawn(g, "relay", restarts=1) == standby
    assert _all_threads_fifo_at(standby, 2)
    assert "not granted" not in g.log()
    assert g.stop() == 0, g.log()


def test_ctrl_c_while_the_simulated_rig_starts_is_a_clean_interrupted_exit(launch, tmp_path):
    """Ctrl-C while the launch starts (here: as the rig's process is importing) printed the node's
    Python traceback and ended as a failed launch (exit 1, CHECK FAILED); it is the operator's
    stop: one line, exit 130, nothing left running. Default arguments (the rig and its recorder)."""
    g = launch(f"recording:={tmp_path / 'run.mcap'}")
    graph_path = g.run_root / "current" / "graph.json"
    deadline = g.deadline(60)

    def rig_spawned() -> bool:
        try:
            graph = json.loads(graph_path.read_text())
        except (OSError, ValueError):  # not yet written, or being replaced
            return False
        return graph.get("state") == "starting" and graph["nodes"].get("rig", {}).get("pid") is not None

    while not rig_spawned():
        assert g.proc.poll() is None and not deadline.expired(), g.log()
        time.sleep(0.005)
    g.proc.send_signal(signal.SIGINT)
    assert g.wait_exit(30) == 130, g.log()
    log = g.log()
    assert "[launch] interrupted while starting" in log and "[launch] no check: the graph never ran" in log, log
    assert "Traceback" not in log and "error:" not in log and "CHECK FAILED" not in log, log
    _wait_until(lambda: not _processes_of(g.run_root), "processes left after the interrupted start", g)
