"""A graph over several machines: placement, endpoints every launcher computes alike,
per-machine CURVE keys, refusals with what to do, the clock offset and time base.

The sockets here are real (tcp on 127.0.0.1, ipc in a temporary directory); the
launchers of tests/e2e/test_two_machines.py run the whole graph over two addresses.
"""

from __future__ import annotations

import json
import os
import signal
import threading
import time
from pathlib import Path

import msgpack
import pytest
import zmq
import zmq.auth

from free_ports import free_port, free_port_block

from slipstack.launch.launch_file import load_launch_file
from slipstack.launch import launcher as launcher_module
from slipstack.launch import peers as peers_module
from slipstack.launch.launcher import Launcher
from slipstack.launch.plan import plan_launch, remote_sources
from slipstack.lib.clock_offset import ClockOffset
from slipstack.lib.errors import ConfigError
from slipstack.nodes.runtime import curve
from slipstack.nodes.runtime.time_base import CLOCK_OFFSET_ENV, graph_clock
from slipstack.nodes.runtime.transport import make_pub, make_sub

BUILTINS = {"run_dir": "/tmp/slipstack-test"}
FIRST = free_port_block(100, ("127.0.0.1", "127.0.0.2"))
"""Both machines' first port (machine a holds 5, b 100), free when this module loads."""
GRAPH = """
[launch]
{launch}

[machines.a]
address = "{a}"
ports = [{first}, {last_a}]
{a_keys}

[machines.b]
address = "127.0.0.2"
ports = [{first}, {last_b}]
{b_keys}

[[node]]
name = "source"
type = "wrench_source"
{source}

[[node]]
name = "relay"
type = "relay"
machine = "b"
{relay}

[[node]]
name = "sink"
type = "sink"
machine = "b"
"""


def _load(tmp_path: Path, *, launch: str = "", a: str = "127.0.0.1", a_keys: str = 'keys = "keys/a"',
          b_keys: str = 'keys = "keys/b"', source: str = "", relay: str = "", extra: str = ""):
    path = tmp_path / "two.toml"
    path.write_text(GRAPH.format(launch=launch, a=a, a_keys=a_keys, b_keys=b_keys, source=source, relay=relay,
                                 first=FIRST, last_a=FIRST + 4, last_b=FIRST + 99) + extra)
    return load_launch_file(str(path), builtins=BUILTINS)


@pytest.fixture
def keys(tmp_path):
    return curve.make_machine_keys(tmp_path / "keys", ["a", "b"])


def test_nodes_are_placed_by_their_key_by_the_machines_nodes_list_or_on_the_first(tmp_path, keys):
    lf = _load(tmp_path)
    assert {e.name: e.machine for e in lf.nodes} == {"source": "a", "relay": "b", "sink": "b"}
    shipped = load_launch_file("two_hosts", builtins=BUILTINS)
    placed = {e.name: e.machine for e in shipped.nodes}
    assert placed["rig"] == placed["ft_driver"] == placed["tactile_driver"] == "robot"
    assert placed["grip_controller"] == placed["fusion"] == placed["monitor"] == "workstation"


