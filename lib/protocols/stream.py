"""Incremental stream deframer shared by every serial protocol.

Bytes arrive in arbitrary chunks; :class:`Deframer` buffers them, finds frames that
start with a codec's sync bytes, asks the codec how long the frame is and whether it
is intact, and returns the decoded values. It never raises on bad input.

More in docs/modules.md, `lib/protocols/stream.py`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Generic, Protocol, TypeVar

__all__ = ["FrameCodec", "Deframer", "DeframerCounts"]

T = TypeVar("T")
T_co = TypeVar("T_co", covariant=True)


class FrameCodec(Protocol[T_co]):
    """What a protocol tells the deframer.

    Attributes
    ----------
    sync: bytes every frame starts with (non-empty).
    header_length: bytes needed from the frame start (sync included) to know its length.
    max_length: largest frame length :meth:`frame_length` may return.
    """

    sync: bytes
    header_length: int
    max_length: int

    def frame_length(self, header: bytes) -> int:
        """Total frame length from its first ``header_length`` bytes; 0 if implausible."""
        ...

    def parse(self, frame: bytes) -> T_co | None:
        """Decoded value of a complete candidate frame, or None if its check fails."""
        ...


@dataclass
class DeframerCounts:
    """Running totals of a :class:`Deframer` (all counts, since construction/reset)."""

    frames: int = 0
    crc_errors: int = 0
    rejected_bytes: int = 0


class Deframer(Generic[T]):
    """Feed bytes, get decoded frames; resynchronises after garbage (module docstring)."""

    def __init__(self, codec: FrameCodec[T]) -> None:
        if not codec.sync or codec.header_length < len(codec.sync):
            raise ValueError("codec needs a non-empty sync and header_length >= len(sync)")
        self.codec = codec
        self.counts = DeframerCounts()
        self._buf = bytearray()

    @property
    def pending(self) -> int:
        """Bytes buffered but not yet part of a decoded or rejected frame."""
        return len(self._buf)

    def reset(self) -> None:
        """Drop buffered bytes (counted as rejected), e.g. after a reconnect."""
        self.counts.rejected_bytes += len(self._buf)
        self._buf.clear()

    def feed(self, data: bytes | bytearray | memoryview) -> list[T]:
        """Append *data* and return every frame it completes, in stream order."""
        buf = self._buf
        buf += data
        codec = self.codec
        sync, hlen = codec.sync, codec.header_length
        counts = self.counts
        out: list[T] = []
        pos = 0
        n = len(buf)
        while True:
            start = buf.find(sync, pos)
            if start < 0:
                # keep a tail that could be the beginning of a sync pattern
                keep = min(len(sync) - 1, n - pos)
                while keep and not sync.startswith(bytes(buf[n - keep:])):
                    keep -= 1
                counts.rejected_bytes += n - keep - pos
                pos = n - keep
                break
            counts.rejected_bytes += start - pos
            pos = start
            if n - pos < hlen:
                break
            length = codec.frame_length(bytes(buf[pos:pos + hlen]))
            if length <= 0 or length > codec.max_length:
                counts.rejected_bytes += 1
                pos += 1
                continue
            if n - pos < length:
                break
            value = codec.parse(bytes(buf[pos:pos + length]))
            if value is None:
                counts.crc_errors += 1
                counts.rejected_bytes += 1
                pos += 1
                continue
            out.append(value)
            counts.frames += 1
            pos += length
        if pos:
            del buf[:pos]
        return out
