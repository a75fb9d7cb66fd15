"""Recordings as rosbag2 writes them: MCAP, profile ``ros2``, ``ros2msg`` schemas, CDR (docs/ros2.md).

:class:`Ros2RecordingWriter` writes the bus's frames so (``bag export --to ros2``, the recorder's
``format = "ros2"``); :class:`Ros2Frames` reads such a file, or any rosbag2 MCAP with those types,
back into slipstack frames, so ``read_recording`` and every tool on it read both layouts alike.
Needs the ``ros2`` extra.
"""

from __future__ import annotations

import os
from collections import defaultdict
from typing import Any, Iterator

import yaml
from mcap.records import Channel, Message as McapMessage, Schema

from slipstack.lib.errors import DecodeError
from slipstack.messages import (Contact, Cor, Diagnostics, GripCommand, GripState, RigTruth, Slip, TactileFrame, Wrench,
                                decode, encode)
from slipstack.messages.ros2 import INFO_SUFFIX, INFO_TYPES, ROS_NAMESPACE, ROS_TYPES, codec, ros_topic
from slipstack.nodes.recording.bag_io import ROS2_MESSAGE_ENCODING, RecordedFrame, RecordingWriter

__all__ = ["PROFILE", "SCHEMA_ENCODING", "qos_profiles_yaml",
           "Ros2RecordingWriter", "Ros2Frames"]

PROFILE, SCHEMA_ENCODING = "ros2", "ros2msg"
ROSBAG2_METADATA = "rosbag2"
"""The metadata record rosbag2's MCAP storage writes at the end: ``serialized_metadata``, the bag's
``metadata.yaml`` (version 9), from which ``ros2 bag info`` reads the file."""
_DEFAULT_TOPICS = {ROS_TYPES[Wrench]: "ft/wrench", ROS_TYPES[TactileFrame]: "tactile/frame",
                   ROS_TYPES[Contact]: "contact", ROS_TYPES[Cor]: "cor", ROS_TYPES[Slip]: "slip",
                   ROS_TYPES[GripCommand]: "grip/command", ROS_TYPES[GripState]: "grip/state",
                   ROS_TYPES[RigTruth]: "rig/truth",
                   ROS_TYPES[Diagnostics]: "diagnostics"}
"""The slipstack topic of a ROS 2 type recorded outside :data:`ROS_NAMESPACE` (another lab's bag)."""


def qos_profiles_yaml(depth: int = 10) -> str:
    """``offered_qos_profiles`` as rosbag2 (metadata version 9) writes it: one reliable, volatile,
    keep-last publisher; zero durations are the middleware's defaults."""
    zero = {"sec": 0, "nsec": 0}
    return yaml.safe_dump([{"history": "keep_last", "depth": depth, "reliability": "reliable",
                            "durability": "volatile", "deadline": zero, "lifespan": zero, "liveliness": "automatic",
                            "liveliness_lease_duration": zero, "avoid_ros_namespace_conventions": False}],
                          sort_keys=False).strip()


