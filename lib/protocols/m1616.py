"""16×16 piezoresistive tactile module ("M1616"), a preset of the framed format.

Source: public serial monitor for the module (see docs/protocols.md §7). 115200 baud;
frame = header ``AA AB AC``, 256 × u16 big-endian row-major, then 4 trailing bytes
of unknown meaning (not verified; skipped on decode, zeros on encode). There is no
checksum, so only the weaker recovery guarantee of
:mod:`~slipstack.lib.protocols.framed` holds.

Note: at 115200 baud a 519-byte frame takes 45 ms, so a real module cannot exceed
about 22 frames/s; faster rates are only possible over a pty or USB CDC link.
"""

from __future__ import annotations

from .framed import FramedFormat

__all__ = ["FORMAT"]

FORMAT = FramedFormat(
    header=b"\xaa\xab\xac", rows=16, cols=16, dtype="u16", endian="be", order="row",
    trailer=4, checksum="none",
)
