"""Weiss Robotics DSACON32 tactile controller (DSA 9205/9335, SCHUNK SDH pads).

Sources: SCHUNK SDHLibrary ``dsa.cpp``/``dsa.h``; RobWork ``DSACON32.cpp``
(see docs/protocols.md §6). 115200 baud. Every packet, both directions, little-endian::

    AA AA AA | u8 id | u16 payload size | payload | u16 CRC (only if size > 0)

More in docs/modules.md, `lib/protocols/dsacon32.py`.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from enum import IntEnum, IntFlag

import numpy as np

from .crc import CRC16_DSACON32

__all__ = [
    "BAUDRATE", "PacketId", "AcquisitionFlags", "Packet", "MatrixInfo", "DsaFrame",
    "encode_packet", "encode_configure_acquisition", "decode_configure_acquisition",
    "encode_query_matrix_info", "encode_matrix_info", "decode_matrix_info",
    "encode_error_reply", "decode_error_reply", "encode_frame_payload",
    "decode_frame_payload", "PacketCodec",
]

SYNC = b"\xaa\xaa\xaa"
BAUDRATE = 115200
MATRIX_INFO_LENGTH = 52
_HEADER = struct.Struct("<3sBH")
_MATRIX_INFO = struct.Struct("<HffHH")
_FRAME_HEAD = struct.Struct("<IB")


class PacketId(IntEnum):
    FRAME = 0x00
    CONTROLLER_INFO = 0x01
    SENSOR_INFO = 0x02
    CONFIGURE_ACQUISITION = 0x03
    MATRIX_INFO = 0x0B


class AcquisitionFlags(IntFlag):
    RLE = 0x01
    INTERNAL_TRIGGER = 0x20
    SINGLE_SHOT = 0x40
    ACQUIRE = 0x80


@dataclass(frozen=True)
class Packet:
    """A packet with a valid CRC: its id and payload."""

    id: int
    payload: bytes


@dataclass(frozen=True)
class MatrixInfo:
    """Decoded part of a matrix-info reply (texel sizes in m)."""

    error: int
    texel_width_m: float
    texel_height_m: float
    cells_x: int
    cells_y: int


@dataclass(frozen=True)
class DsaFrame:
    """A decoded frame: controller time (ms) and all taxels (n,) uint16 in wire order."""

    timestamp_ms: int
    counts: np.ndarray


def encode_packet(packet_id: int, payload: bytes = b"") -> bytes:
    """Packet with sync, header and (if the payload is non-empty) CRC."""
    head = bytes([packet_id]) + len(payload).to_bytes(2, "little")
    if not payload:
        return SYNC + head
    return SYNC + head + payload + CRC16_DSACON32(head + payload).to_bytes(2, "little")


def encode_configure_acquisition(flags: int, fps: int) -> bytes:
    """Host command 0x03; ``flags=0, fps=0`` stops push mode."""
    return encode_packet(PacketId.CONFIGURE_ACQUISITION, struct.pack("<BH", flags, fps))


def decode_configure_acquisition(payload: bytes) -> tuple[int, int] | None:
    """(flags, fps) of a host command 0x03 payload; None if not 3 bytes."""
    return struct.unpack("<BH", payload) if len(payload) == 3 else None


def encode_query_matrix_info(index: int) -> bytes:
    """Host command 0x0B for matrix *index*."""
    return encode_packet(PacketId.MATRIX_INFO, bytes([index]))


def encode_matrix_info(info: MatrixInfo) -> bytes:
    """Device reply 0x0B (52-byte payload, undecoded fields zero)."""
    head = _MATRIX_INFO.pack(info.error, info.texel_width_m * 1e3, info.texel_height_m * 1e3, info.cells_x, info.cells_y)
    return encode_packet(PacketId.MATRIX_INFO, head.ljust(MATRIX_INFO_LENGTH, b"\0"))


def decode_matrix_info(payload: bytes) -> MatrixInfo | None:
    """Matrix info from a reply payload; None if shorter than its decoded fields."""
    if len(payload) < _MATRIX_INFO.size:
        return None
    err, w_mm, h_mm, cx, cy = _MATRIX_INFO.unpack_from(payload)
    return MatrixInfo(err, w_mm * 1e-3, h_mm * 1e-3, cx, cy)


def encode_error_reply(packet_id: int, error: int = 0) -> bytes:
    """Device reply carrying only a u16 error code (e.g. to command 0x03)."""
    return encode_packet(packet_id, error.to_bytes(2, "little"))


def decode_error_reply(payload: bytes) -> int | None:
    """Error code of a 2-byte reply payload (0 = OK); None if not 2 bytes."""
    return int.from_bytes(payload, "little") if len(payload) == 2 else None


def _rle_encode(values: np.ndarray) -> np.ndarray:
    units = []
    i, n = 0, len(values)
    while i < n:
        j = i + 1
        while j < n and j - i < 15 and values[j] == values[i]:
            j += 1
        units.append(((j - i) << 12) | int(values[i]))
        i = j
    return np.array(units, dtype="<u2")


def encode_frame_payload(timestamp_ms: int, counts: np.ndarray, *, rle: bool = False) -> bytes:
    """Frame payload for all taxels *counts* (any shape, flattened row-major, 0..4095)."""
    # np.clip's order (max, then min) without its Python wrapper: 3 µs of a 250 Hz frame
    v = np.minimum(np.maximum(np.asarray(counts).ravel(), 0), 0x0FFF).astype(np.uint16)
    body = _rle_encode(v) if rle else v.astype("<u2")
    return _FRAME_HEAD.pack(timestamp_ms & 0xFFFFFFFF, 1 if rle else 0) + body.tobytes()


def decode_frame_payload(payload: bytes, n_cells: int) -> DsaFrame | None:
    """Decode a frame payload holding *n_cells* taxels; None if sizes disagree."""
    if len(payload) < _FRAME_HEAD.size or (len(payload) - _FRAME_HEAD.size) % 2:
        return None
    stamp, flags = _FRAME_HEAD.unpack_from(payload)
    units = np.frombuffer(payload, "<u2", offset=_FRAME_HEAD.size)
    if flags & 1:
        reps = units >> 12
        if int(reps.sum()) != n_cells:
            return None
        counts = np.repeat(units & 0x0FFF, reps)
    else:
        if len(units) != n_cells:
            return None
        counts = units.astype(np.uint16)
    return DsaFrame(stamp, counts)


class PacketCodec:
    """FrameCodec of DSACON32 packets (either direction); yields :class:`Packet`.

    ``max_length`` bounds the payload a header may announce, so a false sync in
    garbage cannot stall the stream for long; a driver tightens it once it knows
    the frame size. Empty packets carry no CRC, so a false sync followed by two
    zero bytes would pass as one: the host side, whose replies all have a payload,
    sets ``allow_empty=False``; the device side must accept empty queries.
    """

    sync = SYNC
    header_length = _HEADER.size

    def __init__(self, max_payload: int = 4096, *, allow_empty: bool = True) -> None:
        self.max_length = _HEADER.size + max_payload + 2
        self.allow_empty = allow_empty

    def frame_length(self, header: bytes) -> int:
        size = int.from_bytes(header[4:6], "little")
        if size == 0:
            return _HEADER.size if self.allow_empty else 0
        return _HEADER.size + size + 2

    def parse(self, frame: bytes) -> Packet | None:
        if len(frame) == _HEADER.size:
            return Packet(frame[3], b"")
        if CRC16_DSACON32(frame[3:-2]) != int.from_bytes(frame[-2:], "little"):
            return None
        return Packet(frame[3], bytes(frame[6:-2]))