class Ros2RecordingWriter(RecordingWriter):
    """A :class:`RecordingWriter` whose file rosbag2, Foxglove and PlotJuggler read: each frame
    decoded and written as its ROS 2 message(s) on ``/slipstack/<topic>`` (and ``…/info``).

    ``log_time`` stays the receive time (wall clock); ``publish_time`` is ``pub_ns`` put on the
    wall clock with ``wall_minus_monotonic_ns``; header stamps stay on the graph's time base. A
    frame that does not decode, or whose type has no ROS 2 message, is not written; :attr:`skipped`
    counts it per topic.
    """

    PROFILE = PROFILE

    def __init__(self, path: str | os.PathLike, **kwargs: Any) -> None:
        self._codec = codec()  # before the file: a missing extra fails here
        super().__init__(path, **kwargs)
        self._ros_channels: dict[tuple[str, str], int] = {}
        self._ros_counts: dict[tuple[str, str], int] = defaultdict(int)
        self._first_ns: int | None = None
        self._last_ns = 0
        self.skipped: dict[str, int] = defaultdict(int)

    def _ros_channel(self, topic: str, ros_type: str) -> int:
        cid = self._ros_channels.get((topic, ros_type))
        if cid is None:
            schema_id = self._schemas.get(ros_type)
            if schema_id is None:
                schema_id = self._writer.register_schema(ros_type, SCHEMA_ENCODING,
                                                         self._codec.definition(ros_type).encode())
                self._schemas[ros_type] = schema_id
            cid = self._writer.register_channel(topic, ROS2_MESSAGE_ENCODING, schema_id, {
                "offered_qos_profiles": qos_profiles_yaml(), "topic_type_hash": self._codec.type_hash(ros_type)})
            self._ros_channels[(topic, ros_type)] = cid
        return cid

    def write(self, topic: str, payload: bytes, log_time_ns: int) -> None:
        """Append one bus frame received at ``log_time_ns`` (wall-clock ns) as its ROS 2 message(s)."""
        if self._failed(topic):
            return
        try:
            msg = decode(payload)
            outs = self._codec.to_ros(msg)
        except (DecodeError, KeyError):  # KeyError: a message type with no ROS 2 counterpart yet
            self.skipped[topic] += 1
            return
        log_time_ns = int(log_time_ns)
        name = ros_topic(topic)
        for out in outs:  # every channel of the message first: a reader meets the /info channel before its data
            self._ros_channel(name + out.suffix, out.ros_type)
        publish = msg.header.pub_ns + (self.wall_minus_monotonic_ns or 0)
        for out in outs:
            self._writer.add_message(self._ros_channels[(name + out.suffix, out.ros_type)], log_time_ns, out.cdr,
                                     publish, msg.header.seq & 0xFFFFFFFF)
            self._ros_counts[(name + out.suffix, out.ros_type)] += 1
        self._first_ns = log_time_ns if self._first_ns is None else min(self._first_ns, log_time_ns)
        self._last_ns = max(self._last_ns, log_time_ns)
        self._written(topic, log_time_ns, sum(len(out.cdr) for out in outs))

    def close(self, metadata: dict[str, dict[str, str]] | None = None) -> None:
        """Finish the file as :meth:`RecordingWriter.close`, with rosbag2's metadata record too."""
        super().close({ROSBAG2_METADATA: {"serialized_metadata": self._bag_metadata()}, **(metadata or {})})

    def _bag_metadata(self) -> str:
        start = self._first_ns or 0
        duration = self._last_ns - start if self._first_ns is not None else 0
        count = sum(self._ros_counts.values())
        topics = [{"topic_metadata": {"name": t, "type": ros_type, "serialization_format": ROS2_MESSAGE_ENCODING,
                                      "offered_qos_profiles": qos_profiles_yaml(),
                                      "type_description_hash": self._codec.type_hash(ros_type)},
                   "message_count": n} for (t, ros_type), n in sorted(self._ros_counts.items())]
        return yaml.safe_dump({
            "version": 9, "storage_identifier": "mcap", "duration": {"nanoseconds": duration},
            "starting_time": {"nanoseconds_since_epoch": start}, "message_count": count,
            "topics_with_message_count": topics, "compression_format": "", "compression_mode": "",
            "relative_file_paths": [self.path.name],
            "files": [{"path": self.path.name, "starting_time": {"nanoseconds_since_epoch": start},
                       "duration": {"nanoseconds": duration}, "message_count": count}],
            "custom_data": {"writer": "slipstack"}, "ros_distro": "",
        }, sort_keys=False)


