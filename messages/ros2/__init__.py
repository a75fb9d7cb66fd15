"""slipstack's messages as ROS 2 messages: types, CDR and their schemas (docs/ros2.md).

Standard types where ROS 2 has them (``geometry_msgs/msg/WrenchStamped``, ``sensor_msgs/msg/Image``
32FC1 in Pa), the ``slipstack_msgs`` package beside this file for the rest; what a standard type
lacks goes on ``<topic>/info``. CDR, definitions and type hashes come from ``rosbags`` (the
``ros2`` extra): import this package only where ROS 2 is wanted.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from importlib import resources
from typing import Any, Callable

import numpy as np

from slipstack.lib.errors import ConfigError, DecodeError
from slipstack.messages import (Contact, Cor, Diagnostics, GripCommand, GripState, Header, Message, RigTruth, Slip,
                                TactileFrame, Wrench)

__all__ = ["INSTALL_HINT", "PAD_FRAME_ID", "WRENCH_STAMPED", "IMAGE", "ROS_TYPES", "INFO_TYPES", "INFO_SUFFIX",
           "RosOut", "Ros2Codec", "ROS_NAMESPACE", "codec", "ros_topic", "stamp_to_ns"]

INSTALL_HINT = "ROS 2 messages need the ros2 extra: pip install 'slipstack[ros2]'"
PAD_FRAME_ID = "pad"
"""``header.frame_id`` of data in the pad frame F (slipstack's frame names: ``pad``, ``sensor``)."""
WRENCH_STAMPED = "geometry_msgs/msg/WrenchStamped"
IMAGE = "sensor_msgs/msg/Image"
PACKAGE = "slipstack_msgs"
ROS_TYPES: dict[type[Message], str] = {
    Wrench: WRENCH_STAMPED, TactileFrame: IMAGE, Contact: f"{PACKAGE}/msg/Contact", Cor: f"{PACKAGE}/msg/Cor",
    Slip: f"{PACKAGE}/msg/Slip", GripCommand: f"{PACKAGE}/msg/GripCommand", GripState: f"{PACKAGE}/msg/GripState",
    RigTruth: f"{PACKAGE}/msg/RigTruth", Diagnostics: f"{PACKAGE}/msg/Diagnostics",
}
"""The ROS 2 type each slipstack type is published and recorded as."""
INFO_TYPES: dict[type[Message], str] = {Wrench: f"{PACKAGE}/msg/WrenchInfo", TactileFrame: f"{PACKAGE}/msg/TactileInfo"}
"""Standard-typed messages also go out as these, on ``<topic>/info``: what the standard type lacks."""
INFO_SUFFIX = "/info"
_MSG_FILES = ("Trace", "WrenchInfo", "TactileInfo", "Contact", "Cor", "Slip", "GripCommand", "GripState", "RigTruth",
              "Diagnostics")
_INT32_MAX = 2**31 - 1
# fields renamed or reshaped between a slipstack type and its slipstack_msgs type
_RENAMED = {"case": "cor_case"}
_IMPLIED = {"earlier_samples"}  # the length of the earlier_* arrays


@dataclass(frozen=True)
class RosOut:
    """One ROS 2 message of a slipstack message: topic suffix (``""`` or :data:`INFO_SUFFIX`), type, CDR."""

    suffix: str
    ros_type: str
    cdr: bytes


ROS_NAMESPACE = "/slipstack"
"""Where slipstack's topics live in ROS 2: ``slip`` is ``/slipstack/slip``."""


def ros_topic(topic: str, namespace: str = ROS_NAMESPACE) -> str:
    """The ROS 2 name of a slipstack topic: ``ft/wrench`` → ``/slipstack/ft/wrench``."""
    return f"{namespace.rstrip('/')}/{topic}"


def stamp_to_ns(stamp: Any) -> int:
    """ns of a ``builtin_interfaces/msg/Time``."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


class Ros2Codec:
    """Converts slipstack messages to and from ROS 2 CDR (one rosbags type store per process).

    Raises:
        ConfigError: rosbags is not installed (:data:`INSTALL_HINT`).
    """

    def __init__(self) -> None:
        try:
            from rosbags.typesys import Stores, get_types_from_msg, get_typestore
        except ImportError:
            raise ConfigError(INSTALL_HINT) from None
        self.store = get_typestore(Stores.ROS2_JAZZY)
        folder = resources.files(__package__) / PACKAGE / "msg"
        types: dict[str, Any] = {}
        for name in _MSG_FILES:
            types.update(get_types_from_msg((folder / f"{name}.msg").read_text(), f"{PACKAGE}/msg/{name}"))
        self.store.register(types)
        t = self.store.types
        self._time, self._header, self._trace = t["builtin_interfaces/msg/Time"], t["std_msgs/msg/Header"], t[f"{PACKAGE}/msg/Trace"]
        self._vector, self._wrench = t["geometry_msgs/msg/Vector3"], t["geometry_msgs/msg/Wrench"]
        self._classes = {name: t[name] for name in (*ROS_TYPES.values(), *INFO_TYPES.values())}
        self._to: dict[type[Message], Callable[[Message], list[RosOut]]] = {Wrench: self._wrench_out,
                                                                             TactileFrame: self._tactile_out}
        self._definitions: dict[str, str] = {}
        self._hashes: dict[str, str] = {}

    # -- schemas --------------------------------------------------------------------------
    def definition(self, ros_type: str) -> str:
        """The ``ros2msg`` schema text of a type (its .msg, then each nested type's, as rosbag2 writes it)."""
        if ros_type not in self._definitions:
            self._definitions[ros_type] = self.store.generate_msgdef(ros_type, ros_version=2)[0]
        return self._definitions[ros_type]

    def type_hash(self, ros_type: str) -> str:
        """The type's ``RIHS01_…`` hash (REP-2016), as rmw_zenoh keys and rosbag2 metadata carry it."""
        if ros_type not in self._hashes:
            self._hashes[ros_type] = self.store.hash_rihs01(ros_type)
        return self._hashes[ros_type]

    def serialize(self, ros_msg: Any, ros_type: str) -> bytes:
        return bytes(self.store.serialize_cdr(ros_msg, ros_type))

    def deserialize(self, cdr: bytes | memoryview, ros_type: str) -> Any:
        """The rosbags message of ``cdr``; :class:`DecodeError` for bytes that are no such message."""
        try:
            return self.store.deserialize_cdr(cdr, ros_type)
        except Exception as exc:  # noqa: BLE001 — rosbags raises assorted errors on malformed CDR
            raise DecodeError(f"{ros_type}: not a CDR message of this type ({type(exc).__name__}: {exc})"[:300]) from None

    # -- slipstack -> ROS 2 ---------------------------------------------------------------
    def to_ros(self, msg: Message) -> list[RosOut]:
        """The ROS 2 messages of ``msg``: its main type, then its ``/info`` companion if it has one.

        Raises:
            DecodeError: a stamp beyond ``builtin_interfaces/Time`` (int32 seconds).
        """
        to = self._to.get(type(msg))
        return to(msg) if to is not None else [self._generic_out(msg)]

    def header(self, stamp_ns: int, frame_id: str = "") -> Any:
        sec, nsec = divmod(stamp_ns, 1_000_000_000)
        if not 0 <= sec <= _INT32_MAX:
            raise DecodeError(f"header stamp {stamp_ns} ns is beyond builtin_interfaces/Time (int32 seconds)")
        return self._header(stamp=self._time(sec=sec, nanosec=nsec), frame_id=frame_id)

    def _trace_of(self, h: Header) -> Any:
        names = list(h.sources)
        return self._trace(seq=h.seq, pub_ns=h.pub_ns, source_names=names,
                           source_stamps_ns=np.array([h.sources[n] for n in names], dtype=np.int64))

    def _wrench_out(self, msg: Wrench) -> list[RosOut]:
        header = self.header(msg.header.stamp_ns, msg.frame)
        f, t = msg.force, msg.torque
        wrench = self._wrench(force=self._vector(x=float(f[0]), y=float(f[1]), z=float(f[2])),
                              torque=self._vector(x=float(t[0]), y=float(t[1]), z=float(t[2])))
        main = self._classes[WRENCH_STAMPED](header=header, wrench=wrench)
        info = self._classes[INFO_TYPES[Wrench]](header=header, trace=self._trace_of(msg.header),
                                                  device_seq=msg.device_seq, status=msg.status)
        return [RosOut("", WRENCH_STAMPED, self.serialize(main, WRENCH_STAMPED)),
                RosOut(INFO_SUFFIX, INFO_TYPES[Wrench], self.serialize(info, INFO_TYPES[Wrench]))]

    def _tactile_out(self, msg: TactileFrame) -> list[RosOut]:
        header = self.header(msg.header.stamp_ns, PAD_FRAME_ID)
        pixels = np.ascontiguousarray(msg.pressure_pa, dtype="<f4").view(np.uint8)
        main = self._classes[IMAGE](header=header, height=msg.rows, width=msg.cols, encoding="32FC1",
                                    is_bigendian=0, step=4 * msg.cols, data=pixels)
        info = self._classes[INFO_TYPES[TactileFrame]](
            header=header, trace=self._trace_of(msg.header), pitch_m=msg.pitch_m, saturated=msg.saturated,
            dead=msg.dead, device_stamp=msg.device_stamp, status=msg.status)
        return [RosOut("", IMAGE, self.serialize(main, IMAGE)),
                RosOut(INFO_SUFFIX, INFO_TYPES[TactileFrame], self.serialize(info, INFO_TYPES[TactileFrame]))]

    def _generic_out(self, msg: Message) -> RosOut:
        ros_type = ROS_TYPES[type(msg)]
        fields: dict[str, Any] = {"header": self.header(msg.header.stamp_ns, PAD_FRAME_ID if type(msg) in _PAD_TYPES else ""),
                                  "trace": self._trace_of(msg.header)}
        for name in msg._body_fields:  # type: ignore[attr-defined]
            value = getattr(msg, name)
            if name in _IMPLIED:
                continue
            if name == "verdicts":
                methods = list(value)
                fields.update(verdict_methods=methods,
                              verdict_stick=np.array([bool(value[m][0]) for m in methods], dtype=bool),
                              verdict_margin=np.array([float(value[m][1]) for m in methods], dtype=np.float64))
            elif name == "counters":
                fields.update(counter_names=list(value),
                              counter_values=np.array(list(value.values()), dtype=np.float64))
            else:
                fields[_RENAMED.get(name, name)] = value
        return RosOut("", ros_type, self.serialize(self._classes[ros_type](**fields), ros_type))

    # -- ROS 2 -> slipstack ---------------------------------------------------------------
    def from_ros(self, ros_type: str, main: Any, info: Any = None, seq: int = 0) -> Message:
        """The slipstack message of a decoded ROS 2 message (with its ``/info`` companion, if any).

        A standard message without one takes ``status`` ok, no device counter, the default taxel
        pitch, ``seq`` as given and ``pub_ns`` = its stamp. The result is not validated: encode
        it and let the decoder judge it, as any frame.

        Raises:
            DecodeError: a type slipstack has no message for, or an image that is not 32FC1.
        """
        stamp = stamp_to_ns(main.header.stamp)
        trace = info.trace if info is not None else main.trace if hasattr(main, "trace") else None
        header = Header(stamp, seq, stamp, {}) if trace is None else Header(
            stamp, int(trace.seq), int(trace.pub_ns), dict(zip(trace.source_names, map(int, trace.source_stamps_ns))))
        if ros_type == WRENCH_STAMPED:
            return self._wrench_in(main, info, header)
        if ros_type == IMAGE:
            return self._tactile_in(main, info, header)
        cls = _BY_ROS_TYPE.get(ros_type)
        if cls is None:
            raise DecodeError(f"{ros_type}: slipstack has no message of this type")
        fields: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            if f.name == "header":
                continue
            spec = f.metadata.get("array")
            if f.name == "verdicts":
                fields[f.name] = {str(m): [bool(s), float(v)] for m, s, v in
                                  zip(main.verdict_methods, main.verdict_stick, main.verdict_margin)}
            elif f.name == "counters":
                fields[f.name] = {str(n): float(v) for n, v in zip(main.counter_names, main.counter_values)}
            elif f.name in _IMPLIED:
                fields[f.name] = len(main.earlier_stamp_ns)
            elif spec is not None:
                fields[f.name] = np.asarray(getattr(main, f.name), dtype=spec.dtype)
            else:
                value = getattr(main, _RENAMED.get(f.name, f.name))
                fields[f.name] = value.item() if isinstance(value, np.generic) else value
        return cls(**fields, header=header)

    def _wrench_in(self, main: Any, info: Any, header: Header) -> Wrench:
        w = main.wrench
        frame = PAD_FRAME_ID if main.header.frame_id == PAD_FRAME_ID else "sensor"
        extra = {} if info is None else {"device_seq": int(info.device_seq), "status": info.status}
        return Wrench(force=np.array([w.force.x, w.force.y, w.force.z], dtype="<f8"),
                      torque=np.array([w.torque.x, w.torque.y, w.torque.z], dtype="<f8"), frame=frame, **extra,
                      header=header)

    def _tactile_in(self, main: Any, info: Any, header: Header) -> TactileFrame:
        if main.encoding != "32FC1":
            raise DecodeError(f"{IMAGE}.encoding: the pad image must be 32FC1 (pressure in Pa), got {main.encoding!r:.40}")
        rows, cols, step = int(main.height), int(main.width), int(main.step)
        data = np.asarray(main.data, dtype=np.uint8)
        if step < 4 * cols or data.size != step * rows:
            raise DecodeError(f"{IMAGE}: {rows} rows of step {step} need {step * rows} bytes and step >= 4 x width "
                              f"({4 * cols}), got {data.size} bytes")
        pixels = data.reshape(rows, step)[:, :4 * cols].copy().view(">f4" if main.is_bigendian else "<f4")
        n = rows * cols
        extra = {} if info is None else {"pitch_m": float(info.pitch_m), "device_stamp": int(info.device_stamp),
                                         "status": info.status,
                                         "saturated": np.asarray(info.saturated, dtype=bool),
                                         "dead": np.asarray(info.dead, dtype=bool)}
        extra.setdefault("saturated", np.zeros(n, dtype=bool))
        extra.setdefault("dead", np.zeros(n, dtype=bool))
        return TactileFrame(rows=rows, cols=cols, pressure_pa=pixels.reshape(n).astype("<f4"), **extra, header=header)


_PAD_TYPES = (Contact, Cor, Slip, RigTruth)
_BY_ROS_TYPE = {ros: cls for cls, ros in ROS_TYPES.items()}
_codec: Ros2Codec | None = None


def codec() -> Ros2Codec:
    """This process's :class:`Ros2Codec` (built on first use: ~0.2 s)."""
    global _codec
    if _codec is None:
        _codec = Ros2Codec()
    return _codec
