"""The ``zenoh_bridge`` node: slipstack's topics to ROS 2 over Zenoh, a ROS 2 F/T sensor in.

It speaks rmw_zenoh's layout (``lib/rmw_zenoh.py``): each chosen topic goes out as ROS 2 CDR
on ``<namespace>/<topic>`` (``messages/ros2``), ``grip/command`` also as the
``std_msgs/msg/Float64MultiArray`` a ros2_control forward command controller follows, and a
``geometry_msgs/msg/WrenchStamped`` topic comes in as ``ft/wrench``, bounded in size, rate and
age and validated like any input. Off by default; the ``ros2`` extra; docs/ros2.md.
"""

from __future__ import annotations

import json
import os
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from slipstack.lib import rmw_zenoh
from slipstack.lib.errors import ConfigError, DecodeError
from slipstack.messages import GripCommand, Message, Wrench, registry, validate
from slipstack.messages.ros2 import (INFO_SUFFIX, INFO_TYPES, INSTALL_HINT, PAD_FRAME_ID, ROS_TYPES, WRENCH_STAMPED,
                                     ros_topic, stamp_to_ns)
from slipstack.nodes.runtime.node import Context, Input, Node, Output
from slipstack.nodes.runtime.rate_limit import TokenBucket

__all__ = ["ZenohBridge", "ZenohBridgeParams", "COMMAND_TYPE"]

COMMAND_TYPE = "std_msgs/msg/Float64MultiArray"
"""What a ros2_control forward command controller (an effort controller on the finger) follows."""
_CLOCKS = ("system", "graph")
_LINGER_S = 0.2  # at stop, for the samples still in Zenoh's queues (as ZeroMQ's linger)
_TYPES_BY_TOPIC = {"ft/wrench": "slipstack/Wrench", "tactile/frame": "slipstack/TactileFrame",
                   "contact": "slipstack/Contact", "cor": "slipstack/Cor", "slip": "slipstack/Slip",
                   "grip/command": "slipstack/GripCommand", "grip/state": "slipstack/GripState",
                   "rig/truth": "slipstack/RigTruth",
                   "diagnostics": "slipstack/Diagnostics"}


@dataclass(frozen=True)
class ZenohBridgeParams:
    publish: list[str] = field(default_factory=lambda: ["slip", "grip/command"], metadata={
        "help": f"slipstack topics to publish to ROS 2 (of {', '.join(_TYPES_BY_TOPIC)})"})
    namespace: str = field(default="/slipstack", metadata={"help": "ROS 2 namespace of the published topics"})
    node_name: str = field(default="slipstack_bridge", metadata={"help": "the ROS 2 node name it announces"})
    domain_id: int = field(default=0, metadata={"help": "ROS_DOMAIN_ID"})
    command_topic: str = field(default="", metadata={
        "help": f"also publish grip/command's f_n (N) as {COMMAND_TYPE} here (a ros2_control forward "
                "command controller's ~/commands); empty: not"})
    wrench_in: str = field(default="", metadata={
        "help": f"a ROS 2 {WRENCH_STAMPED} topic (pad frame, frame_id 'pad') to publish as ft/wrench; empty: none"})
    in_clock: str = field(default="system", metadata={
        "help": "the incoming stamps' clock: system (wall time, ROS 2's default) or graph (this graph's time base)"})
    max_age_s: float = field(default=0.1, metadata={"help": "reject an incoming sample older or further ahead than this (s)"})
    max_rate_hz: float = field(default=2000.0, metadata={"help": "incoming samples per second at most (more: dropped)"})
    max_burst: int = field(default=200, metadata={"help": "incoming samples back to back at most"})
    max_bytes: int = field(default=4096, metadata={"help": "largest incoming sample (bytes; larger: rejected)"})
    depth: int = field(default=1000, metadata={"help": "incoming samples waiting at most (more: dropped)"})
    config: str = field(default="", metadata={
        "help": "a Zenoh JSON5 config file (TLS, access control, ...); the settings below go on top"})
    mode: str = field(default="peer", metadata={"help": "Zenoh mode: peer or client"})
    connect: list[str] = field(default_factory=lambda: ["tcp/localhost:7447"], metadata={
        "help": "endpoints to connect to (rmw_zenoh's router: tcp/localhost:7447)"})
    listen: list[str] = field(default_factory=lambda: ["tcp/localhost:0"], metadata={"help": "endpoints to listen on"})
    multicast_scouting: bool = field(default=False, metadata={"help": "UDP multicast discovery (rmw_zenoh: off)"})
    gossip_scouting: bool = field(default=True, metadata={"help": "discovery through the router (rmw_zenoh: on)"})
    queue_depth: int = field(default=10, metadata={"help": "the KEEP_LAST depth the publishers announce"})