def test_both_launchers_compute_the_same_endpoints_ipc_inside_a_machine_tcp_between(tmp_path, keys):
    lf = _load(tmp_path)
    specs = {}
    for machine in ("a", "b"):
        run_dir = tmp_path / machine
        run_dir.mkdir(mode=0o700)
        launcher = Launcher(lf, run_dir, machine=machine, echo=lambda line: None)
        launcher.control.close(linger=0)
        specs[machine] = {p.name: json.loads(p.read_text()) for p in run_dir.glob("*.spec.json")}
    assert set(specs["a"]) == {"source.spec.json"} and set(specs["b"]) == {"relay.spec.json", "sink.spec.json"}
    source = specs["a"]["source.spec.json"]
    relay, sink = specs["b"]["relay.spec.json"], specs["b"]["sink.spec.json"]
    # the port of a node: its machine's first port (the launcher's) + 1 + its rank by name
    assert source["pub"].startswith("ipc://") and source["pub_remote"] == f"tcp://127.0.0.1:{FIRST + 1}"
    assert relay["pub_remote"] == f"tcp://127.0.0.2:{FIRST + 1}" and sink["pub_remote"] == f"tcp://127.0.0.2:{FIRST + 2}"
    assert relay["subs"]["ft/wrench"] == [f"tcp://127.0.0.1:{FIRST + 1}"]  # from the other machine: tcp
    assert sink["subs"]["ft/relayed"] == [relay["pub"]] and relay["pub"].startswith("ipc://")  # same machine: ipc
    assert source["expected_subscribers"] == {"ft/wrench": 1}  # the relay on b is waited for,
    assert source["handshake_timeout_s"] == launcher_module.PEER_WAIT_S  # as long as b's launcher may take
    assert "handshake_timeout_s" not in relay  # its subscriber is on its own machine


def test_each_machine_knows_which_other_machine_its_topics_come_from(tmp_path, keys):
    lf = _load(tmp_path)
    assert remote_sources(plan_launch(lf, tmp_path, "b")) == {  # followed upstream: the relay's output too
        "ft/wrench": "machine a, 127.0.0.1", "ft/relayed": "machine a, 127.0.0.1"}
    assert remote_sources(plan_launch(lf, tmp_path, "a")) == {"ft/relayed": "machine b, 127.0.0.2"}  # a's own left out
    assert remote_sources(plan_launch(lf, tmp_path)) == {}  # one computer
    shipped = load_launch_file("two_hosts", builtins=BUILTINS)
    workstation = remote_sources(plan_launch(shipped, tmp_path, "workstation"))
    assert workstation["slip"] == workstation["ft/wrench"] == "machine robot, 127.0.0.1"
    assert "diagnostics" not in workstation
    assert remote_sources(plan_launch(shipped, tmp_path, "robot"))["grip/command"] == "machine workstation, 127.0.0.2"


@pytest.mark.parametrize("change, message", [
    ({"a": "10.0.0.2", "a_keys": "", "b_keys": ""}, r"machines \['a'\] are on the network without keys: run "
                                                    r"`slipstack keys DIR --machine a --machine b`"),
    ({"a_keys": "", "b_keys": ""}, r"link over tcp without keys.*or insecure = true"),
    ({"extra": '[[node]]\nname = "x"\ntype = "sink"\nmachine = "c"\n'}, r"node x: no \[machines.c\]; machines: a, b"),
    ({"extra": '[[node]]\nname = "x"\ntype = "sink"\n[[node]]\nname = "y"\ntype = "sink"\n'},
     rf"\[machines.a\].ports \[{FIRST}, {FIRST + 4}\] holds 5 ports; it needs 6"),
    ({"relay": 'container = "box"', "extra": '[[node]]\nname = "z"\ntype = "sink"\ncontainer = "box"\n'},
     r"share container 'box' but differ in .*machine"),
], ids=["no-keys-off-loopback", "tcp-without-keys", "unknown-machine", "too-few-ports", "container-across-machines"])
def test_bad_machine_tables_are_refused_with_what_to_do(tmp_path, change, message):
    with pytest.raises(ConfigError, match=message):
        _load(tmp_path, **change)


@pytest.mark.parametrize("source, waits_for", [
    ('after = ["relay"]', "relay"),
    # the simulated world (stop_first) waits for every node elsewhere: with the control path on
    # another machine still starting, the rig had run its scene uncontrolled (issue 29)
    ("stop_first = true", "relay, sink"),
])
def test_a_node_that_waits_for_a_machine_that_is_not_up_names_the_machine(tmp_path, keys, monkeypatch, source,
                                                                           waits_for):
    monkeypatch.setattr(launcher_module, "PEER_WAIT_S", 1.0)
    lines: list[str] = []
    run_dir = tmp_path / "run"
    run_dir.mkdir(mode=0o700)
    launcher = Launcher(_load(tmp_path, source=source), run_dir, machine="a", echo=lines.append)
    try:
        assert launcher.run() == 1
    finally:
        curve.use_keys(None)  # the launcher took machine a's keys for its own links
    assert any(f"node source (wrench_source) starts after {waits_for} on machine b (127.0.0.2), not ready after 1 s: "
               "is `slipstack launch two.toml --machine b` running there?" in line for line in lines), lines


