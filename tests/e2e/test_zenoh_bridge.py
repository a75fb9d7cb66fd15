"""The ``zenoh_bridge`` node in a launched stack against a Zenoh peer, as a ROS 2 node's rmw_zenoh
session would be one (eclipse-zenoh; docs/ros2.md): it finds slipstack's topics by their
liveliness tokens and keys, decodes them with mcap-ros2-support's CDR decoder (not the bridge's),
and publishes the WrenchStamped that drive the graph, garbage and floods among them.

The bridge is off by default (``zenoh:=true`` turns it on). Each test's peer listens on loopback
on a port free at that moment, the bridge connects to it, and both have multicast and gossip
scouting off: no router, nothing that reaches another test run.
"""

from __future__ import annotations

import socket
import struct
import threading
import time
from importlib import resources
from pathlib import Path

import numpy as np
import pytest

zenoh = pytest.importorskip("zenoh", reason="the ros2 extra is not installed")

from mcap_ros2._dynamic import generate_dynamic  # noqa: E402
from rosbags.typesys import Stores, get_types_from_msg, get_typestore  # noqa: E402

from slipstack.messages import decode  # noqa: E402
from slipstack.nodes.recording.bag_io import read_recording  # noqa: E402

pytestmark = pytest.mark.e2e

SLIP, WRENCH, COMMAND = "slipstack_msgs/msg/Slip", "geometry_msgs/msg/WrenchStamped", "std_msgs/msg/Float64MultiArray"


def _store():
    """rosbags' types with slipstack_msgs from the shipped .msg files: hashes and definitions
    computed here, not taken from the bridge."""
    store = get_typestore(Stores.ROS2_JAZZY)
    folder = resources.files("slipstack.messages.ros2") / "slipstack_msgs" / "msg"
    types = {}
    for f in folder.iterdir():
        if f.name.endswith(".msg"):
            types.update(get_types_from_msg(f.read_text(), f"slipstack_msgs/msg/{f.name[:-4]}"))
    store.register(types)
    return store


STORE = _store()


def _key(topic: str, ros_type: str) -> str:  # rmw_zenoh docs/design.md: <domain>/<name>/<dds type>/<hash>
    package, _, name = ros_type.split("/")
    return f"0/{topic.strip('/')}/{package}::msg::dds_::{name}_/{STORE.hash_rihs01(ros_type)}"


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _peer(port: int):
    config = zenoh.Config()
    for key, value in (("mode", '"peer"'), ("listen/endpoints", f'["tcp/127.0.0.1:{port}"]'),
                       ("connect/endpoints", "[]"), ("scouting/multicast/enabled", "false"),
                       ("scouting/gossip/enabled", "false")):
        config.insert_json5(key, value)
    return zenoh.open(config)


def _bridge_args(port: int, rec: Path, *extra: str) -> list[str]:
    return ["stack.toml", "zenoh:=true", f"zenoh_connect:=tcp/127.0.0.1:{port}", "zenoh_listen:=",
            f"recording:={rec}", "monitor:=false", *extra]


def _attachment(raw: bytes) -> tuple[int, int, bytes]:
    seq, source_ns, n = struct.unpack_from("<qqB", raw)  # design.md: int64 LE, int64 LE, GID length, GID
    assert len(raw) == 17 + n == 33
    return seq, source_ns, raw[17:]


