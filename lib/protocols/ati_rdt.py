"""ATI Net F/T and Axia80 Raw Data Transfer (RDT) over UDP.

Sources: ATI Net F/T manual 9620-05, Axia80 manual, netft_utils
``netft_rdt_driver.cpp`` (see docs/protocols.md §3). All fields big-endian.

Request (8 bytes, to UDP port 49152)::

    u16 0x1234 | u16 command | u32 sample count (0 = endless)

More in docs/modules.md, `lib/protocols/ati_rdt.py`.
"""

from __future__ import annotations

import struct
from enum import IntEnum
from typing import NamedTuple, Sequence

import numpy as np

__all__ = [
    "PORT", "RECORD_LENGTH", "RATE_HZ", "Command", "RdtRecord", "encode_request", "decode_request",
    "encode_record", "decode_records", "to_wrench", "follows", "SEQUENCE_WINDOW", "FIRST_RECORDS", "FT_WINDOW",
]

PORT = 49152
HEADER = 0x1234
RECORD_LENGTH = 36
RATE_HZ = 7000.0

SEQUENCE_WINDOW = 1 << 14
"""Largest rdt_sequence step accepted (records lost in between): 2.3 s at 7 kHz."""
FIRST_RECORDS = 64
"""A stream (re)started by a start request: its first record numbers at most this."""
FT_WINDOW = 1 << 24
"""Largest ft_sequence step accepted between two records: 40 min at 7 kHz."""
_WRAP = 1 << 32
_INT32_MIN, _INT32_MAX = float(-(2**31)), float(2**31 - 1)

_REQUEST = struct.Struct(">HHI")
_RECORD = struct.Struct(">III6i")


class Command(IntEnum):
    """RDT request commands."""

    STOP = 0x0000
    REALTIME = 0x0002
    BUFFERED = 0x0003
    MULTI_UNIT = 0x0004
    RESET_LATCH = 0x0041
    BIAS = 0x0042


class RdtRecord(NamedTuple):
    """One RDT record; ``counts`` (6,) int64 are Fx Fy Fz Tx Ty Tz in sensor counts.

    A named tuple: a driver decodes one per sample (7 kHz for a real sensor), and a frozen
    dataclass took three times as long to build."""

    rdt_sequence: int
    ft_sequence: int
    status: int
    counts: np.ndarray


def encode_request(command: int, sample_count: int = 0) -> bytes:
    """8-byte RDT request."""
    return _REQUEST.pack(HEADER, command, sample_count)


def decode_request(data: bytes) -> tuple[int, int] | None:
    """(command, sample count) of a request; None if not an 8-byte 0x1234 request."""
    if len(data) != _REQUEST.size:
        return None
    header, command, count = _REQUEST.unpack(data)
    return (command, count) if header == HEADER else None


def encode_record(rdt_sequence: int, ft_sequence: int, status: int, counts: Sequence[float]) -> bytes:
    """36-byte record; counts are clipped to int32 and rounded half to even; sequences wrap at
    2**32. A NaN count raises ValueError.

    Six values in plain Python: numpy's per-call overhead made this 8 µs a record, paid by
    the simulated sensor 7 000 times a second at the RDT rate."""
    values = counts.tolist() if isinstance(counts, np.ndarray) else counts
    c = [round(min(max(float(v), _INT32_MIN), _INT32_MAX)) for v in values]
    return _RECORD.pack(rdt_sequence & 0xFFFFFFFF, ft_sequence & 0xFFFFFFFF, status & 0xFFFFFFFF, *c)


def decode_records(datagram: bytes) -> list[RdtRecord] | None:
    """Records of one datagram; None unless its length is a positive multiple of 36."""
    n = len(datagram)
    if n == 0 or n % RECORD_LENGTH:
        return None
    return [
        RdtRecord(r[0], r[1], r[2], np.array(r[3:], dtype=np.int64))
        for r in _RECORD.iter_unpack(datagram)
    ]


def follows(previous: RdtRecord | None, record: RdtRecord) -> bool:
    """Whether ``record`` can be the next record of the stream whose last accepted record
    was ``previous`` (``None``: none since our start request).

    Accepted: the first records of a (re)started stream (rdt_sequence in
    1 … :data:`FIRST_RECORDS`), or rdt_sequence ahead by 1 … :data:`SEQUENCE_WINDOW`
    (counters wrap at 2**32); and after a previous record, ft_sequence ahead by
    1 … :data:`FT_WINDOW`.
    """
    seq = record.rdt_sequence
    if previous is None:
        return 1 <= seq <= FIRST_RECORDS
    if not 0 < (record.ft_sequence - previous.ft_sequence) % _WRAP <= FT_WINDOW:
        return False
    return 1 <= seq <= FIRST_RECORDS or 0 < (seq - previous.rdt_sequence) % _WRAP <= SEQUENCE_WINDOW


def to_wrench(record: RdtRecord, counts_per_force: float, counts_per_torque: float) -> tuple[np.ndarray, np.ndarray]:
    """(force N (3,), torque N·m (3,)) of a record, sensor frame."""
    return record.counts[:3] / counts_per_force, record.counts[3:] / counts_per_torque