def test_launch_keys_name_the_directory_of_every_machines_key_directory(tmp_path, keys):
    lf = _load(tmp_path, launch='keys = "keys"', a_keys="", b_keys="")
    assert lf.machines["a"].keys == keys[0].resolve() and lf.machines["b"].keys == keys[1].resolve()


def test_insecure_is_an_explicit_opt_in_for_a_network_address(tmp_path):
    lf = _load(tmp_path, launch="insecure = true", a="10.0.0.2", a_keys="", b_keys="")
    assert lf.insecure and lf.machines["a"].keys is None


def test_the_machine_to_run_must_be_named_and_known(tmp_path, keys):
    lf = _load(tmp_path)
    for machine, message in ((None, r"run `slipstack launch two.toml --machine NAME` on each of them, NAME one of: "
                                    r"a, b"), ("c", r"no machine 'c'")):
        with pytest.raises(ConfigError, match=message):
            Launcher(lf, tmp_path, machine=machine, echo=lambda line: None)


def test_a_machine_admits_the_graphs_machines_and_no_stranger_while_ipc_stays_plain(tmp_path, keys):
    stranger = curve.make_machine_keys(tmp_path / "stranger", ["b"])[0]  # a key pair named b, not the graph's
    (stranger / "a.key").write_bytes((keys[0] / "a.key").read_bytes())  # a's public key is no secret
    hosts = {"127.0.0.1": "a"}
    ctx = zmq.Context()
    try:
        curve.use_keys(keys[0], "a", hosts)
        port = free_port()
        pub = make_pub(ctx, f"ipc://{tmp_path}/a.pub", remote=f"tcp://127.0.0.1:{port}")
        plain_ipc = make_sub(ctx, [f"ipc://{tmp_path}/a.pub"], None)  # ipc: no CURVE on that endpoint
        curve.use_keys(keys[1], "b", hosts)
        member = make_sub(ctx, [f"tcp://127.0.0.1:{port}"], None)
        curve.use_keys(stranger, "b", hosts)
        outsider = make_sub(ctx, [f"tcp://127.0.0.1:{port}"], None)
        time.sleep(0.3)
        end = time.monotonic() + 1.5
        counts = {"ipc": 0, "member": 0, "outsider": 0}
        while time.monotonic() < end:
            pub.send_multipart([b"t", b"x"])
            for name, sock in (("ipc", plain_ipc), ("member", member), ("outsider", outsider)):
                while sock.poll(0):
                    sock.recv_multipart()
                    counts[name] += 1
            time.sleep(0.005)
        assert counts["ipc"] > 20 and counts["member"] > 20 and counts["outsider"] == 0, counts
    finally:
        curve.use_keys(None)
        ctx.destroy(linger=0)


