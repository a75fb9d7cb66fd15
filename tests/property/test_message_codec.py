"""Every valid message of every type round-trips; random bytes never crash the decoder."""

from __future__ import annotations

import dataclasses

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from msg_strategies import any_valid_message

from slipstack.lib.errors import DecodeError
from slipstack.messages import decode, encode


def _equal(a, b) -> bool:
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b)
    return a == b


@settings(max_examples=300)
@given(any_valid_message())
def test_every_type_round_trips_exactly(msg):
    back = decode(encode(msg), type(msg))
    assert back.header == msg.header
    for f in dataclasses.fields(msg):
        assert _equal(getattr(back, f.name), getattr(msg, f.name)), f.name


@settings(max_examples=1000)
@given(st.binary(max_size=300))
def test_random_bytes_raise_decode_error_only(data):
    try:
        decode(data)
    except DecodeError:
        pass


@settings(max_examples=300)
@given(any_valid_message(), st.data())
def test_corrupted_frames_raise_decode_error_only(msg, data):
    payload = bytearray(encode(msg))
    for _ in range(data.draw(st.integers(1, 4))):
        i = data.draw(st.integers(0, len(payload) - 1))
        payload[i] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(0, len(payload)))
    try:
        decode(bytes(payload[:cut]), type(msg))
    except DecodeError:
        pass
