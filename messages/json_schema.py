"""Messages as JSON, and the JSON Schema (draft 2020-12) of that JSON, from the declarations.

Used by ``bag export`` (an MCAP file Foxglove opens) and by the live ``foxglove`` node.
The schema is as tight as decoding: every field is required and no other is allowed;
numbers are numbers (a float that may be infinite also takes the strings ``"inf"`` and
``"-inf"``, JSON having no infinities); fixed array lengths, declared bounds and
enumerations become ``minItems``/``maxItems``, ``minimum``/``maximum``, ``enum`` and
``pattern``; a field's declared unit opens its ``description``.

More in docs/modules.md, `messages/json_schema.py`.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from typing import Any

import numpy as np

from slipstack.messages.base import INT64_MAX, MAX_HEADER_SOURCES, MAX_KEY_LEN, Message, declared_bounds
from slipstack.messages.types import MAX_PAD_SIDE

__all__ = ["json_schema", "to_json", "wall_time", "TIME_SCHEMA", "NON_FINITE"]

NON_FINITE = {"nan": "nan", "inf": "inf", "-inf": "-inf"}
"""How a non-finite float is written in JSON (which has no NaN or infinity)."""

TIME_SCHEMA: dict[str, Any] = {
    "type": "object", "title": "time",
    "properties": {"sec": {"type": "integer", "minimum": 0},
                   "nsec": {"type": "integer", "minimum": 0, "maximum": 999_999_999}},
    "required": ["sec", "nsec"], "additionalProperties": False,
}
"""A wall-clock time as Foxglove writes it: whole seconds and nanoseconds since the Unix epoch."""

_STAMP = {"type": "integer", "minimum": 0, "maximum": INT64_MAX}
_MONOTONIC = "ns on CLOCK_MONOTONIC of the publishing host (as on the bus)"
_HEADER: dict[str, Any] = {
    "type": "object",
    "properties": {
        "stamp_ns": {**_STAMP, "description": f"sample time, {_MONOTONIC}"},
        "seq": {**_STAMP, "description": "per-publisher sequence number, from 0; gaps are losses"},
        "pub_ns": {**_STAMP, "description": f"publication time, {_MONOTONIC}"},
        "sources": {"type": "object", "maxProperties": MAX_HEADER_SOURCES,
                    "propertyNames": {"maxLength": MAX_KEY_LEN}, "additionalProperties": _STAMP,
                    "description": f"stamps of the input samples by input name, {_MONOTONIC}"},
        "stamp": {**TIME_SCHEMA, "description": "sample time on the wall clock (stamp_ns + the recording "
                                                "host's wall - monotonic offset)"},
    },
    "required": ["stamp_ns", "seq", "pub_ns", "sources", "stamp"],
    "additionalProperties": False,
}
_MAX_ITEMS = MAX_PAD_SIDE * MAX_PAD_SIDE  # a free or rows*cols array length at most


_INFINITE = ("inf", "-inf")
_ANY_FLOAT = tuple(NON_FINITE.values())


def _number(non_finite: tuple[str, ...] = (), bounds: dict[str, Any] | None = None) -> dict[str, Any]:
    """A float: a JSON number within ``bounds``, or one of the ``non_finite`` strings."""
    number = {"type": "number", **(bounds or {})}
    return {"anyOf": [number, {"enum": list(non_finite)}]} if non_finite else number


def _python_type(kind: Any) -> dict[str, Any]:
    """Schema of a value declared as a Python type (``bool``, ``int``, ``float``) or a tuple of them
    (a fixed-length list: ``(bool, float)``)."""
    if isinstance(kind, tuple):
        items = [_python_type(k) for k in kind]
        return {"type": "array", "prefixItems": items, "items": False, "minItems": len(items)}
    return {bool: {"type": "boolean"}, int: {"type": "integer"}}.get(kind) or _number(_ANY_FLOAT)


def _array(spec: Any) -> dict[str, Any]:
    kind = np.dtype(spec.dtype).kind
    item = ({"type": "boolean"} if kind == "b" else
            _number(() if spec.finite else _ANY_FLOAT) if kind == "f" else {"type": "integer"})
    out: dict[str, Any] = {"type": "array", "items": item}
    for n in spec.shape[:1]:  # every declared array is 1-D
        if isinstance(n, int):
            out["minItems"] = out["maxItems"] = n
        else:
            out["maxItems"] = _MAX_ITEMS
    return out


def _field(f: dataclasses.Field, hint: Any) -> dict[str, Any]:
    spec = f.metadata.get("array")
    if spec is not None:
        out = _array(spec)
        tied = [n for n in spec.shape if isinstance(n, str)]
        note = f"{tied[0]} values" if tied else ""
    else:
        origin = typing.get_origin(hint) or hint
        bounds = declared_bounds(f, hint)
        if origin is float:
            allow_inf = bool(getattr(f.metadata.get("bounds"), "allow_inf", False))
            out = _number(_INFINITE if allow_inf else (), bounds)
        elif origin is dict:
            out = {"type": "object", "propertyNames": {"maxLength": MAX_KEY_LEN}, **bounds}
            if "values" in f.metadata:
                out["additionalProperties"] = _python_type(f.metadata["values"])
        else:
            out = {**{int: {"type": "integer"}, bool: {"type": "boolean"}, str: {"type": "string"}}[origin], **bounds}
        note = ""
    unit = f.metadata.get("doc", "")
    description = "; ".join(x for x in (f"unit: {unit}" if unit else "", note) if x)
    if description:
        out["description"] = description
    return out


def json_schema(cls: type[Message]) -> dict[str, Any]:
    """The JSON Schema of :func:`to_json` of ``cls`` (see the module docstring)."""
    hints = typing.get_type_hints(cls)
    props: dict[str, Any] = {"header": _HEADER}
    for f in dataclasses.fields(cls):
        if f.name != "header":
            props[f.name] = _field(f, hints[f.name])
    doc = (cls.__doc__ or "").strip().split("\n\n")[0]
    return {"$schema": "https://json-schema.org/draft/2020-12/schema", "title": cls.TYPE,
            "description": " ".join(doc.split()), "type": "object", "properties": props,
            "required": list(props), "additionalProperties": False}


def wall_time(ns: int) -> dict[str, int]:
    """Wall-clock ns since the Unix epoch as ``{sec, nsec}`` (:data:`TIME_SCHEMA`; clamped at 0)."""
    sec, nsec = divmod(max(int(ns), 0), 1_000_000_000)
    return {"sec": sec, "nsec": nsec}


def _jsonable(v: Any) -> Any:
    if isinstance(v, np.ndarray):
        return [_jsonable(x) for x in v.tolist()] if v.dtype.kind == "f" else v.tolist()
    if isinstance(v, float) and not math.isfinite(v):
        return NON_FINITE["nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")]
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    return v


def to_json(msg: Message, wall_minus_monotonic_ns: int) -> dict[str, Any]:
    """A message as JSON-ready builtins (:func:`json_schema` of its type describes them).

    Arrays become lists; ±inf and NaN become the strings of :data:`NON_FINITE`;
    ``header.stamp`` is ``stamp_ns`` + ``wall_minus_monotonic_ns`` as ``{sec, nsec}``.
    """
    h = msg.header
    out: dict[str, Any] = {"header": {"stamp_ns": h.stamp_ns, "seq": h.seq, "pub_ns": h.pub_ns,
                                      "sources": dict(h.sources),
                                      "stamp": wall_time(h.stamp_ns + wall_minus_monotonic_ns)}}
    for name in msg._body_fields:  # type: ignore[attr-defined]
        out[name] = _jsonable(getattr(msg, name))
    return out