def test_one_subscriber_of_publishers_on_both_machines_hears_them_all(tmp_path, keys):
    """The recorder on machine b taps the graph with one SUB: the tcp publishers of a (CURVE)
    and the ipc publishers of b (plain), connected in graph.json's order, whichever comes first."""
    hosts = {"127.0.0.1": "a"}
    ctx = zmq.Context()
    try:
        curve.use_keys(keys[0], "a", hosts)
        remote = make_pub(ctx, f"ipc://{tmp_path}/a.pub", remote=f"tcp://127.0.0.1:{free_port()}")
        curve.use_keys(keys[1], "b", hosts)
        local = [make_pub(ctx, f"ipc://{tmp_path}/b{k}.pub") for k in range(2)]
        tcp = remote.getsockopt(zmq.LAST_ENDPOINT).decode()
        tap = make_sub(ctx, [f"ipc://{tmp_path}/b0.pub", tcp, f"ipc://{tmp_path}/b1.pub"], None)
        heard: set[bytes] = set()
        end = time.monotonic() + 10.0
        while time.monotonic() < end and len(heard) < 3:
            for name, pub in ((b"a", remote), (b"b0", local[0]), (b"b1", local[1])):
                pub.send_multipart([b"t", name])
            while tap.poll(5):
                heard.add(tap.recv_multipart()[1])
        assert heard == {b"a", b"b0", b"b1"}
    finally:
        curve.use_keys(None)
        ctx.destroy(linger=0)


def test_a_machine_without_the_peers_public_key_says_where_to_copy_it(tmp_path, keys):
    (keys[0] / "b.key").unlink()
    with pytest.raises(ConfigError, match=r"no public key of machine b \(b.key\): copy it there"):
        curve.GraphKeys.load(keys[0], "a", {"127.0.0.2": "b"})


def test_clock_offset_recovers_a_known_offset_through_asymmetric_delays():
    est = ClockOffset(window=64)
    offset = 5_000_000_000  # their clock is 5 s ahead
    for k in range(64):
        t1 = k * 10_000_000
        out, back = 100_000 + (k % 7) * 300_000, 100_000 + (k % 5) * 200_000  # loaded scheduler: uneven
        t2 = t1 + out + offset
        t3 = t2 + 20_000
        t4 = t3 - offset + back
        assert est.add(t1, t2, t3, t4)
    e = est.estimate()
    assert abs(e.offset_ns - offset) <= e.uncertainty_ns <= 2_000_000 and e.samples == 64
    assert not est.add(100, 50, 60, 90)  # a reply from before the ping: impossible, ignored
    assert ClockOffset().estimate() is None


def test_graph_clock_is_shifted_by_the_launchers_offset(monkeypatch):
    monkeypatch.delenv(CLOCK_OFFSET_ENV, raising=False)
    assert graph_clock() is time.monotonic_ns
    monkeypatch.setenv(CLOCK_OFFSET_ENV, str(3_600 * 10**9))
    assert abs(graph_clock()() - time.monotonic_ns() - 3_600 * 10**9) < 10**8
    monkeypatch.setenv(CLOCK_OFFSET_ENV, "soon")
    with pytest.raises(ConfigError, match="must be an integer number of nanoseconds"):
        graph_clock()


def test_the_monitor_summary_says_the_launchers_clock_offsets():
    from slipstack.launch.clock_report import clock_counters, clock_status
    from slipstack.lib.clock_offset import OffsetEstimate
    from slipstack.messages import Diagnostics, Header
    from slipstack.nodes.monitor import Monitor, format_summary, summarise
    from slipstack.nodes.runtime.inprocess import InProcessExecutor

    estimates = {"robot": OffsetEstimate(12_345_000, 50_000, 40)}
    report = Diagnostics(node="launcher@workstation", status=clock_status(estimates),
                         counters=clock_counters(estimates, 12_300_000), header=Header(1_000_000, 0, 1_000_000, {}))
    assert report.status == "ok: clock of robot +12.345 ms ± 0.050 ms"
    monitor = Monitor()
    ex = InProcessExecutor([monitor])
    ex.feed([(1_000_000, "diagnostics", report)])
    ex.run(until_ns=2_000_000)
    summary = summarise(monitor, 2_000_000)
    assert summary["clock_offsets"] == {"launcher@workstation": {"robot": {"offset_ms": 12.345, "uncertainty_ms": 0.05}}}
    assert ("clock offsets between the machines (their clock minus the launcher's): launcher@workstation: robot "
            "+12.345 ms ± 0.050 ms") in format_summary(summary, verbose=True)
    assert "clocks: robot +12.345 ms ± 0.050 (other machines' minus ours)" in format_summary(summary)


