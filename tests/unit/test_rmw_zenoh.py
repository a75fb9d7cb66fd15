"""rmw_zenoh's names and attachment (lib/rmw_zenoh.py) against the examples of its docs/design.md
(the layout since rmw_zenoh_cpp 0.2.4 / 0.6.0), and type hashes against the one it prints."""

from __future__ import annotations

import struct

import pytest

from slipstack.lib.rmw_zenoh import (Attachment, dds_type_name, endpoint_token, mangle, node_token, qos_text,
                                     topic_key, valid_ros_name)

STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"  # design.md's std_msgs/String
ZID = "aac3178e146ba6f1fc6e6a4085e77f21"


def test_topic_keys_as_in_the_design_document() -> None:
    assert topic_key(0, "/chatter", "std_msgs/msg/String", STRING_HASH) == \
        f"0/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    assert topic_key(0, "/robot1/chatter", "std_msgs/msg/String", STRING_HASH) == \
        f"0/robot1/chatter/std_msgs::msg::dds_::String_/{STRING_HASH}"
    assert dds_type_name("slipstack_msgs/msg/Slip") == "slipstack_msgs::msg::dds_::Slip_"


def test_liveliness_tokens_as_in_the_design_document() -> None:
    assert node_token(2, ZID, 0, "/", "listener") == f"@ros2_lv/2/{ZID}/0/0/NN/%/%/listener"
    assert endpoint_token(2, ZID, 0, 10, "MS", "/", "listener", "/chatter", "std_msgs/msg/String", STRING_HASH,
                          qos_text(depth=10)) == (
        f"@ros2_lv/2/{ZID}/0/10/MS/%/%/listener/%chatter/std_msgs::msg::dds_::String_/{STRING_HASH}/::,10:,:,:,,")
    assert mangle("/slipstack/ft/wrench") == "%slipstack%ft%wrench" and mangle("/") == "%"


def test_qos_text_leaves_rmw_zenohs_defaults_empty() -> None:
    assert qos_text(depth=7) == "::,7:,:,:,,"  # the talker of design.md
    assert qos_text(depth=42) == "::,:,:,:,,"
    assert qos_text("best_effort", "transient_local", "keep_all", 5) == "2:1:2,5:,:,:,,"


def test_the_attachment_is_sequence_time_and_gid_little_endian() -> None:
    gid = bytes(range(16))
    raw = Attachment(1, 1_700_000_000_123_456_789, gid).pack()
    assert len(raw) == 33 and raw[:8] == struct.pack("<q", 1) and raw[16] == 16 and raw[17:] == gid
    assert Attachment.unpack(raw) == Attachment(1, 1_700_000_000_123_456_789, gid)
    for bad in (raw[:16], raw[:-1], raw + b"x"):
        with pytest.raises(ValueError, match="attachment"):
            Attachment.unpack(bad)


def test_ros_names() -> None:
    assert valid_ros_name("/slipstack") and valid_ros_name("/ft_sensor/wrench")
    for bad in ("", "slip", "/a//b", "/1a", "/a b", "/a/", "/a__b"):
        assert not valid_ros_name(bad), bad


def test_the_type_hash_of_std_msgs_string_is_the_design_documents() -> None:
    from slipstack.messages.ros2 import codec

    assert codec().type_hash("std_msgs/msg/String") == STRING_HASH
