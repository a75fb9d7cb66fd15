"""Hypothesis strategies of valid messages, drawn from the declarations (types,
shapes, tied lengths, :class:`~slipstack.messages.base.Bounds`)."""

from __future__ import annotations

import dataclasses
import math
import typing

import numpy as np
from hypothesis import strategies as st

from slipstack.messages import Header, Message, registry
from slipstack.messages.base import ArraySpec, Bounds

__all__ = ["valid_message", "any_valid_message", "stamps"]

stamps = st.integers(min_value=0, max_value=2**63 - 1)
finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
MAX_SIDE_DRAWN = 6  # pads drawn small: the limits are tested on their own


def _array(spec: ArraySpec, free: int, fields: dict[str, object], draw) -> np.ndarray:
    shape = tuple(
        n if isinstance(n, int) else free if n is None else math.prod(fields[k] for k in n.split("*"))
        for n in spec.shape
    )
    dtype = np.dtype(spec.dtype)
    size = math.prod(shape)
    if dtype.kind == "b":
        data = draw(st.lists(st.booleans(), min_size=size, max_size=size))
    elif dtype.kind == "f":
        width = 32 if dtype.itemsize == 4 else 64
        data = draw(st.lists(st.floats(allow_nan=False, allow_infinity=False, width=width), min_size=size, max_size=size))
    else:
        data = draw(st.lists(st.integers(0, 255), min_size=size, max_size=size))
    return np.array(data, dtype=dtype).reshape(shape)


def _number(kind: type, b: Bounds, small: bool) -> st.SearchStrategy:
    lo = b.ge if b.ge is not None else b.gt
    hi = b.le
    if kind is int:
        lo_i = -(2**62) if lo is None else int(lo) + (1 if b.gt is not None else 0)
        hi_i = 2**62 if hi is None else int(hi)
        return st.integers(lo_i, min(hi_i, MAX_SIDE_DRAWN) if small else hi_i)
    return st.floats(min_value=lo, max_value=hi, exclude_min=b.gt is not None, allow_nan=False,
                     allow_infinity=b.allow_inf and lo is None and hi is None)


def _text(b: Bounds) -> st.SearchStrategy:
    max_len = b.max_len if b.max_len is not None else 256
    options = []
    if b.choices is not None:
        options.append(st.sampled_from(b.choices))
    if b.pattern is not None:
        options.append(st.from_regex(b.pattern, fullmatch=True).filter(lambda s: len(s) <= max_len))
    return st.one_of(options) if options else st.text(max_size=min(max_len, 20))


def _dict_value(kind: object) -> st.SearchStrategy:
    """A value of a dict field as declared (``"values"``: a type, or a tuple of them for a list)."""
    if isinstance(kind, tuple):
        return st.tuples(*(_dict_value(k) for k in kind)).map(list)
    if kind is bool:
        return st.booleans()
    return st.integers(-1000, 1000) | finite


@st.composite
def valid_message(draw, cls: type[Message]) -> Message:
    """One valid ``cls`` with a random header."""
    hints = typing.get_type_hints(cls)
    body = [f for f in dataclasses.fields(cls) if f.name != "header"]
    tied = {k for f in body if (s := f.metadata.get("array")) for n in s.shape if isinstance(n, str)
            for k in n.split("*")}
    free = draw(st.integers(0, 20))
    values: dict[str, object] = {}
    for f in body:
        spec = f.metadata.get("array")
        if spec is not None:
            values[f.name] = _array(spec, free, values, draw)
            continue
        kind = typing.get_origin(hints[f.name]) or hints[f.name]
        b = f.metadata.get("bounds") or Bounds()
        values[f.name] = draw({
            float: lambda: _number(float, b, False),
            int: lambda: _number(int, b, f.name in tied),
            bool: st.booleans,
            str: lambda: _text(b),
            dict: lambda: st.dictionaries(st.text(max_size=8), _dict_value(f.metadata.get("values")), max_size=4),
        }[kind]())
    header = Header(draw(stamps), draw(st.integers(0, 2**40)), draw(stamps),
                    draw(st.dictionaries(st.text(max_size=6), stamps, max_size=3)))
    return cls(header=header, **values)


def any_valid_message() -> st.SearchStrategy[Message]:
    """A valid message of any registered type."""
    return st.sampled_from(sorted(registry.values(), key=lambda c: c.TYPE)).flatmap(valid_message)
