"""The code generated for each message type (``messages/generated.py``) never changes an outcome.

Its accept test takes a valid message in one pass; what it does not accept goes through the
field-by-field checks. So for every registered type, with one or two fields of a valid
message replaced by a random value — NaN, ±inf, huge, out of bounds, of the wrong type, an
array of the wrong shape, dtype or memory layout, oversized text or maps — the hand-over
must reject exactly what the field-by-field checks reject, with their text, and the decoder
likewise on the frame carrying those values; and its wire body must encode to the bytes
the generic packer writes for the same fields.
"""

from __future__ import annotations

import dataclasses
import math
import typing

import msgpack
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from msg_strategies import valid_message

from slipstack.lib.errors import DecodeError
from slipstack.lib.status import SlipState
from slipstack.messages import Header, Message, decode, encode, handed_over, registry
from slipstack.messages.base import MAX_DICT_ITEMS, MAX_STR_LEN, Bounds, _check_fields
from slipstack.messages.codec import _default
from slipstack.messages.frame import pack_frame, unpack_frame

_HEADER = Header(5, 1, 6, {"ft": 5})
pytestmark = pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning")  # NaN/Inf arrays, on purpose
_SPECIAL_FLOATS = [math.nan, math.inf, -math.inf, 1e308, -1e308, 1e200, 0.0, -0.0, 5e-324, 2.5]


def _near(limit: float | None) -> list[float]:
    """A bound and the floats just either side of it."""
    return [] if limit is None else [limit, math.nextafter(limit, -math.inf), math.nextafter(limit, math.inf)]


def _number(b: Bounds) -> st.SearchStrategy:
    edges = [x for limit in (b.ge, b.gt, b.le) for x in _near(limit)]
    return st.one_of(
        st.sampled_from(_SPECIAL_FLOATS + edges), st.floats(), st.integers(-(2**70), 2**70),
        st.sampled_from([int(x) for x in edges if math.isfinite(x)] or [0]),
        st.floats().map(np.float64), st.integers(-5, 5).map(np.int64), st.floats(width=32).map(np.float32),
    )


def _text(b: Bounds) -> st.SearchStrategy:
    max_len = b.max_len if b.max_len is not None else MAX_STR_LEN
    return st.one_of(
        st.sampled_from(list(b.choices or ()) + ["", "ok", "device-status 0x00ff", "device-status 0xZZ", "a b"]),
        st.text(max_size=8), st.just("x" * max_len), st.just("x" * (max_len + 1)),
        st.sampled_from(list(SlipState)),  # a str enumeration member, as the slip detector publishes
    )


def _dict(b: Bounds) -> st.SearchStrategy:
    max_items = b.max_len if b.max_len is not None else MAX_DICT_ITEMS
    value = st.one_of(st.booleans(), st.floats(), st.integers(-3, 3), st.none(), st.text(max_size=2),
                      st.lists(st.one_of(st.booleans(), st.floats(), st.integers(0, 1)), max_size=3),
                      st.tuples(st.booleans(), st.floats()))
    key = st.one_of(st.text(max_size=6), st.just("k" * 129), st.integers(0, 3))
    return st.one_of(st.dictionaries(key, value, max_size=4),
                     st.just({f"k{i}": 1.0 for i in range(max_items + 1)}))


@st.composite
def _array(draw, spec) -> object:
    """An array near the declared one (its dtype and shape half the time), or not an array."""
    declared = tuple(n if isinstance(n, int) else 3 for n in spec.shape)
    shape = draw(st.sampled_from([declared] * 4 + [(declared[0] + 1,) + declared[1:], declared + (1,), (), (0,)]))
    dtype = draw(st.sampled_from([spec.dtype] * 7 + ["<f8", "<f4", ">f8", "<i8", "|u1", "|b1", "<f2", "<i4"]))
    size = math.prod(shape)
    values = draw(st.lists(st.sampled_from(_SPECIAL_FLOATS) | st.floats(-10, 10), min_size=size, max_size=size))
    with np.errstate(all="ignore"):
        arr = np.array(values).astype(dtype).reshape(shape)
    if draw(st.booleans()) and arr.ndim == 1 and arr.size:  # a strided view of the same values
        arr = np.repeat(arr, 2)[::2]
    return draw(st.sampled_from([arr, arr, arr, list(values), None, 1.0]))


