"""One graph over two machines: two launchers on two loopback addresses, CURVE on.

``launch/files/two_hosts.toml`` puts the rig and the drivers on ``robot`` (127.0.0.1)
and the control path, the monitor and the recorder on ``workstation`` (127.0.0.2), each
launched by its own ``slipstack launch two_hosts --machine NAME`` with its own run root
and key directory, as documented: default arguments, only the port range chosen free.
The closed loop must hold Fig. 15's object three runs of three (recorded ``rig/truth``).
Tools on the workstation see and record the robot's topics; a peer with a key pair the
graph does not know gets nothing. Other tests freeze the robot (its launcher and nodes
stopped, as a dropped link looks from the workstation) and kill the robot's launcher.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import msgpack
import numpy as np
import pytest
import zmq
import zmq.auth
from free_ports import free_port_block

from slipstack.lib.toml_file import resolve_path
from slipstack.messages import Header, Wrench, decode, encode
from slipstack.nodes.recording.bag_io import read_recording

from .conftest import LaunchedGraph, count_frames, ended_by_its_check, pid_alive

pytestmark = pytest.mark.e2e

ROBOT, WORKSTATION = "127.0.0.1", "127.0.0.2"
RUNS = 3  # the documented launch must hold every time, not most times


@pytest.fixture
def two_hosts(tmp_path):
    """``start(*args)`` → (robot, workstation) launchers of two_hosts.toml with fresh keys and a
    random port range, otherwise the default arguments, run in ``tmp_path`` (the default
    recording goes to its ``runs/``); both killed at teardown."""
    keys = tmp_path / "keys"
    made = subprocess.run([sys.executable, "-m", "slipstack.launch.cli", "keys", str(keys), "--machine", "robot",
                           "--machine", "workstation"], capture_output=True, text=True, timeout=60)
    assert made.returncode == 0, made.stderr
    first = free_port_block(100, (ROBOT, WORKSTATION))
    graphs: list[LaunchedGraph] = []
    roots: list[tempfile.TemporaryDirectory] = []

    def start(*extra: str) -> tuple[LaunchedGraph, LaunchedGraph]:
        common = ["two_hosts", f"keys:={keys}", f"first_port:={first}", f"last_port:={first + 99}", *extra]
        for machine in ("robot", "workstation"):
            roots.append(tempfile.TemporaryDirectory(prefix="ss-", dir="/tmp"))
            graphs.append(LaunchedGraph([*common, "--machine", machine], Path(roots[-1].name), cwd=tmp_path))
        return graphs[-2], graphs[-1]

    start.keys, start.first_port = keys, first
    yield start
    for g in graphs:
        g.stop(9 if g.proc.poll() is None else 2)
    for r in roots:
        r.cleanup()


def _scene(tmp_path: Path, seconds: float) -> Path:
    """Fig. 15's scene lasting ``seconds`` (a test that needs the graph up longer than the scene)."""
    scene = tmp_path / "fig15_long.toml"
    text = resolve_path("fig15", Path.cwd(), "scenes").read_text()
    scene.write_text(text.replace("duration_s = 12.0", f"duration_s = {seconds}", 1))
    return scene


def _curve_client(ctx: zmq.Context, kind: int, secret_file: Path, server_public_file: Path) -> zmq.Socket:
    sock = ctx.socket(kind)
    sock.setsockopt(zmq.LINGER, 0)
    sock.curve_publickey, sock.curve_secretkey = zmq.auth.load_certificate(secret_file)
    sock.curve_serverkey = zmq.auth.load_certificate(server_public_file)[0]
    return sock


@pytest.mark.parametrize("run", range(1, RUNS + 1))
def test_the_documented_launch_holds_fig15_with_default_arguments(two_hosts, tmp_path, run):
    robot, workstation = two_hosts()
    graph = workstation.wait_ready(timeout=90)
    robot.wait_ready(timeout=90)
    nodes = graph["nodes"]
    assert nodes["rig"]["machine"] == "robot" and nodes["rig"]["pub"].startswith(f"tcp://{ROBOT}:")
    assert nodes["fusion"]["pub"].startswith("ipc://")  # on one machine the link stays ipc

    # the scene ends: the rig (required) exits, its launcher stops, the workstation follows
    assert robot.proc.wait(90) == 0, robot.log()
    try:
        ended_by_its_check(workstation, 90)
    except subprocess.TimeoutExpired:
        pytest.fail("the workstation's launcher did not follow the robot's:\n" + workstation.log()[-4000:])
    assert "machine robot (127.0.0.1) stopped" in workstation.log()
    # the truth, as the rig recorded it on the workstation's default recording
    recordings = list((tmp_path / "runs").glob("*.mcap"))
    assert len(recordings) == 1, recordings
    truth = [decode(f.payload) for f in read_recording(recordings[0], ["rig/truth"])]
    commands = [decode(f.payload) for f in read_recording(recordings[0], ["grip/command"])]
    assert truth and truth[-1].header.stamp_ns - truth[0].header.stamp_ns > 11e9  # the whole 12 s scene
    assert len(commands) > 4000  # the loop closed from the start (500 Hz for 12 s)
    slid_mm = max(t.slip_distance_m for t in truth) * 1e3
    turned_deg = max(abs(t.slip_angle_rad) for t in truth) * 180 / np.pi
    assert slid_mm < 0.1 and turned_deg < 0.1, (slid_mm, turned_deg)