class _Inbox:
    """Samples from Zenoh's thread to the node's loop: a bounded queue and a pipe that wakes it.

    The Zenoh callback judges size and rate (cheap, before anything is copied); the rest is the
    node's, in its own thread."""

    def __init__(self, p: ZenohBridgeParams) -> None:
        self._read, self._write = os.pipe()
        os.set_blocking(self._read, False)
        os.set_blocking(self._write, False)
        self.queue: deque[tuple[bytes, bytes | None]] = deque()
        self._depth = p.depth
        self._max_bytes = p.max_bytes
        self._bucket = TokenBucket(p.max_rate_hz, p.max_burst)
        self._signalled = threading.Event()
        self.counts = {"received": 0, "oversize": 0, "over_rate": 0, "dropped": 0}  # written by Zenoh's thread only

    def fileno(self) -> int:
        return self._read

    def on_sample(self, sample: Any) -> None:
        self.counts["received"] += 1
        self._bucket.refill(time.monotonic_ns())
        if not self._bucket.take():
            self.counts["over_rate"] += 1
        elif len(sample.payload) > self._max_bytes:
            self.counts["oversize"] += 1
        elif len(self.queue) >= self._depth:
            self.counts["dropped"] += 1
        else:
            attachment = sample.attachment
            self.queue.append((sample.payload.to_bytes(), None if attachment is None else attachment.to_bytes()))
        if not self._signalled.is_set():  # the loop reports the counts too
            self._signalled.set()
            try:
                os.write(self._write, b"\0")
            except BlockingIOError:  # the pipe is full of wake-ups: the loop is awake anyway
                pass

    def take(self) -> list[tuple[bytes, bytes | None]]:
        """Every queued sample, oldest first (and the wake-up consumed).

        The pipe is drained before the flag is cleared, and the queue emptied after: a sample
        queued later finds the flag clear and wakes the loop again."""
        try:
            while os.read(self._read, 4096):
                pass
        except BlockingIOError:
            pass
        self._signalled.clear()
        out = []
        while self.queue:
            out.append(self.queue.popleft())
        return out

    def close(self) -> None:
        os.close(self._read)
        os.close(self._write)


