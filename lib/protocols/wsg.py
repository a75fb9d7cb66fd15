"""Weiss Robotics WSG 50 gripper: its binary command protocol over TCP (docs/protocols.md §9).

More in docs/modules.md, `lib/protocols/wsg.py`.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum

from .crc import CRC16_DSACON32

__all__ = ["PREAMBLE", "DEFAULT_PORT", "FORCE_RANGE_N", "Command", "Status", "GraspingState", "Message",
           "MessageCodec", "encode_message", "encode_reply", "reply_status", "f32", "set_force_limit", "grasp",
           "release", "ack_fast_stop", "get_force_limit", "get_grasping_state", "get_force", "ACK_PAYLOAD",
           "AUTO_UPDATE", "MAX_PAYLOAD"]

PREAMBLE = b"\xaa\xaa\xaa"
DEFAULT_PORT = 1000
"""The WSG's TCP command port as shipped (its web interface changes it)."""
FORCE_RANGE_N = (5.0, 80.0)
"""The WSG 50's grasping force limit range (N): a value outside gets ``E_RANGE_ERROR``."""
ACK_PAYLOAD = b"ack"
AUTO_UPDATE = 0x01
"""Flag b0 of a get-value command: send the value every period (ms), not just once."""
_HEADER = struct.Struct("<3sBH")
_F32 = struct.Struct("<f")
MAX_PAYLOAD = 64
"""Payload bytes a message may announce, at most: the commands used here and their replies
carry at most 9 (a loop's echo is bounded by it too). A false preamble in garbage announcing
more costs one byte at once instead of stalling the stream until that many bytes came."""


class Command(IntEnum):
    LOOP = 0x06
    DISCONNECT = 0x07
    ACK_FAST_STOP = 0x24
    GRASP = 0x25
    RELEASE = 0x26
    SET_FORCE_LIMIT = 0x32
    GET_FORCE_LIMIT = 0x33
    GET_GRASPING_STATE = 0x41
    GET_FORCE = 0x45


class Status(IntEnum):
    """The WSG's status codes (its full list; those the emulator sends are marked in docs/protocols.md §9)."""

    E_SUCCESS = 0
    E_NOT_AVAILABLE = 1
    E_NO_SENSOR = 2
    E_NOT_INITIALIZED = 3
    E_ALREADY_RUNNING = 4
    E_FEATURE_NOT_SUPPORTED = 5
    E_INCONSISTENT_DATA = 6
    E_TIMEOUT = 7
    E_READ_ERROR = 8
    E_WRITE_ERROR = 9
    E_INSUFFICIENT_RESOURCES = 10
    E_CHECKSUM_ERROR = 11
    E_NO_PARAM_EXPECTED = 12
    E_NOT_ENOUGH_PARAMS = 13
    E_CMD_UNKNOWN = 14
    E_CMD_FORMAT_ERROR = 15
    E_ACCESS_DENIED = 16
    E_ALREADY_OPEN = 17
    E_CMD_FAILED = 18
    E_CMD_ABORTED = 19
    E_INVALID_HANDLE = 20
    E_NOT_FOUND = 21
    E_NOT_OPEN = 22
    E_IO_ERROR = 23
    E_INVALID_PARAMETER = 24
    E_INDEX_OUT_OF_BOUNDS = 25
    E_CMD_PENDING = 26
    E_OVERRUN = 27
    E_RANGE_ERROR = 28
    E_AXIS_BLOCKED = 29
    E_FILE_EXISTS = 30


class GraspingState(IntEnum):
    IDLE = 0
    GRASPING = 1
    NO_PART_FOUND = 2
    PART_LOST = 3
    HOLDING = 4
    RELEASING = 5
    POSITIONING = 6
    ERROR = 7


@dataclass(frozen=True)
class Message:
    """A message with a valid CRC: its command id and payload (a reply's starts with its status)."""

    id: int
    payload: bytes


def encode_message(command: int, payload: bytes = b"") -> bytes:
    """A whole message: preamble, id, size, payload and the CRC over all of them."""
    body = _HEADER.pack(PREAMBLE, command, len(payload)) + payload
    return body + CRC16_DSACON32(body).to_bytes(2, "little")


def encode_reply(command: int, status: int, values: bytes = b"") -> bytes:
    """The gripper's reply to ``command``: the status code, then ``values`` (only with success)."""
    return encode_message(command, status.to_bytes(2, "little") + values)


def reply_status(payload: bytes) -> tuple[int, bytes] | None:
    """``(status, values)`` of a reply payload; None if it holds no status."""
    if len(payload) < 2:
        return None
    return int.from_bytes(payload[:2], "little"), payload[2:]


def f32(values: bytes) -> float | None:
    """The f32 a reply's values hold; None if they are not exactly four bytes."""
    return _F32.unpack(values)[0] if len(values) == _F32.size else None


def set_force_limit(force_n: float) -> bytes:
    return encode_message(Command.SET_FORCE_LIMIT, _F32.pack(force_n))


def grasp(width_mm: float, speed_mm_s: float) -> bytes:
    return encode_message(Command.GRASP, struct.pack("<ff", width_mm, speed_mm_s))


def release(width_mm: float, speed_mm_s: float) -> bytes:
    return encode_message(Command.RELEASE, struct.pack("<ff", width_mm, speed_mm_s))


def ack_fast_stop() -> bytes:
    return encode_message(Command.ACK_FAST_STOP, ACK_PAYLOAD)


def get_force_limit() -> bytes:
    return encode_message(Command.GET_FORCE_LIMIT)


def get_grasping_state() -> bytes:
    return encode_message(Command.GET_GRASPING_STATE, struct.pack("<BH", 0, 0))


def get_force(period_ms: int = 0) -> bytes:
    """Get the grasping force once (``period_ms = 0``) or every ``period_ms`` (auto-update)."""
    flags = AUTO_UPDATE if period_ms > 0 else 0
    return encode_message(Command.GET_FORCE, struct.pack("<BH", flags, period_ms))


class MessageCodec:
    """FrameCodec of WSG messages (either direction); yields :class:`Message`.

    Every message carries a CRC, even one without payload, so a false preamble in
    garbage passes only with a 2⁻¹⁶ collision; ``max_payload`` bounds the size a header
    may announce (:data:`MAX_PAYLOAD`).
    """

    sync = PREAMBLE
    header_length = _HEADER.size

    def __init__(self, max_payload: int = MAX_PAYLOAD) -> None:
        self.max_length = _HEADER.size + max_payload + 2

    def frame_length(self, header: bytes) -> int:
        return _HEADER.size + int.from_bytes(header[4:6], "little") + 2

    def parse(self, frame: bytes) -> Message | None:
        if CRC16_DSACON32(frame[:-2]) != int.from_bytes(frame[-2:], "little"):
            return None
        return Message(frame[3], bytes(frame[_HEADER.size:-2]))
