"""The WSG 50's binary messages: the manual's example bytes, framing and recovery (docs/protocols.md §9)."""

from __future__ import annotations

import struct

import pytest

from slipstack.lib.protocols import wsg
from slipstack.lib.protocols.stream import Deframer

# (command, payload) -> the bytes the WSG command set reference prints for them
MANUAL_EXAMPLES = [
    ((0x01, b""), "AA AA AA 01 00 00 E8 10"),
    ((0x01, b"\x12\x34"), "AA AA AA 01 02 00 12 34 6D 66"),
    ((0x20, b"\x00\x00"), "AA AA AA 20 02 00 00 00 B3 FD"),  # homing acknowledged, E_SUCCESS
    ((0x90, b"\x0e\x00"), "AA AA AA 90 02 00 0E 00 FD 02"),  # an unknown command: E_CMD_UNKNOWN
    ((0x30, b"\x00\x00" + struct.pack("<f", 150.0)), "AA AA AA 30 06 00 00 00 00 00 16 43 DC CB"),
    ((0x21, b"\x1a\x00"), "AA AA AA 21 02 00 1A 00 67 CB"),  # E_CMD_PENDING
    ((0x21, b"\x00\x00"), "AA AA AA 21 02 00 00 00 28 04"),
]


@pytest.mark.parametrize("message, printed", MANUAL_EXAMPLES)
def test_messages_are_the_manuals_bytes(message, printed):
    assert wsg.encode_message(*message) == bytes.fromhex(printed)


def test_the_crc_over_a_whole_message_with_its_crc_is_zero():
    for _, printed in MANUAL_EXAMPLES:
        from slipstack.lib.protocols.crc import CRC16_DSACON32
        assert CRC16_DSACON32(bytes.fromhex(printed)) == 0


def test_replies_carry_the_status_then_the_values():
    m = wsg.MessageCodec().parse(wsg.encode_reply(wsg.Command.GET_FORCE_LIMIT, wsg.Status.E_SUCCESS,
                                                  struct.pack("<f", 12.5)))
    status, values = wsg.reply_status(m.payload)
    assert (m.id, status, wsg.f32(values)) == (wsg.Command.GET_FORCE_LIMIT, 0, 12.5)
    assert wsg.reply_status(b"\x00") is None and wsg.f32(b"\x00\x00") is None
    assert wsg.Status.E_CMD_UNKNOWN == 14 and wsg.Status.E_CMD_PENDING == 26 and wsg.Status.E_RANGE_ERROR == 28


def test_commands_the_driver_sends():
    assert wsg.set_force_limit(20.0)[3:6] == bytes([0x32, 4, 0]) and wsg.set_force_limit(20.0)[6:10] == struct.pack("<f", 20.0)
    assert wsg.grasp(20.0, 15.0)[6:14] == struct.pack("<ff", 20.0, 15.0)
    assert wsg.ack_fast_stop()[6:9] == b"ack"
    assert wsg.get_force(10)[6:9] == bytes([wsg.AUTO_UPDATE, 10, 0]) and wsg.get_force()[6:9] == bytes(3)
    assert wsg.get_grasping_state()[3] == 0x41 and wsg.get_force_limit()[3:6] == bytes([0x33, 0, 0])


def test_a_message_behind_garbage_and_a_broken_one_is_recovered():
    good = wsg.set_force_limit(12.0)
    broken = bytearray(wsg.get_force(5))
    broken[-1] ^= 0xFF
    d = Deframer(wsg.MessageCodec())
    out = []
    stream = b"\xaa\xaa\x00junk\xaa\xaa\xaa" + bytes(broken) + good  # a false preamble, then a broken message
    for i in range(0, len(stream), 3):  # in arbitrary chunks
        out += d.feed(stream[i:i + 3])
    assert out == [wsg.Message(0x32, good[6:-2])]
    assert d.counts.crc_errors >= 1 and d.counts.rejected_bytes > 0