def test_a_ros2_peer_sees_every_slip_at_1khz_on_rmw_zenohs_keys(launch, tmp_path: Path) -> None:
    port = _free_port()
    peer = _peer(port)
    got: list[tuple[bytes, bytes]] = []
    lock = threading.Lock()

    def on_slip(sample) -> None:
        with lock:
            got.append((sample.payload.to_bytes(), sample.attachment.to_bytes()))

    sub = peer.declare_subscriber(_key("/slipstack/slip", SLIP), on_slip)
    tokens: list[str] = []
    watch = peer.liveliness().declare_subscriber("@ros2_lv/0/**", lambda s: tokens.append(str(s.key_expr)))
    rec = tmp_path / "run.mcap"
    # slip only (the default adds grip/command): the peer listens to slip, and the bridge then keeps
    # up on a machine as loaded as this one (load 10 on 2 cores) at half the work
    graph = launch(*_bridge_args(port, rec, "ft_rate_hz:=1000", "duration_s:=4", "zenoh_publish:=slip"))
    graph.wait_ready()
    assert graph.proc.wait(90) == 0, graph.log()
    time.sleep(0.5)  # the last samples in flight
    sub.undeclare()
    watch.undeclare()
    peer.close()

    decode_slip = generate_dynamic(SLIP, STORE.generate_msgdef(SLIP, ros_version=2)[0])[SLIP]
    recorded = {m.header.seq: m for m in (decode(f.payload) for f in read_recording(rec, ["slip"]))}
    assert len(recorded) > 2500, "the stack ran its slip detector at about 1 kHz for 4 s"
    seqs, received = [], set()
    for payload, raw in got:
        slip = decode_slip(payload)
        received.add(slip.trace.seq)
        seqs.append(_attachment(raw)[0])
        mine = recorded.get(slip.trace.seq)
        if mine is None:  # the last verdicts, after the recorder stopped
            continue
        assert (slip.state, slip.gamma, slip.margin, slip.method) == (mine.state, mine.gamma, mine.margin, mine.method)
        assert slip.header.stamp.sec * 10**9 + slip.header.stamp.nanosec == mine.header.stamp_ns
    assert not set(recorded) - received, f"{len(set(recorded) - received)} slips lost"
    assert len(received) == len(got) and len(got) - len(recorded) < 50
    assert seqs == list(range(1, len(got) + 1)), "rmw_zenoh's sequence numbers count from 1 without a gap"
    nodes = [t for t in tokens if "/NN/" in t]
    publishers = [t for t in tokens if "/MP/" in t and "%slipstack%slip/" in t]
    assert nodes and nodes[0].endswith("/NN/%/%slipstack/slipstack_bridge"), tokens
    assert publishers and publishers[0].endswith(
        f"/MP/%/%slipstack/slipstack_bridge/%slipstack%slip/slipstack_msgs::msg::dds_::Slip_/"
        f"{STORE.hash_rihs01(SLIP)}/::,10:,:,:,,"), tokens


