"""Every message type round-trips; random bytes never crash the decoder."""

from __future__ import annotations

import dataclasses

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from slipstack.lib.errors import DecodeError
from slipstack.messages import Header, decode, encode, registry
from slipstack.messages.base import ArraySpec

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
stamps = st.integers(min_value=0, max_value=2**63 - 1)


def _value(f: dataclasses.Field, hint: type, n: int, draw) -> object:
    spec: ArraySpec | None = f.metadata.get("array")
    if spec is not None:
        shape = tuple(n if s is None else s for s in spec.shape)
        dtype = np.dtype(spec.dtype)
        size = int(np.prod(shape))
        if dtype.kind == "b":
            data = draw(st.lists(st.booleans(), min_size=size, max_size=size))
        elif dtype.kind == "f":
            width = 32 if dtype.itemsize == 4 else 64
            data = draw(st.lists(st.floats(allow_nan=False, allow_infinity=False, width=width), min_size=size, max_size=size))
        else:
            data = draw(st.lists(st.integers(0, 255), min_size=size, max_size=size))
        return np.array(data, dtype=dtype).reshape(shape)
    return {
        float: lambda: draw(finite),
        int: lambda: draw(st.integers(-(2**62), 2**62)),
        bool: lambda: draw(st.booleans()),
        str: lambda: draw(st.text(max_size=20)),
        dict: lambda: draw(st.dictionaries(st.text(max_size=8), st.integers(-1000, 1000) | finite, max_size=4)),
    }[hint]()


@st.composite
def messages(draw):
    cls = draw(st.sampled_from(sorted(registry.values(), key=lambda c: c.TYPE)))
    hints = {f.name: f.type for f in dataclasses.fields(cls)}
    n = draw(st.integers(0, 20))
    import typing
    types = typing.get_type_hints(cls)
    values = {
        f.name: _value(f, typing.get_origin(types[f.name]) or types[f.name], n, draw)
        for f in dataclasses.fields(cls) if f.name != "header"
    }
    assert hints
    header = Header(draw(stamps), draw(st.integers(0, 2**40)), draw(stamps),
                    draw(st.dictionaries(st.text(max_size=6), stamps, max_size=3)))
    return cls(header=header, **values)


def _equal(a, b) -> bool:
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b)
    return a == b


@settings(max_examples=300)
@given(messages())
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
@given(messages(), st.data())
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
