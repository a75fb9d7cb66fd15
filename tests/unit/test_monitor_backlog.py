"""A monitor that fell behind its inputs: at stop it judges what was delivered to its sockets
(real ZeroMQ sockets, the process executor), and what the graph published that it never saw
the summary says, and the check does not pass."""

from __future__ import annotations

import json
import time

import zmq

from slipstack.messages import Diagnostics, GripCommand, Header, RigTruth, encode
from slipstack.nodes.monitor import Monitor, MonitorParams
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from slipstack.nodes.runtime.process import ProcessExecutor, RunSpec
from slipstack.nodes.runtime.transport import make_pub

MS = 1_000_000
COMMANDS, TRUTH = 3000, 1500  # 6 s of the stack's 500 Hz commands and 250 Hz truth: past ZeroMQ's default HWM


def _command(k: int) -> bytes:
    return encode(GripCommand(f_n_desired=3.0, reason="nominal", header=Header(2 * k * MS, k, 2 * k * MS + MS, {})))


def _truth(k: int, slid_m: float = 0.0) -> RigTruth:
    return RigTruth(f_n_applied=3.0, slip_distance_m=slid_m, header=Header(4 * k * MS, k, 4 * k * MS, {}))


def _published(node: str, t_ns: int, topic: str, n: int) -> Diagnostics:
    return Diagnostics(node=node, counters={f"out.{topic}.published": float(n)}, header=Header(t_ns, 0, t_ns, {}))


def test_the_backlog_in_its_sockets_is_judged_before_the_summary(tmp_path):
    """The graph stopped while the monitor was seconds behind: every frame already in its sockets
    counts in the summary (it summed up before reading them: 0 of 3000 commands)."""
    ctx = zmq.Context.instance()
    endpoint = f"ipc://{tmp_path}/graph.pub"
    pub = make_pub(ctx, endpoint, sndhwm=20_000)
    spec = RunSpec(name="monitor", subs={t: [endpoint] for t in ("grip/command", "rig/truth", "diagnostics")})
    summary = tmp_path / "summary.json"
    check = tmp_path / "check.json"
    ex = ProcessExecutor([(Monitor(MonitorParams(summary_path=str(summary), check_path=str(check))), spec)])
    deadline = time.monotonic() + 10
    subscribed = 0
    while subscribed < 3 and time.monotonic() < deadline:  # the three subscriptions reached the publisher
        if pub.poll(100):
            subscribed += pub.recv()[:1] == b"\x01"
    for k in range(COMMANDS):
        pub.send_multipart([b"grip/command", _command(k)])
    for k in range(TRUTH):
        pub.send_multipart([b"rig/truth", encode(_truth(k, slid_m=2e-3 if k == TRUTH - 1 else 0.0))])
    pub.send_multipart([b"diagnostics", encode(_published("control", 1, "grip/command", COMMANDS))])
    pub.send_multipart([b"diagnostics", encode(_published("rig", 1, "rig/truth", TRUTH))])
    ex._stopping = True  # stopped before its loop read anything: all of it still waits in the sockets
    try:
        assert ex.run() == 0
    finally:
        pub.close(linger=0)
    s = json.loads(summary.read_text())
    assert s["grip_commands"] == COMMANDS
    assert s["slip_distance_mm"] == 2.0  # the last truth frame: the object slid, and the check sees it
    assert s["monitor_unseen"] == {}
    verdict = json.loads(check.read_text())
    assert not verdict["passed"] and verdict["short"] == ["object slid 2.00 mm (allowed 0.5)"]


def test_what_it_never_saw_is_said_and_fails_the_check(tmp_path):
    """Frames dropped before they reached the monitor (1000 commands in the middle, the last 500
    truth frames: its queue overflowed while it stalled) are counted against what the publishers
    said they published; the run is not passed (it was, with "no frame lost")."""
    events = [(2 * k * MS, "grip/command", GripCommand(f_n_desired=3.0, reason="nominal",
                                                       header=Header(2 * k * MS, k, 2 * k * MS + MS, {})))
              for k in range(COMMANDS) if not 1000 <= k < 2000]
    events += [(4 * k * MS, "rig/truth", _truth(k)) for k in range(TRUTH - 500)]
    end = 4 * TRUTH * MS
    events += [(end, "diagnostics", _published("control", end, "grip/command", COMMANDS)),
               (end, "diagnostics", _published("rig", end, "rig/truth", TRUTH))]
    summary, check = tmp_path / "summary.json", tmp_path / "check.json"
    monitor = Monitor(MonitorParams(summary_path=str(summary), check_path=str(check)))
    ex = InProcessExecutor([monitor])
    ex.feed(events)
    ex.run()
    ex.stop()
    s = json.loads(summary.read_text())
    unseen = s["monitor_unseen"]
    assert (unseen["grip"]["unseen"], unseen["grip"]["published"]) == (1000, COMMANDS)
    assert (unseen["truth"]["unseen"], unseen["truth"]["published"]) == (500, TRUTH) and unseen["truth"]["tail_unseen"]
    assert abs(unseen["truth"]["seen_up_to_s"] - 3.996) < 1e-6 and abs(unseen["truth"]["published_up_to_s"] - 5.996) < 1e-6
    verdict = json.loads(check.read_text())
    assert not verdict["passed"]
    assert verdict["short"] == ["monitor saw truth up to 4.0 s of 6.0 s: not judged to the end"]
    shown = [line.split("] ", 1)[1] for line in ex.logs if "detail:" not in line]
    assert "bus: 1500 frames lost; every sensor sample examined" in shown, shown  # the long form names the monitor
    assert "HEALTH: monitor saw truth up to 4.0 s of 6.0 s: not judged to the end" in shown