def _wrench_cdr(fx: float, fz: float, frame_id: str = "pad", stamp_ns: int | None = None) -> bytes:
    t = STORE.types
    sec, nsec = divmod(time.time_ns() if stamp_ns is None else stamp_ns, 10**9)
    msg = t[WRENCH](header=t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
                                                     frame_id=frame_id),
                    wrench=t["geometry_msgs/msg/Wrench"](force=t["geometry_msgs/msg/Vector3"](x=fx, y=0.0, z=fz),
                                                         torque=t["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)))
    return bytes(STORE.serialize_cdr(msg, WRENCH))


def test_a_ros2_wrench_drives_the_graph_and_garbage_and_floods_are_counted(launch, tmp_path: Path) -> None:
    port = _free_port()
    peer = _peer(port)
    commands: list[float] = []
    decode_command = generate_dynamic(COMMAND, STORE.generate_msgdef(COMMAND, ros_version=2)[0])[COMMAND]
    sub = peer.declare_subscriber(_key("/gripper/commands", COMMAND),
                                  lambda s: commands.append(float(decode_command(s.payload.to_bytes()).data[0])))
    # BLOCK, as rmw_zenoh's RELIABLE + KEEP_ALL publisher: every sample reaches the bridge, so its
    # counts add up exactly however busy the machine is
    pub = peer.declare_publisher(_key("/ft_sensor/wrench", WRENCH), congestion_control=zenoh.CongestionControl.BLOCK)
    gid = bytes(range(16))
    sequence = iter(range(1, 1 << 30))

    def put(cdr: bytes, attach: bool = True) -> None:
        attachment = struct.pack("<qqB", next(sequence), time.time_ns(), 16) + gid if attach else None
        pub.put(cdr, attachment=attachment)

    rec = tmp_path / "run.mcap"
    # F/T from ROS 2: no F/T driver; an F/T-only slip test and grip law (stack.toml's note on tactile:=false)
    graph = launch(*_bridge_args(port, rec, "ft_driver:=false", "tactile:=false", "method:=coulomb", "law:=linear",
                                 "ros2_wrench_in:=/ft_sensor/wrench", "ros2_command_topic:=/gripper/commands",
                                 "duration_s:=6"))
    graph.wait_ready()
    time.sleep(1.0)
    sent = 0
    start = time.monotonic()
    while time.monotonic() - start < 2.0:  # 1 kHz: 5 N held, then a tangential load past friction
        t = time.monotonic() - start
        put(_wrench_cdr(fx=0.5 if t < 1.0 else 4.0, fz=-5.0))
        sent += 1
        time.sleep(max(0.0, start + sent / 1000 - time.monotonic()))
    garbage = [(b"\x00\x01\x00\x00" + bytes(40), True),  # CDR header, then nothing a WrenchStamped is made of
               (_wrench_cdr(1.0, -5.0, frame_id="ft_sensor_link"), True),  # not in the pad frame
               (_wrench_cdr(float("nan"), -5.0), True),
               (_wrench_cdr(1.0, -5.0, stamp_ns=time.time_ns() - 10**9), True),  # a second old
               (_wrench_cdr(1.0, -5.0), False)]  # without rmw_zenoh's attachment
    for cdr, attach in garbage:
        put(cdr, attach)
    put(bytes(8192))  # larger than max_bytes
    time.sleep(1.5)  # a diagnostics message between the garbage and the flood
    flood_ns = time.time_ns()
    for _ in range(5000):  # a flood: far above max_rate_hz
        put(_wrench_cdr(0.5, -5.0))
    assert graph.proc.wait(90) == 0, graph.log()
    sub.undeclare()
    peer.close()

    wrenches = [decode(f.payload) for f in read_recording(rec, ["ft/wrench"])]
    assert not any(w.frame != "pad" or not np.isfinite(w.force).all() for w in wrenches)
    bridge = [(f.log_time_ns, m.counters) for f in read_recording(rec, ["diagnostics"])
              if (m := decode(f.payload)).node == "zenoh_bridge"]
    topic = "ros2./ft_sensor/wrench"
    before_flood = [c for t, c in bridge if t < flood_ns][-1]
    assert before_flood[f"{topic}.received"] == sent + len(garbage) + 1, before_flood
    assert before_flood[f"{topic}.rejected"] >= len(garbage) and before_flood[f"{topic}.oversize"] == 1, before_flood
    assert before_flood["out.ft/wrench.published"] >= sent / 2, "most of the driver's samples drove the graph"
    last = bridge[-1][1]
    # (the run may end before the flood's tail is read: the last diagnostics count what was)
    assert before_flood[f"{topic}.received"] + 1000 < last[f"{topic}.received"] <= sent + len(garbage) + 1 + 5000
    assert last[f"{topic}.over_rate"] > 1000, last
    # every sample the bridge received went into the graph or was counted as refused
    assert last["out.ft/wrench.published"] + sum(last.get(f"{topic}.{k}", 0) for k in (
        "rejected", "oversize", "over_rate", "dropped")) == last[f"{topic}.received"], last
    assert len(wrenches) == last["out.ft/wrench.published"]
    assert commands and max(commands) > commands[0], "the controller raised the grip on the ROS 2 wrench's slip"
    slips = [decode(f.payload) for f in read_recording(rec, ["slip"])]
    assert any(s.state != "stick" for s in slips) and any(s.state == "stick" for s in slips)