class _StandInPeer(threading.Thread):
    """Machine a's launcher as machine b's sees it: a real CURVE ROUTER at a's launcher endpoint
    answering the peers protocol (launch/peers.py), its clock ``shift_ns`` ahead of ours from the
    ``shift_after``-th ping on (a clock that jumped or drifted)."""

    def __init__(self, endpoint: str, secret_file: Path, shift_ns: int, shift_after: int) -> None:
        super().__init__(daemon=True)
        self.ctx = zmq.Context()
        self.sock = self.ctx.socket(zmq.ROUTER)
        self.sock.setsockopt(zmq.LINGER, 0)
        self.sock.curve_publickey, self.sock.curve_secretkey = zmq.auth.load_certificate(secret_file)
        self.sock.curve_server = True
        self.sock.bind(endpoint)
        self.shift_ns, self.shift_after, self.pings = shift_ns, shift_after, 0
        self.done = threading.Event()
        self.start()

    def run(self) -> None:
        status = msgpack.packb({"machine": "a", "state": "running", "ready": []})
        while not self.done.is_set():
            if not self.sock.poll(50):
                continue
            ident, kind, t1, *_ = self.sock.recv_multipart()
            if kind != b"ping":
                continue
            self.pings += 1
            shift = self.shift_ns if self.pings > self.shift_after else 0
            t2 = (time.monotonic_ns() + shift).to_bytes(8, "big", signed=True)
            self.sock.send_multipart([ident, b"pong", t1, t2, t2, status])

    def close(self) -> None:
        self.done.set()
        self.join(5)
        self.ctx.destroy(linger=0)


DRIFT_GRAPH = """
[machines.a]
address = "127.0.0.1"
ports = [{first}, {last}]
keys = "keys/a"

[machines.b]
address = "127.0.0.2"
ports = [{first}, {last}]
keys = "keys/b"

[[node]]
name = "grip_controller"
type = "grip_controller"
machine = "a"
params = {{timeout_ms = 20.0}}
"""


@pytest.mark.parametrize("shift_ms, warned", [(15, True), (0, False)])  # half the timeout: 10 ms
def test_the_launcher_warns_when_the_clock_offset_drifts_beyond_half_the_controllers_timeout(
        tmp_path, keys, monkeypatch, shift_ms, warned):
    monkeypatch.setattr(peers_module, "PING_PERIOD_S", 0.01)  # the estimate's window fills in a second
    monkeypatch.setattr(launcher_module, "DRIFT_CHECK_S", 0.1)
    first = free_port_block(10)
    path = tmp_path / "drift.toml"
    path.write_text(DRIFT_GRAPH.format(first=first, last=first + 9))
    lf = load_launch_file(str(path), builtins=BUILTINS)
    lf.duration_s = 4.0 if not warned else 30.0  # a bound: the warning stops the launch at once
    peer = _StandInPeer(f"tcp://127.0.0.1:{first}", tmp_path / "keys" / "a" / "a.key_secret",
                        shift_ms * 1_000_000, shift_after=30)
    lines: list[str] = []

    def echo(line: str) -> None:
        lines.append(line)
        if "drifted" in line:
            os.kill(os.getpid(), signal.SIGINT)  # the launcher stops as on Ctrl-C

    run_dir = tmp_path / "run"
    run_dir.mkdir(mode=0o700)
    try:
        Launcher(lf, run_dir, machine="b", echo=echo).run()
    finally:
        curve.use_keys(None)
        peer.close()
    drift = [line for line in lines if "drifted" in line]
    if warned:
        assert drift and drift[0].startswith("[launch] WARNING: this machine's clock drifted ") and (
            "more than half the grip controller's 20 ms timeout" in drift[0]), lines
    else:
        assert not drift and any("clock of machine a is" in line for line in lines), lines