TOOLS_SCENE_S = 30.0
"""The scene while tools attach from the workstation: they start after the graph is ready, and
on a busy host their start alone can outlast the 12 s scene (the graph is then gone); the
default scene is run by the test above."""


def test_tools_on_the_workstation_see_the_robot_and_strangers_get_nothing(two_hosts, tmp_path):
    robot, workstation = two_hosts(f"scene:={_scene(tmp_path, TOOLS_SCENE_S)}")
    graph = workstation.wait_ready(timeout=90)
    robot.wait_ready(timeout=90)
    nodes = graph["nodes"]
    # a tool on the workstation sees the robot's topics (over tcp, with the workstation's keys)
    echo = subprocess.Popen([sys.executable, "-m", "slipstack.launch.cli", "topic", "echo", "rig/truth", "--once",
                             "--no-arr", "--timeout", "30"], env=workstation.env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    recording = tmp_path / "wrench.mcap"  # and records them
    record = subprocess.Popen([sys.executable, "-m", "slipstack.launch.cli", "bag", "record", "ft/wrench", "-o",
                               str(recording), "--duration", "1.5"], env=workstation.env, stdout=subprocess.PIPE,
                              stderr=subprocess.PIPE, text=True)

    # a peer with a key pair the graph does not know: no frames, no answer from a launcher
    stranger_keys = tmp_path / "stranger"
    subprocess.run([sys.executable, "-m", "slipstack.launch.cli", "keys", str(stranger_keys), "--machine", "robot"],
                   check=True, capture_output=True, timeout=60)
    ctx = zmq.Context()
    try:
        legit = _curve_client(ctx, zmq.SUB, two_hosts.keys / "workstation" / "workstation.key_secret",
                              two_hosts.keys / "workstation" / "robot.key")
        wrong = _curve_client(ctx, zmq.SUB, stranger_keys / "robot" / "robot.key_secret",
                              two_hosts.keys / "workstation" / "robot.key")
        for sock in (legit, wrong):
            sock.setsockopt(zmq.SUBSCRIBE, b"")
            sock.connect(nodes["rig"]["pub"])
        pinger = _curve_client(ctx, zmq.DEALER, stranger_keys / "robot" / "robot.key_secret",
                               two_hosts.keys / "workstation" / "workstation.key")
        member = _curve_client(ctx, zmq.DEALER, two_hosts.keys / "robot" / "robot.key_secret",
                               two_hosts.keys / "robot" / "workstation.key")
        for sock in (pinger, member):
            sock.connect(f"tcp://{WORKSTATION}:{two_hosts.first_port}")  # the workstation's launcher
            sock.send_multipart([b"ping", (0).to_bytes(8, "big"), b"robot"])
        # the graph's keys are answered and served (generous waits: a busy machine may take seconds
        # over the CURVE handshakes of a node that has just started), then the stranger in the same time
        assert member.poll(60_000), workstation.log()[-3000:]  # the robot's key pair is answered
        assert legit.poll(60_000) and count_frames(legit, 1.0) > 10, robot.log()[-3000:]
        assert count_frames(wrong, 1.0) == 0
        assert not pinger.poll(1000)
    finally:
        ctx.destroy(linger=0)
    out, err = echo.communicate(timeout=60)
    assert echo.returncode == 0 and "slip_distance" in out, err
    out, err = record.communicate(timeout=60)
    assert record.returncode == 0, err
    frames = int(re.search(r"wrote .*: (\d+) frames", out + err).group(1))
    assert frames > 0, out

    for g in (robot, workstation):
        g.stop()


def test_a_machine_whose_launcher_dies_takes_its_nodes_and_is_reported(two_hosts):
    robot, workstation = two_hosts()
    workstation.wait_ready(timeout=90)
    robot_nodes = robot.wait_ready(timeout=90)["nodes"]
    pids = [v["pid"] for v in robot_nodes.values() if v.get("machine") == "robot"]
    assert pids and all(pid_alive(p) for p in pids)
    robot.proc.kill()  # no goodbye: the workstation must notice the silence
    deadline = workstation.deadline(30)
    while not deadline.expired() and ("went quiet" not in workstation.log() or any(map(pid_alive, pids))):
        time.sleep(0.1)
    assert not any(pid_alive(p) for p in pids), "the robot's nodes outlived their launcher"
    assert "machine robot (127.0.0.1) went quiet" in workstation.log(), workstation.log()


def test_a_machine_gone_quiet_is_named_the_grip_holds_and_the_loop_resumes(two_hosts, tmp_path):
    # a scene that outlasts the test; no monitor: its summary of a frozen run is not what is
    # tested here and it costs a core's share (the default, monitor on, runs in the test above)
    robot, workstation = two_hosts(f"scene:={_scene(tmp_path, 120.0)}", "monitor:=false")
    nodes = workstation.wait_ready(timeout=90)["nodes"]
    robot_pids = [robot.proc.pid, *(v["pid"] for v in robot.wait_ready(timeout=90)["nodes"].values()
                                    if v.get("machine") == "robot")]
    ctx = zmq.Context()
    commands = ctx.socket(zmq.SUB)  # on the workstation, where the controller runs: its ipc endpoint
    commands.setsockopt(zmq.SUBSCRIBE, b"grip/command")
    commands.connect(nodes["grip_controller"]["pub"])
    diagnostics = ctx.socket(zmq.SUB)  # the controller's status line, as the monitor reads it
    diagnostics.setsockopt(zmq.SUBSCRIBE, b"diagnostics")
    diagnostics.connect(nodes["grip_controller"]["pub"])

    def status_naming(text: str, seconds: float) -> str:
        """The first status of the controller containing ``text`` within ``seconds`` (else the last seen)."""
        status, end = "", time.monotonic() + seconds
        while time.monotonic() < end and text not in status:
            if diagnostics.poll(100):
                status = decode(diagnostics.recv_multipart()[1]).status
        return status

    def read(seconds: float, until: str | None = None) -> list[tuple[float, str]]:
        """(f_n desired, reason) of the commands over ``seconds``, or until ``until`` is in the log."""
        got, end = [], time.monotonic() + seconds
        while time.monotonic() < end and not (until and until in workstation.log()):
            if commands.poll(50):
                _, payload = commands.recv_multipart()
                body = msgpack.unpackb(payload, raw=False, strict_map_key=False)[3]
                got.append((float(body[0]), str(body[2])))
        return got

    try:
        before: list[tuple[float, str]] = []
        deadline = workstation.deadline(30)
        while not deadline.expired() and not any(reason != "fail-safe" for _, reason in before):
            before += read(0.5)
        assert before, "no grip command before the freeze"
        for pid in robot_pids:
            os.kill(pid, signal.SIGSTOP)  # the robot's computer vanishes from the network
        frozen = read(30, until="machine robot (127.0.0.1) went quiet")
        assert "machine robot (127.0.0.1) went quiet" in workstation.log(), workstation.log()
        held = read(1.0)
        assert held and all(reason == "fail-safe" for _, reason in held), held
        status = status_naming("(from machine robot, 127.0.0.1)", 30)  # the controller itself names it
        assert status.startswith("fail-safe: ") and "(from machine robot, 127.0.0.1)" in status, status
        trail = before + frozen + held  # from the last command judged on fresh data on, never lower
        last_ok = max(k for k, (_, reason) in enumerate(trail) if reason != "fail-safe")
        forces = [f for f, _ in trail[last_ok:]]
        assert all(b >= a - 1e-9 for a, b in zip(forces, forces[1:])), forces
        for pid in robot_pids:
            os.kill(pid, signal.SIGCONT)
        read(30, until="machine robot (127.0.0.1) is back")
        assert "machine robot (127.0.0.1) is back" in workstation.log(), workstation.log()
        deadline = workstation.deadline(30)
        resumed: list[tuple[float, str]] = []
        while not deadline.expired() and not any(reason != "fail-safe" for _, reason in resumed):
            resumed = read(0.5)
        assert any(reason != "fail-safe" for _, reason in resumed), resumed
    finally:
        for pid in robot_pids:
            if pid_alive(pid):
                os.kill(pid, signal.SIGCONT)
        ctx.destroy(linger=0)


INJECTION_GRAPH = """
[machines.a]
address = "127.0.0.1"
ports = [{first}, {last}]
keys = "{keys}/a"

[machines.b]
address = "127.0.0.2"
ports = [{first}, {last}]
keys = "{keys}/b"

[[node]]
name = "source"
type = "wrench_source"
params = {{rate_hz = 20.0}}

[[node]]
name = "relay"
type = "relay"
machine = "b"
"""


def test_topic_pub_on_one_machine_reaches_a_node_on_the_other_and_both_launchers_publish_their_offsets(tmp_path):
    keys, stranger = tmp_path / "keys", tmp_path / "stranger"
    for directory in (keys, stranger):
        subprocess.run([sys.executable, "-m", "slipstack.launch.cli", "keys", str(directory), "--machine", "a",
                        "--machine", "b"], check=True, capture_output=True, timeout=60)
    first = free_port_block(10, (ROBOT, WORKSTATION))
    launch_file = tmp_path / "inject.toml"
    launch_file.write_text(INJECTION_GRAPH.format(first=first, last=first + 9, keys=keys))
    roots = [tempfile.TemporaryDirectory(prefix="ss-", dir="/tmp") for _ in range(2)]
    a, b = (LaunchedGraph([str(launch_file), "--machine", m], Path(r.name)) for m, r in zip("ab", roots))
    ctx = zmq.Context()
    try:
        graph_a = a.wait_ready(timeout=90)
        relay_pub = b.wait_ready(timeout=90)["nodes"]["relay"]["pub"]
        assert graph_a["nodes"]["relay"]["inject"] == {"ft/wrench": f"tcp://127.0.0.2:{first + 9}"}
        relayed = ctx.socket(zmq.SUB)  # what the relay on b republishes (its ipc endpoint, on b)
        relayed.setsockopt(zmq.SUBSCRIBE, b"ft/relayed")
        relayed.connect(relay_pub)
        time.sleep(0.5)  # the test's own subscription (slow joiner)

        def injected(count: int, seconds: float) -> dict[float, list[int]]:
            """Force z → stamps of the relayed wrenches not from the source (z 10 N), until ``count``
            of them or ``seconds``."""
            got: dict[float, list[int]] = {}
            end = time.monotonic() + seconds
            while time.monotonic() < end and sum(map(len, got.values())) < count:
                if relayed.poll(100):
                    msg = decode(relayed.recv_multipart()[1])
                    if msg.force[2] != 10.0:
                        got.setdefault(float(msg.force[2]), []).append(msg.header.stamp_ns)
            return got

        # a peer holding keys the graph does not know: no subscription comes back, nothing gets in
        intruder = _curve_client(ctx, zmq.XPUB, stranger / "a" / "a.key_secret", keys / "a" / "b.key")
        intruder.connect(f"tcp://127.0.0.2:{first + 9}")
        assert not intruder.poll(2000)
        for k in range(20):
            wrench = Wrench(force=np.array([0.0, 0.0, -3.5]), torque=np.zeros(3))
            now = time.monotonic_ns()
            intruder.send_multipart([b"ft/wrench", encode(wrench, Header(now, k, now, {})), b"intruder"])
        sent_at = time.monotonic_ns()
        pub = a.cli("topic", "pub", "ft/wrench", "{force: [0.0, 0.0, -7.25]}", "--times", "20", "--rate", "50",
                    "--wait", "30", timeout=90)
        assert pub.returncode == 0 and "joined" not in pub.stderr, pub.stderr
        got = injected(20, 30.0)
        # topic pub's frames reach b's relay, none of the intruder's. Injection is best-effort pub/sub
        # through two relays with budgets (docs/safety.md): 19 of 20 arrived at load 1, 9 of 20 at
        # load 17, so the test asks that they arrive, not that all do
        assert list(got) == [-7.25] and 1 <= len(got[-7.25]) <= 20, got
        assert all(sent_at <= s <= time.monotonic_ns() for s in got[-7.25])  # on a's clock: the graph's time base

        # each launcher's clock offsets on diagnostics: b's as a tool on a sees them (tcp, a's keys)
        offsets = _curve_client(ctx, zmq.SUB, keys / "a" / "a.key_secret", keys / "a" / "b.key")
        offsets.setsockopt(zmq.SUBSCRIBE, b"diagnostics")
        offsets.connect(graph_a["nodes"]["launcher@b"]["pub"])
        assert offsets.poll(30_000), "no diagnostics from b's launcher"
        report = decode(offsets.recv_multipart()[1])
        assert report.node == "launcher@b" and report.status.startswith("ok: clock of a "), report
        assert abs(report.counters["clock.a.offset_ns"] - report.counters["clock.time_base_offset_ns"]) < 50e6
        assert 0 < report.counters["clock.a.uncertainty_ns"] < 50e6  # one computer: both clocks are one
    finally:
        ctx.destroy(linger=0)
        for g in (a, b):
            g.stop()
        for r in roots:
            r.cleanup()
