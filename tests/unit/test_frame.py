"""messages/frame.py against frames built by hand with msgpack (not with our encoder)."""

from __future__ import annotations

import msgpack
import numpy as np
import pytest

from slipstack.lib.errors import DecodeError
from slipstack.messages import Diagnostics, Header, Wrench, decode, encode
from slipstack.messages.frame import (
    DIAGNOSTICS_TYPE, FrameHeader, SeqTracker, header_from_wire, peek_header, publisher_key, restamp, unpack_frame,
)


def _frame(type_name, version, header, body) -> bytes:
    return msgpack.packb([type_name, version, header, body])


@pytest.mark.parametrize("stamp, seq, pub", [(0, 0, 0), (5, 127, 128), (10**12, 70_000, 255),
                                              (2**63 - 1, 2**32 + 5, 2**16)])
def test_peek_header_reads_every_integer_width(stamp, seq, pub):
    payload = _frame("slipstack/Wrench", 1, [stamp, seq, pub, {"ft": 3}], [[1.0, 2.0], "x"])
    assert peek_header(payload) == FrameHeader("slipstack/Wrench", 1, stamp, seq, pub)


def test_peek_header_reads_long_type_names():
    name = "t" * 40  # str8, beyond fixstr's 31 characters
    assert peek_header(_frame(name, 3, [1, 2, 3, {}], [])) == FrameHeader(name, 3, 1, 2, 3)
    name = "u" * 300  # str16
    assert peek_header(_frame(name, 3, [1, 2, 3, {}], [])).type_name == name


@pytest.mark.parametrize("payload", [
    b"", b"\xc1", msgpack.packb([1, 2, 3]), msgpack.packb(["t", 1, [1, 2], []]),
    msgpack.packb(["t", 1, [1.5, 2, 3, {}], []]), msgpack.packb([7, 1, [1, 2, 3, {}], []]),
    msgpack.packb(["t", 1, [1, 2, 3, {}], []])[:-4],
])
def test_peek_header_refuses_what_is_not_a_frame(payload):
    assert peek_header(payload) is None


def test_peek_header_agrees_with_the_encoder():
    msg = encode(Wrench(force=np.ones(3), torque=np.zeros(3), header=Header(123_456_789, 42, 123_999_000, {"ft": 1})))
    assert peek_header(msg) == FrameHeader(Wrench.TYPE, Wrench.VERSION, 123_456_789, 42, 123_999_000)


def test_restamp_shifts_every_stamp_and_nothing_else():
    body = [msgpack.ExtType(1, b"\x03<f8\x01\x03\x00\x00\x00" + np.arange(3.0).tobytes()), "kept"]
    payload = _frame("slipstack/X", 2, [100, 7, 150, {"ft": 90, "tactile": 80}], body)
    type_name, version, header, out_body = msgpack.unpackb(restamp(payload, 1_000), strict_map_key=False)
    assert (type_name, version, header) == ("slipstack/X", 2, [1_100, 7, 1_150, {"ft": 1_090, "tactile": 1_080}])
    assert out_body == body


def test_restamp_refuses_a_payload_without_a_header():
    with pytest.raises(DecodeError, match="payload: expected"):
        restamp(_frame("slipstack/X", 1, [1, 2], []), 5)
    with pytest.raises(DecodeError, match="payload: expected"):
        restamp(msgpack.packb([1, 2, 3]), 5)


def test_unpack_frame_and_header_from_wire_name_what_is_wrong():
    with pytest.raises(DecodeError, match=r"payload: expected \[type, version, header, body\]"):
        unpack_frame(msgpack.packb({"a": 1}))
    with pytest.raises(DecodeError, match=r"T\.header\.seq: expected int, got str"):
        header_from_wire([1, "2", 3, {}], "T")
    with pytest.raises(DecodeError, match=r"T\.header\.pub_ns: must be within"):
        header_from_wire([1, 2, -3, {}], "T")
    with pytest.raises(DecodeError, match=r"T\.header\.stamp_ns: expected int, got bool"):
        header_from_wire([True, 2, 3, {}], "T")
    with pytest.raises(DecodeError, match=r"T\.header\.seq: must be within"):
        header_from_wire([1, 2**63, 3, {}], "T")
    with pytest.raises(DecodeError, match=r"T\.header\.sources: expected a map"):
        header_from_wire([1, 2, 3, []], "T")
    with pytest.raises(DecodeError, match=r"T\.header\.sources: expected a map"):
        header_from_wire([1, 2, 3, {"ft": -1}], "T")
    with pytest.raises(DecodeError, match=r"T\.header\.sources: at most 32 entries"):
        header_from_wire([1, 2, 3, {f"s{k}": k for k in range(33)}], "T")
    assert header_from_wire([1, 2, 3, {"ft": 4}], "T") == Header(1, 2, 3, {"ft": 4})


def test_publisher_key_names_the_node_of_diagnostics_only():
    assert DIAGNOSTICS_TYPE == Diagnostics.TYPE
    diag = _frame(DIAGNOSTICS_TYPE, 1, [1, 2, 3, {}], ["fusion", "ok"])
    assert publisher_key("diagnostics", diag, peek_header(diag)) == "diagnostics/fusion"
    wrench = _frame("slipstack/Wrench", 1, [1, 2, 3, {}], ["fusion"])
    assert publisher_key("ft/wrench", wrench, peek_header(wrench)) == "ft/wrench"
    assert publisher_key("x", b"\xc1", None) == "x"


def test_seq_tracker_counts_gaps_per_stream_and_restarts_as_no_loss():
    t = SeqTracker()
    gaps = [t.update(s, "a") for s in (0, 1, 4, 5)] + [t.update(s, "b") for s in (10, 11, 13)]
    assert gaps == [0, 0, 2, 0, 0, 0, 1] and t.lost == 3
    assert t.update(0, "a") == 0 and t.restarts == 1 and t.lost == 3  # a respawned publisher
    assert t.update(3, "a") == 2


def test_seq_tracker_skipped_frames_fill_the_gap():
    t = SeqTracker()
    t.update(0)
    assert t.update(5, skipped=3) == 1 and t.lost == 1
    assert t.update(9, skipped=5) == 0  # more skipped than missing: no loss


def test_seq_tracker_forgets_the_oldest_stream_beyond_its_bound():
    t = SeqTracker(max_streams=2)
    t.update(0, "a"), t.update(0, "b"), t.update(0, "c")  # "a" forgotten
    assert t.update(9, "a") == 0 and t.update(9, "c") == 8
    t.forget("c")
    assert t.update(20, "c") == 0


def test_decode_of_a_hand_built_frame_uses_the_frame_header():
    vector = msgpack.ExtType(1, b"\x03<f8\x01\x03\x00\x00\x00" + np.arange(3.0).tobytes())
    payload = _frame(Wrench.TYPE, Wrench.VERSION, [5, 6, 7, {"ft": 4}], [vector, vector, "pad", 3, "ok"])
    msg = decode(payload, Wrench)
    assert msg.header == Header(5, 6, 7, {"ft": 4}) and msg.force.tolist() == [0.0, 1.0, 2.0]
    assert (msg.frame, msg.device_seq, msg.status) == ("pad", 3, "ok")
