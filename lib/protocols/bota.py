"""Bota Systems serial F/T sensors (Rokubi, SensONE): the 37-byte stream frame.

Sources: BOTAsys/matlab ``bota_serial/*.m``; public BotaSerialDriver sources
(see docs/protocols.md §5). 460800 baud 8N1. Frame, little-endian, packed::

More in docs/modules.md, `lib/protocols/bota.py`.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntFlag
from typing import Sequence

import numpy as np

from .crc import CRC16_X25

__all__ = [
    "FRAME_LENGTH", "BAUDRATE", "RATE_HZ", "CONFIG_COMMAND", "RUN_COMMAND", "BotaStatus",
    "BotaFrame", "encode_frame", "decode_frame", "command_reply", "StreamCodec",
]

SYNC = b"\xaa"
FRAME_LENGTH = 37
BAUDRATE = 460800
RATE_HZ = 200.0
CONFIG_COMMAND = b"C"
RUN_COMMAND = b"R"

_BODY = struct.Struct("<H6fIf")


class BotaStatus(IntFlag):
    """Status word bits."""

    APP_TOO_SLOW = 1
    OVER_RANGE = 2
    INVALID = 4
    RAW = 8


@dataclass(frozen=True)
class BotaFrame:
    """One frame: force (3,) N, torque (3,) N·m (sensor frame), device time, temperature."""

    status: int
    force_n: np.ndarray
    torque_nm: np.ndarray
    timestamp_us: int
    temperature_c: float


def encode_frame(
    force_n: Sequence[float], torque_nm: Sequence[float], *, timestamp_us: int,
    status: int = 0, temperature_c: float = 25.0,
) -> bytes:
    """37-byte frame (values stored as float32; timestamp wraps at 2**32 µs)."""
    body = _BODY.pack(status, *force_n, *torque_nm, timestamp_us & 0xFFFFFFFF, temperature_c)
    return SYNC + body + CRC16_X25(body).to_bytes(2, "little")


def decode_frame(frame: bytes) -> BotaFrame | None:
    """Decode a 37-byte frame; None if the length, sync byte or CRC is wrong."""
    if len(frame) != FRAME_LENGTH or frame[0] != 0xAA:
        return None
    if CRC16_X25(frame[1:35]) != int.from_bytes(frame[35:], "little"):
        return None
    status, *ft, stamp, temp = _BODY.unpack_from(frame, 1)
    v = np.array(ft, dtype=float)
    return BotaFrame(status, v[:3], v[3:], stamp, temp)


def command_reply(command: bytes) -> bytes:
    """Reply a sensor sends to a one-letter command (``r,0,C,0`` form, CRLF assumed)."""
    return b"r,0," + command + b",0\r\n"


class StreamCodec:
    """:class:`~slipstack.lib.protocols.stream.FrameCodec` of the Bota frame."""

    sync = SYNC
    header_length = 1
    max_length = FRAME_LENGTH

    def frame_length(self, header: bytes) -> int:
        return FRAME_LENGTH

    def parse(self, frame: bytes) -> BotaFrame | None:
        return decode_frame(frame)
