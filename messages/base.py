"""Typed message records: declaration, validation, encoding.

A message type is a frozen dataclass decorated with :func:`message`. Scalar fields
are annotated ``float``, ``int``, ``bool``, ``str`` or ``dict``; array fields use
:func:`array` to declare dtype, shape and finiteness. Every message carries a
:class:`~slipstack.messages.frame.Header` filled in by the executor when it is
published; :mod:`slipstack.messages.frame` holds the frame layout around the body.

More in docs/modules.md, `messages/base.py`.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar, get_type_hints

import numpy as np

from slipstack.lib.errors import DecodeError
from slipstack.messages.frame import (
    INT64_MAX, MAX_HEADER_SOURCES, MAX_KEY_LEN, Header, header_from_wire, pack_frame, unpack_frame,
)
from slipstack.messages.generated import FieldRule, all_finite, compile_accept, compile_init, compile_wire_body

__all__ = [
    "Header", "Message", "ArraySpec", "Bounds", "array", "bounded", "declared_bounds", "message", "encode", "decode", "validate",
    "handed_over",
    "registry", "MAX_STR_LEN", "MAX_DICT_ITEMS", "MAX_KEY_LEN", "MAX_HEADER_SOURCES", "INT64_MAX",
]

MAX_STR_LEN = 256
"""Characters a ``str`` field may hold unless it declares its own ``max_len``."""
MAX_DICT_ITEMS = 256
"""Entries a ``dict`` field may hold unless it declares its own ``max_len``."""
_SHOWN_CHARS = 40  # a rejected string is quoted up to this many characters in the error


@dataclass(frozen=True)
class ArraySpec:
    """Declared dtype and shape of an array field.

    A shape entry is a fixed length, ``None`` (free), or a product of integer fields
    declared before the array, e.g. ``"rows*cols"`` (checked against their values).
    """

    dtype: str
    shape: tuple[int | str | None, ...]
    finite: bool = True


@dataclass(frozen=True)
class Bounds:
    """Declared limits of a scalar field, checked on decode and written into the schemas.

    ge / gt / le: inclusive lower, exclusive lower, inclusive upper bound of a number
        (in the field's unit). allow_inf: a float may be ±inf (still within ge/le).
    choices: the strings allowed; pattern: a regular expression a string outside
        ``choices`` must match in full (e.g. a device status code).
    max_len: characters of a ``str``, entries of a ``dict``.
    """

    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    allow_inf: bool = False
    choices: tuple[str, ...] | None = None
    pattern: str | None = None
    max_len: int | None = None

    def json_schema(self) -> dict[str, Any]:
        """The JSON Schema keywords of these bounds (``minimum``, ``enum``, ``maxLength`` …)."""
        out: dict[str, Any] = {}
        if self.ge is not None:
            out["minimum"] = self.ge
        if self.gt is not None:
            out["exclusiveMinimum"] = self.gt
        if self.le is not None:
            out["maximum"] = self.le
        if self.choices is not None and self.pattern is None:
            out["enum"] = list(self.choices)
        elif self.pattern is not None:
            alternatives = [re.escape(c) for c in self.choices or ()] + [self.pattern]
            out["pattern"] = "^(?:" + "|".join(alternatives) + ")$"
        return out


def declared_bounds(f: dataclasses.Field, hint: Any) -> dict[str, Any]:
    """The limits decoding enforces on scalar field ``f`` (of type ``hint``), as JSON
    Schema keywords: its :class:`Bounds` plus the default length limits."""
    b: Bounds = f.metadata.get("bounds") or Bounds()
    out = b.json_schema()
    origin = getattr(hint, "__origin__", hint)
    if origin is str and "enum" not in out:
        out["maxLength"] = b.max_len if b.max_len is not None else MAX_STR_LEN
    elif origin is dict:
        out["maxProperties"] = b.max_len if b.max_len is not None else MAX_DICT_ITEMS
    return out


def bounded(default: Any, *, doc: str = "", **limits: Any) -> Any:
    """Declare a scalar field with :class:`Bounds` (keywords as its attributes)."""
    return field(default=default, metadata={"bounds": Bounds(**limits), "doc": doc})


def array(dtype: str, shape: tuple[int | str | None, ...], *, finite: bool = True, doc: str = "") -> Any:
    """Declare an array field (a dataclass ``field`` carrying an :class:`ArraySpec`)."""
    spec = ArraySpec(np.dtype(dtype).str, shape, finite)
    empty_shape = tuple(n if isinstance(n, int) else 0 for n in shape)
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


def _shown(v: str) -> str:
    """A rejected string as an error quotes it: at most :data:`_SHOWN_CHARS` characters."""
    return repr(v) if len(v) <= _SHOWN_CHARS else f"{v[:_SHOWN_CHARS]!r}… ({len(v)} characters)"


def _size_factors(owner: str, spec: ArraySpec, ints: list[str]) -> tuple[str, ...] | None:
    """The integer fields whose product is the array's length (``"rows*cols"``), if any."""
    tied = [n for n in spec.shape if isinstance(n, str)]
    if not tied:
        return None
    if len(spec.shape) != 1 or len(tied) != 1:
        raise TypeError(f"{owner}: a tied dimension must be the only one of a 1-D array, got {spec.shape}")
    names = tuple(tied[0].split("*"))
    if not all(n in ints for n in names):
        raise TypeError(f"{owner}: {tied[0]!r} must name int fields declared before the array")
    return names


def _array_validator(name: str, spec: ArraySpec):
    want_dtype = np.dtype(spec.dtype)
    shape = tuple(None if isinstance(n, str) else n for n in spec.shape)  # a tied length is checked later
    fixed_shape = shape if None not in shape else None
    check_finite = spec.finite and want_dtype.kind == "f"

    def check_array(v: Any) -> Any:
        if type(v) is not np.ndarray:
            raise DecodeError(f"{name}: expected an array, got {type(v).__name__}")
        if v.dtype != want_dtype:
            raise DecodeError(f"{name}: expected dtype {want_dtype}, got {v.dtype}")
        if v.shape != fixed_shape and (len(v.shape) != len(shape) or any(
            s is not None and s != n for s, n in zip(shape, v.shape)
        )):
            raise DecodeError(f"{name}: expected shape {spec.shape}, got {v.shape}")
        if check_finite and not all_finite(v):
            raise DecodeError(f"{name}: contains NaN or Inf")
        return v

    return check_array


def _number_check(name: str, b: Bounds):
    ge, gt, le = b.ge, b.gt, b.le
    if ge is None and gt is None and le is None:
        return None

    def check(v: float) -> None:
        if (ge is not None and v < ge) or (gt is not None and v <= gt) or (le is not None and v > le):
            limits = [f">= {ge:g}" if ge is not None else "", f"> {gt:g}" if gt is not None else "",
                      f"<= {le:g}" if le is not None else ""]
            raise DecodeError(f"{name}: must be {' and '.join(x for x in limits if x)}, got {v:g}")

    return check


def _str_check(name: str, b: Bounds):
    max_len = b.max_len if b.max_len is not None else MAX_STR_LEN
    choices = frozenset(b.choices) if b.choices is not None else None
    pattern = re.compile(b.pattern) if b.pattern is not None else None

    def check(v: str) -> None:
        if len(v) > max_len:
            raise DecodeError(f"{name}: at most {max_len} characters, got {len(v)}")
        if choices is not None and v in choices:
            return
        if pattern is not None and pattern.fullmatch(v):
            return
        if choices is not None or pattern is not None:
            allowed = ", ".join(sorted(choices or ())) + (f" or {b.pattern}" if pattern is not None else "")
            raise DecodeError(f"{name}: must be one of {allowed.lstrip(', ')}; got {_shown(v)}")

    return check


def _is_value(v: Any, kind: Any) -> bool:
    """``v`` is of the declared dict value ``kind`` (a type, or a tuple of types for a list)."""
    if isinstance(kind, tuple):
        return isinstance(v, (list, tuple)) and len(v) == len(kind) and all(map(_is_value, v, kind))
    if kind is bool or isinstance(v, bool):
        return kind is bool and isinstance(v, bool)
    return isinstance(v, _SCALARS[kind])


def _dict_check(name: str, b: Bounds, values: Any = None):
    max_items = b.max_len if b.max_len is not None else MAX_DICT_ITEMS

    def check(v: dict) -> None:
        if len(v) > max_items:
            raise DecodeError(f"{name}: at most {max_items} entries, got {len(v)}")
        for k, x in v.items():
            if not isinstance(k, str) or len(k) > MAX_KEY_LEN:
                shown = _shown(k) if isinstance(k, str) else type(k).__name__
                raise DecodeError(f"{name}: keys are strings of at most {MAX_KEY_LEN} characters, got {shown}")
            if values is not None and not _is_value(x, values):
                raise DecodeError(f"{name}.{k}: expected {_type_name(values)}, got {x!r:.40}")

    return check


def _type_name(kind: Any) -> str:
    if isinstance(kind, tuple):
        return "[" + ", ".join(_type_name(k) for k in kind) + "]"
    return kind.__name__


def _validator(owner: str, f: dataclasses.Field, hint: Any):
    name = f"{owner}.{f.name}"
    spec: ArraySpec | None = f.metadata.get("array")
    if spec is not None:
        return _array_validator(name, spec)
    origin = getattr(hint, "__origin__", hint)
    allowed = _SCALARS.get(origin)
    if allowed is None:
        raise TypeError(f"{name}: unsupported field type {hint!r}")
    b: Bounds = f.metadata.get("bounds") or Bounds()
    allow_inf = b.allow_inf
    if origin is dict:
        extra = _dict_check(name, b, f.metadata.get("values"))
    else:
        extra = {float: _number_check, int: _number_check, str: _str_check}.get(origin, lambda *_: None)(name, b)

    is_float = origin is float

    def check_scalar(v: Any) -> Any:
        if type(v) is not origin:  # exactly the declared type (what the wire carries) needs no conversion
            if isinstance(v, bool) and origin is not bool:
                raise DecodeError(f"{name}: expected {origin.__name__}, got bool")
            if not isinstance(v, allowed):
                raise DecodeError(f"{name}: expected {origin.__name__}, got {type(v).__name__}")
            if is_float:
                v = float(v)
        if is_float and not math.isfinite(v) and (math.isnan(v) or not allow_inf):
            raise DecodeError(f"{name}: must be finite, got {v}")
        if extra is not None:
            extra(v)
        return v

    return check_scalar


def _field_rule(f: dataclasses.Field, hint: Any, tied: dict[str, tuple[str, ...]]) -> FieldRule:
    """What the generated accept test and wire body (:mod:`slipstack.messages.generated`) need
    of field ``f``: the declaration :func:`_validator` checks it against, limits resolved."""
    spec: ArraySpec | None = f.metadata.get("array")
    if spec is not None:
        return FieldRule(f.name, np.ndarray, dtype=np.dtype(spec.dtype), shape=spec.shape, finite=spec.finite,
                         tied=tied.get(f.name))
    kind = getattr(hint, "__origin__", hint)
    b: Bounds = f.metadata.get("bounds") or Bounds()
    default_len = {str: MAX_STR_LEN, dict: MAX_DICT_ITEMS}.get(kind)
    return FieldRule(f.name, kind, bounds=b, max_len=b.max_len if b.max_len is not None else default_len,
                     values=f.metadata.get("values"))


def message(type_name: str, version: int = 1, *, reads_older: dict[int, str] | None = None):
    """Class decorator: make a frozen message dataclass and register its type name.

    ``reads_older`` maps an older version that decode still accepts to the first field it
    lacked: that version wrote every field before it, and the later ones take their
    defaults (e.g. recordings made before fields were appended).
    """

    def wrap(cls: type[M]) -> type[M]:
        if "header" not in cls.__dict__.get("__annotations__", {}):
            cls.__annotations__ = {"header": Header, **cls.__dict__.get("__annotations__", {})}
            cls.header = field(default_factory=Header, kw_only=True)  # type: ignore[attr-defined]
        dc = dataclass(frozen=True)(cls)
        if not hasattr(dc, "__post_init__"):
            dc.__init__ = compile_init(dc)
        hints = get_type_hints(dc)
        body = [f for f in dataclasses.fields(dc) if f.name != "header"]
        dc.TYPE = type_name
        dc.VERSION = version
        dc._body_fields = tuple(f.name for f in body)  # type: ignore[attr-defined]
        dc._validators = tuple(_validator(type_name, f, hints[f.name]) for f in body)  # type: ignore[attr-defined]
        ints: list[str] = []
        tied = []
        for f in body:
            spec = f.metadata.get("array")
            factors = _size_factors(f"{type_name}.{f.name}", spec, ints) if spec is not None else None
            if factors is not None:
                tied.append((f.name, factors))
            elif hints[f.name] is int:
                ints.append(f.name)
        dc._tied_lengths = tuple(tied)  # type: ignore[attr-defined]
        rules = [_field_rule(f, hints[f.name], dict(tied)) for f in body]
        dc._accept = staticmethod(compile_accept(type_name, rules, max_key_len=MAX_KEY_LEN))  # type: ignore[attr-defined]
        dc._wire_body = staticmethod(compile_wire_body(type_name, rules))  # type: ignore[attr-defined]
        # Every declared field must be on the wire; trailing extra fields (appended by
        # a newer writer of the same version) are ignored.
        dc._required = len(body)  # type: ignore[attr-defined]
        names = [f.name for f in body]
        dc._older_required = {v: names.index(first_new) for v, first_new in (reads_older or {}).items()}  # type: ignore[attr-defined]
        dc._defaults = tuple(f.default_factory if f.default is dataclasses.MISSING else (lambda d=f.default: d)  # type: ignore[attr-defined,misc]
                             for f in body)
        if type_name in registry:
            raise TypeError(f"message type {type_name!r} registered twice")
        registry[type_name] = dc
        return dc

    return wrap


def _check_tied_lengths(msg: Message, fields: dict[str, Any]) -> None:
    """Arrays whose length is a product of integer fields (``rows*cols``) must match it."""
    for name, factors in msg._tied_lengths:  # type: ignore[attr-defined]
        want = math.prod(fields[n] for n in factors)
        got = len(fields[name])
        if got != want:
            raise DecodeError(f"{msg.TYPE}.{name}: expected {'*'.join(factors)} = {want} values, got {got}")


def encode(msg: Message, header: Header | None = None) -> bytes:
    """Encode a message to its MessagePack payload, with ``header`` in place of its own."""
    body = msg._wire_body(msg.__dict__)  # type: ignore[attr-defined]
    return pack_frame(msg.TYPE, msg.VERSION, msg.header if header is None else header, body)


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
    type_name, version, raw_header, raw_body = unpack_frame(payload)
    if not isinstance(type_name, str):
        raise DecodeError("payload.type: expected a type name string")
    cls = registry.get(type_name) if expected is None else expected
    if cls is None:
        raise DecodeError(f"payload.type: unknown message type {type_name!r}")
    if type_name != cls.TYPE:
        raise DecodeError(f"payload.type: expected {cls.TYPE!r}, got {type_name!r}")
    required = cls._required if version == cls.VERSION else _older_required(cls, version)  # type: ignore[attr-defined]
    header = header_from_wire(raw_header, type_name)
    if not isinstance(raw_body, list):
        raise DecodeError(f"{type_name}.body: expected a list of fields")
    names = cls._body_fields  # type: ignore[attr-defined]
    if len(raw_body) < required:
        missing = names[len(raw_body)]
        raise DecodeError(f"{type_name}.{missing}: missing")
    msg = object.__new__(cls)  # fields are validated below; skip the frozen __init__'s setattr per field
    fields = msg.__dict__
    if required == len(names):
        fields.update(zip(names, raw_body))  # trailing fields of a newer writer are left out
        if not cls._accept(fields):  # type: ignore[attr-defined]
            _check_fields(msg, fields)
    else:  # an older version: the fields it wrote, then the defaults of those it did not
        fields.update(zip(names, raw_body[:required]))
        for n, default in zip(names[required:], cls._defaults[required:]):  # type: ignore[attr-defined]
            fields[n] = default()
        _check_fields(msg, fields, checked=required)
    fields["header"] = header
    return msg


def _older_required(cls: type[Message], version: Any) -> int:
    """Body fields an older ``version`` of ``cls`` wrote; DecodeError if decode cannot read it."""
    older = cls._older_required  # type: ignore[attr-defined]
    if type(version) is not int or version not in older:
        readable = f" (or {', '.join(map(str, sorted(older)))})" if older else ""
        raise DecodeError(f"{cls.TYPE}.version: expected {cls.VERSION}{readable}, got {version!r}; the frame "
                          f"was written by another slipstack release: read it with that release")
    return older[version]


def handed_over(msg: M, header: Header) -> tuple[M, str | None]:
    """What an in-process subscriber receives when ``msg`` is published with ``header``: a
    shallow copy carrying ``header`` (the publisher may publish the same object again; the
    fields, arrays included, are shared, not copied), and why it fails the decoder's checks
    (``None`` if it passes). A subscriber rejects and counts a failing message exactly as it
    would the frame on the bus (:meth:`NodeHost.receive_local`), so a container or a lock-step
    run never lets through what separate processes would refuse."""
    copied = object.__new__(type(msg))
    fields = copied.__dict__
    fields.update(msg.__dict__)
    fields["header"] = header
    try:
        validate(copied)
    except DecodeError as exc:
        return copied, str(exc)
    return copied, None


def validate(msg: Message) -> Message:
    """Run the decoder's checks on a message built in memory; returns it unchanged."""
    fields = msg.__dict__
    if not msg._accept(fields):  # type: ignore[attr-defined]
        _check_fields(msg, dict(fields))  # a copy: the checks' converted values (int -> float) stay out of msg
    return msg


def _check_fields(msg: Message, fields: dict[str, Any], checked: int | None = None) -> None:
    """The decoder's checks, field by field in declared order, on the body ``fields`` of
    ``msg`` (the first ``checked`` fields, all by default: an older version's defaults are
    not checked), then the tied lengths: each value is replaced by its checked one (an
    ``int`` in a ``float`` field becomes a float); :class:`DecodeError` names the first
    fault. The full form of the generated accept test (:mod:`slipstack.messages.generated`),
    run when that one does not accept: it names the fault or passes what the test was too
    strict for."""
    for n, check in zip(msg._body_fields[:checked], msg._validators):  # type: ignore[attr-defined]
        fields[n] = check(fields[n])
    if msg._tied_lengths:  # type: ignore[attr-defined]
        _check_tied_lengths(msg, fields)
