"""Generic framed tactile format: a configurable fixed-length frame.

Many home-made and low-cost tactile boards stream a matrix as::

    header (fixed bytes) | rows*cols values | trailer (opaque bytes) | checksum

More in docs/modules.md, `lib/protocols/framed.py`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np

from ..errors import ConfigError
from .crc import CRC16_CCITT_FALSE, CRC16_MODBUS

__all__ = ["FramedFormat", "FramedCodec", "encode_frame", "decode_frame"]

Dtype = Literal["u8", "u16", "u12"]
_DTYPES = ("u8", "u16", "u12")
_CHECKSUMS = ("none", "sum8", "crc16", "crc16-ccitt")


@dataclass(frozen=True)
class FramedFormat:
    """Layout of a framed tactile stream (module docstring)."""

    header: bytes
    rows: int
    cols: int
    dtype: Dtype = "u16"
    endian: Literal["le", "be"] = "le"
    order: Literal["row", "col"] = "row"
    trailer: int = 0
    checksum: Literal["none", "sum8", "crc16", "crc16-ccitt"] = "none"

    def __post_init__(self) -> None:
        if not self.header:
            raise ConfigError("framed format: header must be at least one byte (hex, e.g. header=aabbcc)")
        if self.rows < 1 or self.cols < 1:
            raise ConfigError(f"framed format: rows and cols must be >= 1, got {self.rows}x{self.cols}")
        if self.dtype not in _DTYPES:
            raise ConfigError(f"framed format: dtype must be one of {_DTYPES}, got {self.dtype!r}")
        if self.endian not in ("le", "be"):
            raise ConfigError(f"framed format: endian must be 'le' or 'be', got {self.endian!r}")
        if self.order not in ("row", "col"):
            raise ConfigError(f"framed format: order must be 'row' or 'col', got {self.order!r}")
        if self.checksum not in _CHECKSUMS:
            raise ConfigError(f"framed format: checksum must be one of {_CHECKSUMS}, got {self.checksum!r}")
        if self.trailer < 0:
            raise ConfigError(f"framed format: trailer must be >= 0, got {self.trailer}")

    @property
    def wire_dtype(self) -> np.dtype:
        if self.dtype == "u8":
            return np.dtype("u1")
        return np.dtype("<u2" if self.endian == "le" else ">u2")

    @property
    def payload_length(self) -> int:
        return self.rows * self.cols * self.wire_dtype.itemsize

    @property
    def checksum_length(self) -> int:
        return {"none": 0, "sum8": 1, "crc16": 2, "crc16-ccitt": 2}[self.checksum]

    @property
    def length(self) -> int:
        """Total frame length in bytes."""
        return len(self.header) + self.payload_length + self.trailer + self.checksum_length

    @property
    def max_count(self) -> int:
        return {"u8": 0xFF, "u12": 0x0FFF, "u16": 0xFFFF}[self.dtype]


def _checksum(fmt: FramedFormat, body: bytes) -> bytes:
    if fmt.checksum == "sum8":
        return bytes([sum(body) & 0xFF])
    if fmt.checksum == "crc16":
        return CRC16_MODBUS(body).to_bytes(2, "little")
    if fmt.checksum == "crc16-ccitt":
        return CRC16_CCITT_FALSE(body).to_bytes(2, "big")
    return b""


def encode_frame(fmt: FramedFormat, counts: np.ndarray, trailer: bytes | None = None) -> bytes:
    """Frame for *counts* (rows, cols); values clipped to the format's range."""
    c = np.clip(np.asarray(counts).reshape(fmt.rows, fmt.cols), 0, fmt.max_count)
    if fmt.order == "col":
        c = c.T
    tail = bytes(fmt.trailer) if trailer is None else trailer
    if len(tail) != fmt.trailer:
        raise ValueError(f"trailer must be {fmt.trailer} bytes")
    body = fmt.header + np.ascontiguousarray(c).astype(fmt.wire_dtype).tobytes() + tail
    return body + _checksum(fmt, body)


def decode_frame(fmt: FramedFormat, frame: bytes) -> np.ndarray | None:
    """Counts (rows, cols) uint16 of one frame; None if header, length or check fail."""
    if len(frame) != fmt.length or not frame.startswith(fmt.header):
        return None
    n_check = fmt.checksum_length
    if n_check and frame[-n_check:] != _checksum(fmt, frame[:-n_check]):
        return None
    v = np.frombuffer(frame, fmt.wire_dtype, fmt.rows * fmt.cols, len(fmt.header))
    if fmt.dtype == "u12" and int(v.max()) > 0x0FFF:
        return None
    if fmt.order == "col":
        return v.reshape(fmt.cols, fmt.rows).T.astype(np.uint16)
    return v.reshape(fmt.rows, fmt.cols).astype(np.uint16)


class FramedCodec:
    """:class:`~slipstack.lib.protocols.stream.FrameCodec` for a :class:`FramedFormat`."""

    def __init__(self, fmt: FramedFormat) -> None:
        self.fmt = fmt
        self.sync = fmt.header
        self.header_length = len(fmt.header)
        self.max_length = fmt.length

    def frame_length(self, header: bytes) -> int:
        return self.max_length

    def parse(self, frame: bytes) -> np.ndarray | None:
        return decode_frame(self.fmt, frame)