def _mischief(cls: type[Message], name: str) -> st.SearchStrategy:
    """Random values, valid or not, for field ``name`` of ``cls``."""
    f = next(f for f in dataclasses.fields(cls) if f.name == name)
    spec = f.metadata.get("array")
    wrong_type = st.sampled_from([None, "1", b"1", [1.0], True, 1, 1.5])
    if spec is not None:
        return _array(spec)
    hint = typing.get_type_hints(cls)[name]
    kind = typing.get_origin(hint) or hint
    b = f.metadata.get("bounds") or Bounds()
    own = {float: _number(b), int: _number(b), bool: st.sampled_from([True, False, 0, 1, np.bool_(True)]),
           str: _text(b), dict: _dict(b)}[kind]
    return st.one_of(own, own, wrong_type)


@st.composite
def _tampered(draw) -> tuple[type[Message], dict[str, object]]:
    """A registered type and the body fields of one of its valid messages, one or two replaced."""
    cls = draw(st.sampled_from(sorted(registry.values(), key=lambda c: c.TYPE)))
    fields = {n: getattr(draw(valid_message(cls)), n) for n in cls._body_fields}
    for name in draw(st.lists(st.sampled_from(cls._body_fields), min_size=1, max_size=2, unique=True)):
        fields[name] = draw(_mischief(cls, name))
    return cls, fields


def _field_checks(cls: type[Message], fields: dict[str, object]) -> str | None:
    """What the field-by-field checks say of ``fields``: ``None`` (valid) or the error."""
    msg = object.__new__(cls)
    try:
        _check_fields(msg, dict(fields))
    except DecodeError as exc:
        return str(exc)
    return None


def _message(cls: type[Message], fields: dict[str, object]) -> Message:
    msg = object.__new__(cls)
    msg.__dict__.update(fields, header=_HEADER)
    return msg


@settings(max_examples=150)
@given(_tampered())
def test_the_hand_over_rejects_exactly_what_the_field_checks_reject(case):
    cls, fields = case
    expected = _field_checks(cls, fields)
    assert expected is None or not cls._accept(fields), f"accepted, but the field checks say: {expected}"
    assert handed_over(_message(cls, fields), _HEADER)[1] == expected


@settings(max_examples=150)
@given(_tampered())
def test_the_decoder_rejects_exactly_what_the_field_checks_reject(case):
    cls, fields = case
    try:
        payload = pack_frame(cls.TYPE, cls.VERSION, _HEADER, list(fields.values()))
    except (TypeError, ValueError, OverflowError):
        return  # a value the wire cannot carry (encode refuses it)
    try:
        wire = dict(zip(cls._body_fields, unpack_frame(payload)[3]))
    except DecodeError as exc:  # beyond what the unpacker builds: the decoder says the same
        expected = str(exc)
    else:
        expected = _field_checks(cls, wire)
    try:
        decode(payload, cls)
    except DecodeError as exc:
        assert str(exc) == expected
    else:
        assert expected is None


@settings(max_examples=150)
@given(_tampered())
def test_a_message_encodes_to_the_bytes_the_generic_packer_writes(case):
    cls, fields = case
    try:
        expected = msgpack.packb([cls.TYPE, cls.VERSION, [5, 1, 6, {"ft": 5}], list(fields.values())],
                                 default=_default, use_bin_type=True)  # the packer's fallback for arrays
    except (TypeError, ValueError, OverflowError) as exc:
        expected = type(exc)
    try:
        got = encode(_message(cls, fields))
    except (TypeError, ValueError, OverflowError) as exc:
        got = type(exc)
    assert got == expected