class Ros2Frames:
    """Turns the CDR messages of a ROS 2 MCAP file into slipstack frames, as recorded on the bus.

    A channel's slipstack topic: its name without :data:`ROS_NAMESPACE`, or, outside it, the topic
    of its type (a ``WrenchStamped`` is ``ft/wrench``, a 32FC1 ``Image`` ``tactile/frame``); the
    first channel to claim a topic keeps it, later ones and types slipstack has no message for are
    left out (:attr:`left_out`). A ``…/info`` message joins the message before it of the same stamp.
    A message that does not convert becomes a frame of its raw bytes, which no decoder accepts:
    the tools count it as undecodable.
    """

    def __init__(self, channels: dict[int, Channel], schemas: dict[int, Schema]) -> None:
        self._codec = codec()
        self._channels = channels  # filled by the scan as the file is read
        self._schemas = schemas
        self._routes: dict[int, tuple[str, str, bool, bool] | None] = {}  # channel -> topic, type, is /info, has one
        self._claimed: dict[str, int] = {}
        self._pending: tuple[McapMessage, str, str, Any] | None = None  # a main message awaiting its /info
        self._seq: dict[int, int] = defaultdict(int)
        self.left_out: dict[str, str] = {}
        """ROS 2 topic → why it was not read."""
        self.topic_types: dict[str, str] = {}
        """Slipstack topic → the ROS 2 type it is read from."""

    def _route(self, channel_id: int) -> tuple[str, str, bool, bool] | None:
        if channel_id in self._routes:
            return self._routes[channel_id]
        ch = self._channels[channel_id]
        schema = self._schemas.get(ch.schema_id)
        ros_type = schema.name if schema is not None else ""
        route = None
        prefix = ROS_NAMESPACE + "/"
        info = ros_type in INFO_TYPES.values()
        if ros_type not in _DEFAULT_TOPICS and not info:
            self.left_out[ch.topic] = f"type {ros_type or 'unknown'} has no slipstack message"
        elif info and ch.topic.startswith(prefix) and ch.topic.endswith(INFO_SUFFIX):
            route = (ch.topic[len(prefix):-len(INFO_SUFFIX)], ros_type, True, False)
        else:
            topic = ch.topic[len(prefix):] if ch.topic.startswith(prefix) else _DEFAULT_TOPICS.get(ros_type, "")
            if not topic or info or self._claimed.setdefault(topic, channel_id) != channel_id:
                self.left_out[ch.topic] = f"{topic or ch.topic} is read from another channel"
            else:  # a writer registers a message's /info channel before the message (Ros2RecordingWriter)
                has_info = any(c.topic == ch.topic + INFO_SUFFIX for c in self._channels.values())
                route = (topic, ros_type, False, has_info)
                self.topic_types[topic] = ros_type
        self._routes[channel_id] = route
        return route

    def frames(self, m: McapMessage, wanted: set[str] | None) -> Iterator[RecordedFrame]:
        """The frames that message ``m`` completes (none, one or two), in file order."""
        route = self._route(m.channel_id)
        if route is None or (wanted is not None and route[0] not in wanted):
            return
        topic, ros_type, is_info, has_info = route
        try:
            decoded = self._codec.deserialize(m.data, ros_type)
        except DecodeError:
            yield from self.flush()
            yield RecordedFrame(m.log_time, topic, bytes(m.data), m.publish_time, m.sequence)
            return
        if is_info:
            pending, self._pending = self._pending, None
            if pending is not None and pending[1] == topic and pending[3].header.stamp == decoded.header.stamp:
                yield self._frame(*pending, decoded)
            else:
                if pending is not None:
                    yield self._frame(*pending)
            return
        yield from self.flush()
        if has_info:
            self._pending = (m, topic, ros_type, decoded)
        else:
            yield self._frame(m, topic, ros_type, decoded)

    def flush(self) -> Iterator[RecordedFrame]:
        """The message still waiting for its ``/info``, without it (call at the end of the file)."""
        if self._pending is not None:
            pending, self._pending = self._pending, None
            yield self._frame(*pending)

    def _frame(self, m: McapMessage, topic: str, ros_type: str, main: Any, info: Any = None) -> RecordedFrame:
        seq = self._seq[m.channel_id]
        self._seq[m.channel_id] = seq + 1
        try:
            msg = self._codec.from_ros(ros_type, main, info, seq)
            payload = encode(msg)
        except (DecodeError, TypeError, ValueError, OverflowError):
            return RecordedFrame(m.log_time, topic, bytes(m.data), m.publish_time, m.sequence)
        return RecordedFrame(m.log_time, topic, payload, msg.header.pub_ns, msg.header.seq)
