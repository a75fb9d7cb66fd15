"""Fuzz the deframer and decoders: random streams, truncated frames, flipped bits,
garbage bursts between good frames, arbitrary chunking.

Guarantees checked:

More in docs/modules.md, `tests/property/test_codec_fuzz.py`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from hypothesis import given, settings, strategies as st

from slipstack.lib.protocols import ati_rdt, bota, dsacon32, m1616, robotiq
from slipstack.lib.protocols.framed import FramedCodec, FramedFormat, decode_frame, encode_frame as encode_framed
from slipstack.lib.protocols.stream import Deframer, FrameCodec

SETTINGS = settings(max_examples=120, deadline=None, derandomize=True)

i16 = st.integers(-(2**15), 2**15 - 1)
f32 = st.floats(width=32, allow_nan=False, allow_infinity=False)
U12_FMT = FramedFormat(header=b"\x5a\xa5", rows=4, cols=4, dtype="u12", endian="le")
CRC_FMT = FramedFormat(header=b"\x5a", rows=3, cols=5, dtype="u8", checksum="crc16")
CCITT_FMT = FramedFormat(header=b"\xa5\x5a", rows=4, cols=4, dtype="u16", endian="be", checksum="crc16-ccitt")


@dataclass(frozen=True)
class Case:
    """A protocol under fuzz: a codec, a strategy of good frames, and how to turn a
    decoded value back into its bytes (so recovered == sent is a byte comparison)."""

    codec: Callable[[], FrameCodec]
    frames: st.SearchStrategy[bytes]
    reencode: Callable[[object], bytes]
    exact: bool = True  # False: good frames all recovered, junk may also yield frames


CASES = {
    "robotiq": Case(
        robotiq.StreamCodec,
        st.tuples(st.lists(i16, min_size=6, max_size=6)).map(
            lambda t: robotiq.encode_frame(np.array(t[0][:3]) / 100, np.array(t[0][3:]) / 1000)),
        lambda d: robotiq.encode_frame(d.force_n, d.torque_nm),
    ),
    "bota": Case(
        bota.StreamCodec,
        st.builds(lambda v, s, ts, temp: bota.encode_frame(v[:3], v[3:], timestamp_us=ts, status=s, temperature_c=temp),
                  st.lists(f32, min_size=6, max_size=6), st.integers(0, 15), st.integers(0, 2**32 - 1), f32),
        lambda d: bota.encode_frame(d.force_n, d.torque_nm, timestamp_us=d.timestamp_us, status=d.status,
                                    temperature_c=d.temperature_c),
    ),
    "dsacon32": Case(
        lambda: dsacon32.PacketCodec(allow_empty=False),
        st.builds(dsacon32.encode_packet, st.sampled_from([0x00, 0x03, 0x0B]), st.binary(min_size=1, max_size=60)),
        lambda p: dsacon32.encode_packet(p.id, p.payload),
    ),
    "framed-crc16": Case(
        lambda: FramedCodec(CRC_FMT),
        st.lists(st.integers(0, 255), min_size=15, max_size=15).map(lambda v: encode_framed(CRC_FMT, np.array(v))),
        lambda c: encode_framed(CRC_FMT, c),
    ),
    "framed-ccitt": Case(
        lambda: FramedCodec(CCITT_FMT),
        st.binary(min_size=32, max_size=32).map(lambda b: encode_framed(CCITT_FMT, np.frombuffer(b, "<u2"))),
        lambda c: encode_framed(CCITT_FMT, c),
    ),
    "framed-u12": Case(
        lambda: FramedCodec(U12_FMT),
        st.lists(st.integers(0, 4095), min_size=16, max_size=16).map(lambda v: encode_framed(U12_FMT, np.array(v))),
        lambda c: encode_framed(U12_FMT, c),
        exact=False,
    ),
}


@st.composite
def garbage(draw, frames: st.SearchStrategy[bytes], sync: bytes) -> bytes:
    """A burst of junk: random bytes, sync patterns, truncated and bit-flipped frames."""
    parts = draw(st.lists(st.one_of(
        st.binary(max_size=12),
        st.just(sync),
        frames.flatmap(lambda f: st.integers(0, len(f) - 1).map(lambda n: f[:n])),
        frames.flatmap(lambda f: st.integers(0, 8 * len(f) - 1).map(
            lambda bit: f[:bit // 8] + bytes([f[bit // 8] ^ (1 << bit % 8)]) + f[bit // 8 + 1:])),
    ), max_size=4))
    return b"".join(parts)


def _stream(draw, case: Case, codec: FrameCodec) -> tuple[list[bytes], list[bytes]]:
    good = draw(st.lists(case.frames, min_size=1, max_size=6))
    junk = [draw(garbage(case.frames, codec.sync)) for _ in range(len(good) + 1)]
    return good, junk


def _feed_in_chunks(d: Deframer, data: bytes, cuts: list[int]) -> list:
    out, prev = [], 0
    for c in sorted({min(c, len(data)) for c in cuts}) + [len(data)]:
        out += d.feed(data[prev:c])
        prev = c
    return out


@SETTINGS
@given(data=st.data(), name=st.sampled_from(sorted(CASES)))
def test_checked_formats_recover_every_good_frame(data: st.DataObject, name: str) -> None:
    case = CASES[name]
    codec = case.codec()
    good, junk = _stream(data.draw, case, codec)
    stream = b"".join(j + g for j, g in zip(junk, good)) + junk[-1] + bytes(codec.max_length)
    cuts = data.draw(st.lists(st.integers(0, len(stream)), max_size=8))
    d = Deframer(codec)
    out = [case.reencode(v) for v in _feed_in_chunks(d, stream, cuts)]
    if case.exact:
        assert out == good
        assert d.counts.rejected_bytes + d.pending == len(stream) - sum(map(len, good))
    else:  # a sync in the junk followed by in-range bytes is a frame for a range check
        rest = iter(out)
        assert all(any(g == o for o in rest) for g in good), "a good frame was lost"


@SETTINGS
@given(data=st.data())
def test_m1616_weaker_guarantee(data: st.DataObject) -> None:
    fmt = m1616.FORMAT
    frames = st.binary(min_size=512, max_size=512).map(
        lambda b: encode_framed(fmt, np.frombuffer(b, "<u2") & 0x0FFF))
    case = Case(lambda: FramedCodec(fmt), frames, lambda c: encode_framed(fmt, c))
    codec = case.codec()
    good, junk = _stream(data.draw, case, codec)
    # tag frame i with count i+1 at taxel 0: distinct, so "which was lost" is well defined
    good = [encode_framed(fmt, np.r_[i + 1, decode_frame(fmt, g).ravel()[1:]]) for i, g in enumerate(good)]
    stream = b"".join(j + g for j, g in zip(junk, good)) + junk[-1] + bytes(codec.max_length)
    d = Deframer(codec)
    out = [case.reencode(v) for v in _feed_in_chunks(d, stream, data.draw(st.lists(st.integers(0, len(stream)))))]
    recovered = [g for g in out if g in good]
    assert recovered == [g for g in good if g in recovered]  # in order, no duplicates
    for j, g in zip(junk, good):
        if g not in recovered:
            assert fmt.header in j + g[:2], "a frame was lost without a header pattern before it"


@settings(max_examples=200, deadline=None)
@given(blob=st.binary(max_size=600), name=st.sampled_from(sorted(CASES)))
def test_random_bytes_never_raise(blob: bytes, name: str) -> None:
    d = Deframer(CASES[name].codec())
    d.feed(blob)
    d.feed(blob[::-1])
    assert d.counts.rejected_bytes + d.pending + d.counts.frames * 0 <= 2 * len(blob)
    for decode in (robotiq.decode_frame, bota.decode_frame):
        decode(blob)
    dsacon32.decode_frame_payload(blob, 16)
    dsacon32.decode_matrix_info(blob)


@settings(max_examples=150, deadline=None)
@given(datagram=st.binary(max_size=200))
def test_rdt_datagrams(datagram: bytes) -> None:
    records = ati_rdt.decode_records(datagram)
    if len(datagram) and len(datagram) % 36 == 0:
        assert b"".join(ati_rdt.encode_record(r.rdt_sequence, r.ft_sequence, r.status, r.counts)
                        for r in records) == datagram
    else:
        assert records is None
    ati_rdt.decode_request(datagram[:8])
