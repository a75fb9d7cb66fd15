"""Typed message records: declaration, validation, encoding.

A message type is a frozen dataclass decorated with :func:`message`. Scalar fields
are annotated ``float``, ``int``, ``bool``, ``str`` or ``dict``; array fields use
:func:`array` to declare dtype, shape and finiteness. Every message carries a
:class:`Header` filled in by the executor when it is published.

Decoding validates types, shapes and finiteness and raises
:class:`~slipstack.lib.errors.DecodeError` naming the field
(``ft/wrench.force: expected shape (3,), got (2,)``).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar, get_type_hints

import numpy as np

from slipstack.lib.errors import DecodeError
from slipstack.messages.codec import packb, unpackb

__all__ = ["Header", "Message", "ArraySpec", "array", "message", "encode", "decode", "validate", "registry"]


@dataclass(frozen=True, slots=True)
class Header:
    """Stamps common to every message.

    Attributes:
        stamp_ns: time of the sensor sample this message derives from, integer ns on
            the executor clock (CLOCK_MONOTONIC for processes, simulated in-process).
        seq: per-publisher, per-topic sequence number, from 0; gaps reveal loss.
        pub_ns: when the message was published, same clock as ``stamp_ns``.
        sources: stamps of the input samples used, by input name (e.g. ``{"ft": …}``).
    """

    stamp_ns: int = 0
    seq: int = 0
    pub_ns: int = 0
    sources: dict[str, int] = field(default_factory=dict)


@dataclass(frozen=True)
class ArraySpec:
    """Declared dtype and shape of an array field; ``None`` in the shape is free."""

    dtype: str
    shape: tuple[int | None, ...]
    finite: bool = True


def array(dtype: str, shape: tuple[int | None, ...], *, finite: bool = True, doc: str = "") -> Any:
    """Declare an array field (a dataclass ``field`` carrying an :class:`ArraySpec`)."""
    spec = ArraySpec(np.dtype(dtype).str, shape, finite)
    empty_shape = tuple(0 if n is None else n for n in shape)
    return field(
        default_factory=lambda: np.zeros(empty_shape, dtype=spec.dtype),
        metadata={"array": spec, "doc": doc},
    )


class Message:
    """Base of all message types; see :func:`message`."""

    TYPE: ClassVar[str]
    VERSION: ClassVar[int]
    header: Header


M = TypeVar("M", bound=Message)
registry: dict[str, type[Message]] = {}

_SCALARS = {float: (int, float), int: (int,), bool: (bool,), str: (str,), dict: (dict,)}


def _validator(owner: str, f: dataclasses.Field, hint: Any):
    name = f"{owner}.{f.name}"
    spec: ArraySpec | None = f.metadata.get("array")
    if spec is not None:
        want_dtype = np.dtype(spec.dtype)

        fixed_shape = spec.shape if None not in spec.shape else None
        check_finite = spec.finite and want_dtype.kind == "f"

        def check_array(v: Any) -> Any:
            if type(v) is not np.ndarray:
                raise DecodeError(f"{name}: expected an array, got {type(v).__name__}")
            if v.dtype != want_dtype:
                raise DecodeError(f"{name}: expected dtype {want_dtype}, got {v.dtype}")
            if v.shape != fixed_shape and (len(v.shape) != len(spec.shape) or any(
                s is not None and s != n for s, n in zip(spec.shape, v.shape)
            )):
                raise DecodeError(f"{name}: expected shape {spec.shape}, got {v.shape}")
            # NaN/Inf make the dot product with zeros NaN: one pass, no temporary array
            if check_finite and v.size and v.reshape(-1).dot(np.zeros(v.size, v.dtype)) != 0:
                raise DecodeError(f"{name}: contains NaN or Inf")
            return v

        return check_array
    origin = getattr(hint, "__origin__", hint)
    allowed = _SCALARS.get(origin)
    if allowed is None:
        raise TypeError(f"{name}: unsupported field type {hint!r}")
    allow_inf = bool(f.metadata.get("allow_inf", False))

    def check_scalar(v: Any) -> Any:
        if isinstance(v, bool) and origin is not bool:
            raise DecodeError(f"{name}: expected {origin.__name__}, got bool")
        if not isinstance(v, allowed):
            raise DecodeError(f"{name}: expected {origin.__name__}, got {type(v).__name__}")
        if origin is float:
            v = float(v)
            if math.isnan(v) or (math.isinf(v) and not allow_inf):
                raise DecodeError(f"{name}: must be finite, got {v}")
        return v

    return check_scalar


def message(type_name: str, version: int = 1):
    """Class decorator: make a frozen message dataclass and register its type name."""

    def wrap(cls: type[M]) -> type[M]:
        if "header" not in cls.__dict__.get("__annotations__", {}):
            cls.__annotations__ = {"header": Header, **cls.__dict__.get("__annotations__", {})}
            cls.header = field(default_factory=Header, kw_only=True)  # type: ignore[attr-defined]
        dc = dataclass(frozen=True)(cls)
        hints = get_type_hints(dc)
        body = [f for f in dataclasses.fields(dc) if f.name != "header"]
        dc.TYPE = type_name
        dc.VERSION = version
        dc._body_fields = tuple(f.name for f in body)  # type: ignore[attr-defined]
        dc._validators = tuple(_validator(type_name, f, hints[f.name]) for f in body)  # type: ignore[attr-defined]
        # Every declared field must be on the wire; trailing extra fields (appended by
        # a newer writer of the same version) are ignored.
        dc._required = len(body)  # type: ignore[attr-defined]
        if type_name in registry:
            raise TypeError(f"message type {type_name!r} registered twice")
        registry[type_name] = dc
        return dc

    return wrap


def encode(msg: Message, header: Header | None = None) -> bytes:
    """Encode a message to its MessagePack payload, with ``header`` in place of its own."""
    h = msg.header if header is None else header
    fields = msg.__dict__
    body = [fields[n] for n in msg._body_fields]  # type: ignore[attr-defined]
    return packb([msg.TYPE, msg.VERSION, [h.stamp_ns, h.seq, h.pub_ns, h.sources], body])


def _decode_header(raw: Any, type_name: str) -> Header:
    if not isinstance(raw, list) or len(raw) != 4:
        raise DecodeError(f"{type_name}.header: expected [stamp_ns, seq, pub_ns, sources]")
    stamp, seq, pub, sources = raw
    for label, v in (("stamp_ns", stamp), ("seq", seq), ("pub_ns", pub)):
        if not isinstance(v, int) or isinstance(v, bool):
            raise DecodeError(f"{type_name}.header.{label}: expected int, got {type(v).__name__}")
    if not isinstance(sources, dict) or not all(
        isinstance(k, str) and isinstance(v, int) and not isinstance(v, bool) for k, v in sources.items()
    ):
        raise DecodeError(f"{type_name}.header.sources: expected a map of str to int")
    return Header(stamp, seq, pub, sources)


def decode(payload: bytes, expected: type[M] | None = None) -> M:
    """Decode and validate one payload.

    Args:
        payload: bytes produced by :func:`encode`.
        expected: the message type the caller subscribed to; ``None`` accepts any
            registered type.

    Raises:
        DecodeError: naming the field, for any malformed, mistyped, misshapen or
            non-finite content, an unknown type or an incompatible version.
    """
    top = unpackb(payload)
    if not isinstance(top, list) or len(top) != 4:
        raise DecodeError("payload: expected [type, version, header, body]")
    type_name, version, raw_header, raw_body = top
    if not isinstance(type_name, str):
        raise DecodeError("payload.type: expected a type name string")
    cls = registry.get(type_name) if expected is None else expected
    if cls is None:
        raise DecodeError(f"payload.type: unknown message type {type_name!r}")
    if type_name != cls.TYPE:
        raise DecodeError(f"payload.type: expected {cls.TYPE!r}, got {type_name!r}")
    if version != cls.VERSION:
        raise DecodeError(f"{type_name}.version: expected {cls.VERSION}, got {version!r}")
    header = _decode_header(raw_header, type_name)
    if not isinstance(raw_body, list):
        raise DecodeError(f"{type_name}.body: expected a list of fields")
    names = cls._body_fields  # type: ignore[attr-defined]
    if len(raw_body) < cls._required:  # type: ignore[attr-defined]
        missing = names[len(raw_body)]
        raise DecodeError(f"{type_name}.{missing}: missing")
    msg = object.__new__(cls)  # fields are validated above; skip the frozen __init__'s setattr per field
    fields = msg.__dict__
    for n, check, v in zip(names, cls._validators, raw_body):  # type: ignore[attr-defined]
        fields[n] = check(v)
    fields["header"] = header
    return msg


def validate(msg: Message) -> Message:
    """Run the decoder's checks on a message built in memory; returns it unchanged."""
    for n, check in zip(msg._body_fields, msg._validators):  # type: ignore[attr-defined]
        check(getattr(msg, n))
    return msg