class ZenohBridge(Node):
    """Publishes chosen topics to ROS 2 (rmw_zenoh's layout) and brings a ROS 2 wrench in."""

    name = "zenoh_bridge"
    Params = ZenohBridgeParams

    def __init__(self, params: ZenohBridgeParams | None = None) -> None:
        super().__init__(params)
        p = self.params
        unknown = sorted(set(p.publish) - set(_TYPES_BY_TOPIC))
        if unknown:
            raise ConfigError(f"zenoh_bridge: cannot publish {', '.join(unknown)}; publish takes "
                              f"{', '.join(_TYPES_BY_TOPIC)}")
        for label, name in (("namespace", p.namespace), ("wrench_in", p.wrench_in), ("command_topic", p.command_topic)):
            if name and not rmw_zenoh.valid_ros_name(name):
                raise ConfigError(f"zenoh_bridge: {label} {name!r} is no fully qualified ROS 2 name (like /a/b)")
        if p.in_clock not in _CLOCKS:
            raise ConfigError(f"zenoh_bridge: in_clock must be system or graph, got {p.in_clock!r}")
        if not (p.max_age_s > 0 and p.max_rate_hz > 0 and p.max_burst >= 1 and p.max_bytes >= 64 and p.depth >= 1):
            raise ConfigError("zenoh_bridge: max_age_s and max_rate_hz must be > 0, max_burst and depth >= 1, "
                              "max_bytes >= 64")
        self.inputs = {f"out{i}": Input(t, registry[_TYPES_BY_TOPIC[t]], policy="queue", depth=1000)
                       for i, t in enumerate(p.publish)}
        for name in self.inputs:
            setattr(self, f"on_{name}", self._forward)
        self.outputs = {"wrench": Output("ft/wrench", Wrench)} if p.wrench_in else {}
        self._session: Any = None
        self._publishers: dict[str, Any] = {}  # ROS 2 topic (and /info) -> [Zenoh publisher, gid, next sequence]
        self._topic_of: dict[type[Message], str] = {}  # the ROS 2 topic of each type published
        self._tokens: list[Any] = []
        self._inbox: _Inbox | None = None
        self._in_sequence: int | None = None
        self._counted = dict.fromkeys(("received", "oversize", "over_rate", "dropped"), 0)

    # -- session -------------------------------------------------------------------------
    def _config(self) -> Any:
        import zenoh

        p = self.params
        try:
            config = zenoh.Config.from_file(p.config) if p.config else zenoh.Config()
            for key, value in (("mode", p.mode), ("connect/endpoints", p.connect), ("listen/endpoints", p.listen),
                               ("scouting/multicast/enabled", p.multicast_scouting),
                               ("scouting/gossip/enabled", p.gossip_scouting)):
                config.insert_json5(key, json.dumps(value))
        except Exception as exc:  # noqa: BLE001 — Zenoh reports a bad file or value as its own error
            raise ConfigError(f"zenoh_bridge: the Zenoh configuration is refused ({exc}); check config, mode, "
                              "connect and listen (docs/ros2.md)") from None
        return config

    def start(self, ctx: Context) -> None:
        try:
            import zenoh
        except ImportError:
            raise ConfigError(INSTALL_HINT) from None
        from slipstack.messages.ros2 import codec

        p = self.params
        self._codec = codec()
        try:
            self._session = zenoh.open(self._config())
        except Exception as exc:  # noqa: BLE001
            raise ConfigError(f"zenoh_bridge: cannot open the Zenoh session ({exc}); check connect/listen "
                              "endpoints and the config file (docs/ros2.md)") from None
        zid = str(self._session.zid())
        liveliness = self._session.liveliness()
        self._tokens.append(liveliness.declare_token(rmw_zenoh.node_token(p.domain_id, zid, 0, p.namespace,
                                                                           p.node_name)))
        entity = iter(range(1, 1 << 30))
        qos = rmw_zenoh.qos_text(depth=p.queue_depth)
        topics = []
        for name, spec in self.inputs.items():
            topic = ros_topic(ctx.input_topic(name), p.namespace)
            self._topic_of[spec.type] = topic
            topics.append((topic, ROS_TYPES[spec.type]))
            if spec.type in INFO_TYPES:
                topics.append((topic + INFO_SUFFIX, INFO_TYPES[spec.type]))
        if p.command_topic:
            topics.append((p.command_topic, COMMAND_TYPE))
        for topic, ros_type in topics:
            self._declare(topic, ros_type, next(entity), zid, qos)
        if p.wrench_in:
            type_hash = self._codec.type_hash(WRENCH_STAMPED)
            self._inbox = _Inbox(p)
            self._subscriber = self._session.declare_subscriber(
                rmw_zenoh.topic_key(p.domain_id, p.wrench_in, WRENCH_STAMPED, type_hash), self._inbox.on_sample)
            self._tokens.append(liveliness.declare_token(rmw_zenoh.endpoint_token(
                p.domain_id, zid, 0, next(entity), rmw_zenoh.SUBSCRIPTION, p.namespace, p.node_name, p.wrench_in,
                WRENCH_STAMPED, type_hash, qos)))
        ctx.log(f"ROS 2 over Zenoh (rmw_zenoh layout, domain {p.domain_id}, session {zid}): publishing "
                f"{', '.join(t for t, _ in topics) or 'nothing'}"
                + (f"; {p.wrench_in} in as ft/wrench" if p.wrench_in else ""))

    def _declare(self, topic: str, ros_type: str, entity_id: int, zid: str, qos: str) -> None:
        import zenoh

        p = self.params
        type_hash = self._codec.type_hash(ros_type)
        token = rmw_zenoh.endpoint_token(p.domain_id, zid, 0, entity_id, rmw_zenoh.PUBLISHER, p.namespace,
                                         p.node_name, topic, ros_type, type_hash, qos)
        publisher = self._session.declare_publisher(rmw_zenoh.topic_key(p.domain_id, topic, ros_type, type_hash),
                                                    express=True, congestion_control=zenoh.CongestionControl.DROP)
        self._publishers[topic] = [publisher, rmw_zenoh.entity_gid(token), 1]
        self._tokens.append(self._session.liveliness().declare_token(token))

    def stop(self, ctx: Context) -> None:
        if self._session is not None and self._publishers:
            time.sleep(_LINGER_S)  # Zenoh sends from its own threads; closing at once would drop the last samples
        for token in self._tokens:
            token.undeclare()
        self._tokens.clear()
        if self._session is not None:
            self._session.close()
            self._session = None
        if self._inbox is not None:
            self._inbox.close()
            self._inbox = None

    # -- out -----------------------------------------------------------------------------
    def _put(self, topic: str, cdr: bytes, ctx: Context) -> None:
        entry = self._publishers[topic]
        publisher, gid, sequence = entry
        entry[2] = sequence + 1
        attachment = rmw_zenoh.Attachment(sequence, time.time_ns(), gid).pack()
        try:
            publisher.put(cdr, attachment=attachment)
        except Exception as exc:  # noqa: BLE001 — a closed or failing session must not stop the node
            ctx.count(f"ros2.{topic}.send_failed")
            ctx.report_error(f"zenoh_bridge: publishing {topic} failed ({exc})")
            return
        ctx.count(f"ros2.{topic}.published")

    def _forward(self, msg: Message, ctx: Context) -> None:
        p = self.params
        try:
            outs = self._codec.to_ros(msg)
        except DecodeError as exc:
            ctx.count("ros2.unconvertible")
            ctx.report_error(f"zenoh_bridge: {exc}")
            return
        topic = self._topic_of[type(msg)]
        for out in outs:
            self._put(topic + out.suffix, out.cdr, ctx)
        if p.command_topic and isinstance(msg, GripCommand):
            self._put(p.command_topic, self._command(msg), ctx)

    def _command(self, msg: GripCommand) -> bytes:
        t = self._codec.store.types
        layout = t["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
        return self._codec.serialize(t[COMMAND_TYPE](layout=layout, data=np.array([msg.f_n_desired])), COMMAND_TYPE)

    # -- in ------------------------------------------------------------------------------
    def io_sources(self) -> list[_Inbox]:
        return [self._inbox] if self._inbox is not None else []

    def on_readable(self, source: _Inbox, ctx: Context) -> None:
        topic = self.params.wrench_in
        for key, n in source.counts.items():  # what Zenoh's thread counted since the last call
            if n != self._counted[key]:
                ctx.count(f"ros2.{topic}.{key}", n - self._counted[key])
                self._counted[key] = n
        for cdr, attachment in source.take():
            reason = self._receive(cdr, attachment, ctx)
            if reason is not None:
                ctx.count(f"ros2.{topic}.rejected")
                ctx.report_error(f"zenoh_bridge: {topic}: {reason}")

    def _receive(self, cdr: bytes, raw_attachment: bytes | None, ctx: Context) -> str | None:
        """Publish one incoming WrenchStamped as ``ft/wrench``; why not, if it is rejected."""
        p = self.params
        if raw_attachment is None:
            return "a sample without rmw_zenoh's attachment (sequence, time, GID)"
        try:
            attachment = rmw_zenoh.Attachment.unpack(raw_attachment)
            ros = self._codec.deserialize(cdr, WRENCH_STAMPED)
            msg = self._codec.from_ros(WRENCH_STAMPED, ros, seq=0)
        except (ValueError, DecodeError) as exc:
            return str(exc)
        if ros.header.frame_id != PAD_FRAME_ID:
            return (f"frame_id {ros.header.frame_id!r:.40}: only wrenches in the pad frame ('{PAD_FRAME_ID}') drive "
                    "the graph; transform it in ROS 2 (tf2) first")
        now = ctx.now_ns()
        stamp = stamp_to_ns(ros.header.stamp)
        if p.in_clock == "system":
            stamp -= time.time_ns() - now
        if abs(now - stamp) > p.max_age_s * 1e9:
            return (f"stamped {(now - stamp) / 1e9:+.3f} s from now (max_age_s {p.max_age_s:g}); check the sender's "
                    "clock and in_clock")
        if self._in_sequence is not None and attachment.sequence > self._in_sequence + 1:
            ctx.count(f"ros2.{p.wrench_in}.lost", attachment.sequence - self._in_sequence - 1)
        self._in_sequence = attachment.sequence
        wrench = Wrench(force=msg.force, torque=msg.torque, frame=PAD_FRAME_ID, device_seq=attachment.sequence)
        try:
            validate(wrench)  # finite forces and torques
        except DecodeError as exc:
            return str(exc)
        ctx.publish("wrench", wrench, stamp_ns=max(stamp, 0))
        return None

