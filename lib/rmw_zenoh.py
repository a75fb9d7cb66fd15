"""rmw_zenoh's names on the wire: topic key expressions, liveliness tokens, QoS text, attachments.

The layout of rmw_zenoh_cpp's docs/design.md from release 0.2.4 (Jazzy) / 0.6.0 (Kilted,
Rolling) on, when the attachment became a fixed little-endian record; docs/ros2.md says what
was checked against what. Strings and bytes only: the Zenoh session is the bridge node's.
"""

from __future__ import annotations

import hashlib
import re
import struct
from dataclasses import dataclass

__all__ = ["ADMIN_SPACE", "NODE", "PUBLISHER", "SUBSCRIPTION", "GID_BYTES", "Attachment", "dds_type_name",
           "mangle", "topic_key", "node_token", "endpoint_token", "qos_text", "entity_gid", "valid_ros_name"]

ADMIN_SPACE = "@ros2_lv"
NODE, PUBLISHER, SUBSCRIPTION = "NN", "MP", "MS"
GID_BYTES = 16
_EMPTY = "%"  # an empty namespace or enclave
_ATTACHMENT = struct.Struct("<qqB")  # sequence number, source timestamp (ns since the epoch), GID length
_NAME = re.compile(r"(/[A-Za-z_][A-Za-z0-9_]*)+")
# rmw's enums (rmw/types.h): the values rmw_zenoh writes where a QoS differs from its default
_RELIABILITY = {"reliable": 1, "best_effort": 2}
_DURABILITY = {"transient_local": 1, "volatile": 2}
_HISTORY = {"keep_last": 1, "keep_all": 2}
_DEFAULT = {"reliability": "reliable", "durability": "volatile", "history": "keep_last", "depth": 42}


def valid_ros_name(name: str) -> bool:
    """A fully qualified ROS 2 name (``/ns/topic``): tokens of letters, digits and ``_``, none leading with a digit."""
    return bool(_NAME.fullmatch(name)) and "__" not in name


def dds_type_name(ros_type: str) -> str:
    """``std_msgs/msg/String`` → ``std_msgs::msg::dds_::String_`` (the CDR type name in keys)."""
    package, kind, name = ros_type.split("/")
    return f"{package}::{kind}::dds_::{name}_"


def mangle(name: str) -> str:
    """A name inside one token: each ``/`` as ``%``; empty (the root) as ``%``."""
    return name.replace("/", "%") if name.strip("/") else _EMPTY


def topic_key(domain_id: int, topic: str, ros_type: str, type_hash: str) -> str:
    """``<domain>/<fully qualified name, no leading />/<DDS type name>/<RIHS01 hash>``: where data flows."""
    return f"{domain_id}/{topic.strip('/')}/{dds_type_name(ros_type)}/{type_hash}"


def node_token(domain_id: int, zid: str, node_id: int, namespace: str, node_name: str) -> str:
    """The liveliness token that announces a node (``ros2 node list``)."""
    return f"{ADMIN_SPACE}/{domain_id}/{zid}/{node_id}/{node_id}/{NODE}/{_EMPTY}/{mangle(namespace)}/{node_name}"


def endpoint_token(domain_id: int, zid: str, node_id: int, entity_id: int, kind: str, namespace: str,
                   node_name: str, topic: str, ros_type: str, type_hash: str, qos: str) -> str:
    """The liveliness token of a publisher (``MP``) or subscription (``MS``) of ``topic`` (``ros2 topic list``)."""
    return (f"{ADMIN_SPACE}/{domain_id}/{zid}/{node_id}/{entity_id}/{kind}/{_EMPTY}/{mangle(namespace)}/{node_name}/"
            f"{mangle(topic)}/{dds_type_name(ros_type)}/{type_hash}/{qos}")


def qos_text(reliability: str = "reliable", durability: str = "volatile", history: str = "keep_last",
             depth: int = 10) -> str:
    """A QoS as rmw_zenoh writes it in a token: each field left empty where it is rmw_zenoh's default
    (reliable, volatile, keep last 42; deadline, lifespan and liveliness always default here):
    ``<reliability>:<durability>:<history>,<depth>:<deadline s>,<ns>:<lifespan s>,<ns>:<liveliness>,<s>,<ns>``."""
    def differing(field: str, value: object, code: object) -> str:
        return "" if value == _DEFAULT[field] else str(code)

    return (f"{differing('reliability', reliability, _RELIABILITY[reliability])}:"
            f"{differing('durability', durability, _DURABILITY[durability])}:"
            f"{differing('history', history, _HISTORY[history])},{differing('depth', depth, depth)}:,:,:,,")


def entity_gid(token: str) -> bytes:
    """A 16-byte id of an entity, from its token (rmw_zenoh hashes the token too, with XXH3-128)."""
    return hashlib.blake2b(token.encode(), digest_size=GID_BYTES).digest()


@dataclass(frozen=True)
class Attachment:
    """What rmw_zenoh attaches to every sample: the publisher's sequence number (from 1), the
    source time (ns since the Unix epoch) and the publisher's GID."""

    sequence: int
    source_time_ns: int
    gid: bytes

    def pack(self) -> bytes:
        return _ATTACHMENT.pack(self.sequence, self.source_time_ns, len(self.gid)) + self.gid

    @classmethod
    def unpack(cls, raw: bytes) -> "Attachment":
        """Raises ValueError for bytes that are not one attachment."""
        if len(raw) < _ATTACHMENT.size:
            raise ValueError(f"an rmw_zenoh attachment has at least {_ATTACHMENT.size} bytes, got {len(raw)}")
        sequence, source_ns, gid_len = _ATTACHMENT.unpack_from(raw)
        if len(raw) != _ATTACHMENT.size + gid_len:
            raise ValueError(f"an rmw_zenoh attachment with a {gid_len}-byte GID has {_ATTACHMENT.size + gid_len} "
                             f"bytes, got {len(raw)}")
        return cls(sequence, source_ns, bytes(raw[_ATTACHMENT.size:]))
