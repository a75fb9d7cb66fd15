"""Robotiq FT 300 / FT 300-S: Modbus RTU commands and the 16-byte stream frame.

Sources: Robotiq FT 150/300 manual p.44, FT 300-S manual pp.33-34;
ros-industrial-attic/robotiq ``rq_sensor_com.cpp`` (see docs/protocols.md §4).

Link 19200 baud 8N1, Modbus slave id 9. Streaming starts when 0x0200 is written to
holding register 410 (function 16); the sensor echoes the 8-byte write response and
then sends, at 100 Hz::

More in docs/modules.md, `lib/protocols/robotiq.py`.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from .crc import CRC16_MODBUS

__all__ = [
    "SLAVE_ID", "STREAM_REGISTER", "STREAM_START_VALUE", "STOP_BYTE", "FRAME_LENGTH",
    "BAUDRATE", "RATE_HZ", "RobotiqFrame", "WriteRequest", "encode_frame", "decode_frame",
    "encode_write_registers", "encode_write_echo", "StreamCodec", "WriteRequestCodec",
    "START_STREAM_REQUEST", "START_STREAM_ECHO",
]

SLAVE_ID = 9
STREAM_REGISTER = 410
STREAM_START_VALUE = 0x0200
STOP_BYTE = 0xFF
BAUDRATE = 19200
RATE_HZ = 100.0
FRAME_LENGTH = 16
SYNC = b"\x20\x4e"
FORCE_COUNTS_PER_N = 100.0
TORQUE_COUNTS_PER_NM = 1000.0

_FRAME = struct.Struct("<2s6hH")
_I16 = np.iinfo(np.int16)
_COUNTS_PER_UNIT = np.array([FORCE_COUNTS_PER_N] * 3 + [TORQUE_COUNTS_PER_NM] * 3)


@dataclass(frozen=True)
class RobotiqFrame:
    """One stream frame: force (3,) in N and torque (3,) in N·m, sensor frame."""

    force_n: np.ndarray
    torque_nm: np.ndarray


@dataclass(frozen=True)
class WriteRequest:
    """A Modbus function-16 request: write ``values`` (u16) from ``register`` on."""

    slave: int
    register: int
    values: tuple[int, ...]


def _crc_le(body: bytes) -> bytes:
    return CRC16_MODBUS(body).to_bytes(2, "little")


def encode_frame(force_n: Sequence[float], torque_nm: Sequence[float]) -> bytes:
    """16-byte stream frame; values are rounded to the wire resolution and clipped to int16."""
    f = np.clip(np.rint(np.asarray(force_n, float) * FORCE_COUNTS_PER_N), _I16.min, _I16.max)
    t = np.clip(np.rint(np.asarray(torque_nm, float) * TORQUE_COUNTS_PER_NM), _I16.min, _I16.max)
    body = SYNC + np.concatenate([f, t]).astype("<i2").tobytes()
    return body + _crc_le(body)


def decode_frame(frame: bytes) -> RobotiqFrame | None:
    """Decode a 16-byte frame; None if the length, sync or CRC is wrong."""
    if len(frame) != FRAME_LENGTH or frame[:2] != SYNC:
        return None
    _, *counts, crc = _FRAME.unpack(frame)
    if CRC16_MODBUS(frame[:14]) != crc:
        return None
    v = np.array(counts, dtype=float) / _COUNTS_PER_UNIT
    return RobotiqFrame(force_n=v[:3], torque_nm=v[3:])


def encode_write_registers(slave: int, register: int, values: Sequence[int]) -> bytes:
    """Modbus RTU function 16 request (registers big-endian, CRC little-endian)."""
    n = len(values)
    body = struct.pack(f">BBHHB{n}H", slave, 16, register, n, 2 * n, *values)
    return body + _crc_le(body)


def encode_write_echo(slave: int, register: int, count: int) -> bytes:
    """The 8-byte response to a function-16 request."""
    body = struct.pack(">BBHH", slave, 16, register, count)
    return body + _crc_le(body)


START_STREAM_REQUEST = encode_write_registers(SLAVE_ID, STREAM_REGISTER, [STREAM_START_VALUE])
START_STREAM_ECHO = encode_write_echo(SLAVE_ID, STREAM_REGISTER, 1)


class StreamCodec:
    """:class:`~slipstack.lib.protocols.stream.FrameCodec` of the stream frame."""

    sync = SYNC
    header_length = 2
    max_length = FRAME_LENGTH

    def frame_length(self, header: bytes) -> int:
        return FRAME_LENGTH

    def parse(self, frame: bytes) -> RobotiqFrame | None:
        return decode_frame(frame)


class WriteRequestCodec:
    """FrameCodec of function-16 requests to one slave (the device side reads these)."""

    header_length = 7
    max_length = 9 + 2 * 123  # Modbus limit: 123 registers per write

    def __init__(self, slave: int = SLAVE_ID) -> None:
        self.sync = bytes([slave, 16])

    def frame_length(self, header: bytes) -> int:
        count = int.from_bytes(header[4:6], "big")
        return 9 + header[6] if header[6] == 2 * count and 0 < count <= 123 else 0

    def parse(self, frame: bytes) -> WriteRequest | None:
        if CRC16_MODBUS(frame[:-2]) != int.from_bytes(frame[-2:], "little"):
            return None
        slave, _, register, count, _ = struct.unpack_from(">BBHHB", frame)
        return WriteRequest(slave, register, struct.unpack_from(f">{count}H", frame, 7))
