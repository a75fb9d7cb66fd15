"""Code generated once per message type when it is declared, for the hot paths.

Every message a node publishes is built, checked for its in-process subscribers and
encoded for the bus or the recording, and every frame a process receives is checked
again: tens of thousands of times a second. Written once per type, like the
``__init__`` :mod:`dataclasses` generates, a type's

More in docs/modules.md, `messages/generated.py`.
"""

from __future__ import annotations

import dataclasses
import math
import re
from typing import Any, Callable, Sequence

import numpy as np

from slipstack.messages.codec import ALLOWED_DTYPES, ARRAY_EXT, array_head, ext_type, pack_array

__all__ = ["FieldRule", "compile_accept", "compile_wire_body", "compile_init", "all_finite"]

_SUMMED_SIZE = 16
"""Float arrays of a fixed size up to this are tested finite by summing their values as
Python floats (~0.1 µs for a 3-vector, half of a numpy ``dot``'s call overhead)."""
_KNOWN_STRINGS_KEPT = 32
"""Exact ``str`` values a field with a pattern remembers as valid (a stream carries few)."""


class FieldRule:
    """What the generated functions need of one body field: its name and declaration.

    kind: the declared Python type (``float``, ``int``, ``bool``, ``str``, ``dict``) or
        ``np.ndarray`` for an array field.
    bounds: the field's :class:`~slipstack.messages.base.Bounds` (scalars).
    max_len: the effective length limit (characters of a ``str``, entries of a ``dict``).
    values: a ``dict`` field's declared value kind (a type, or a tuple of types).
    dtype, shape, finite, tied: an array's dtype, declared shape, finiteness, and the
        integer fields whose product its length is (``None`` if not tied).
    """

    def __init__(self, name: str, kind: type, *, bounds: Any = None, max_len: int | None = None,
                 values: Any = None, dtype: np.dtype | None = None, shape: tuple[Any, ...] = (),
                 finite: bool = True, tied: tuple[str, ...] | None = None) -> None:
        self.name, self.kind, self.bounds, self.max_len, self.values = name, kind, bounds, max_len, values
        self.dtype, self.shape, self.finite, self.tied = dtype, shape, finite, tied


def compile_accept(type_name: str, rules: Sequence[FieldRule], *, max_key_len: int) -> Callable[[dict[str, Any]], bool]:
    """The function ``accept(fields) -> bool`` of a message type (see the module docstring):
    true only if the body ``fields`` (a message's ``__dict__``) pass every field check and
    every tied length; ``max_key_len``: characters of a ``dict`` field's key."""
    env: dict[str, Any] = {"ndarray": np.ndarray, "inf": math.inf, "max_key_len": max_key_len, "all_finite": all_finite,
                           "remember": _remember}
    tests = [_test(rule, env) for rule in rules]
    lines = [f"    v_{rule.name} = fields[{rule.name!r}]" for rule in rules]
    lines.append("    return (" + "\n            and ".join(f"({t})" for t in tests) + ")" if tests else "    return True")
    return _define(f"accept_{type_name}", "fields", lines, env)


def compile_wire_body(type_name: str, rules: Sequence[FieldRule]) -> Callable[[dict[str, Any]], list[Any]]:
    """The function ``wire_body(fields) -> list`` of a message type: the values of its body
    fields in declared order (``rules``), each numpy array as its extension
    (:func:`~slipstack.messages.codec.pack_array`; anything else in an array field is left
    to the packer). An array of its field's fixed shape and declared dtype (that very
    object, as in the accept test) takes the header built here: no look-up, no call."""
    env: dict[str, Any] = {"ndarray": np.ndarray, "pack_array": pack_array, "ext_type": ext_type, "ARRAY_EXT": ARRAY_EXT}
    items = []
    for rule in rules:
        v = f"v_{rule.name}"
        if rule.kind is not np.ndarray:
            items.append(v)
            continue
        item = f"pack_array({v}) if type({v}) is ndarray else {v}"
        if rule.tied is None and None not in rule.shape and rule.dtype.str in ALLOWED_DTYPES:
            env[f"dtype_{v}"], env[f"head_{v}"] = rule.dtype, array_head(rule.dtype.str, rule.shape)
            item = (f"ext_type((ARRAY_EXT, head_{v} + {v}.tobytes())) if type({v}) is ndarray and {v}.dtype is "
                    f"dtype_{v} and {v}.shape == {tuple(rule.shape)!r} else {item}")
        items.append(item)
    lines = [f"    v_{rule.name} = fields[{rule.name!r}]" for rule in rules]
    lines.append("    return [" + ",\n            ".join(items) + "]")
    return _define(f"wire_body_{type_name}", "fields", lines, env)


def compile_init(cls: type) -> Callable[..., None]:
    """An ``__init__`` for frozen dataclass ``cls`` with the signature, defaults and default
    factories of the one :func:`dataclasses.dataclass` writes, storing the fields through
    the instance ``__dict__`` in one update (``cls`` has no ``__post_init__``)."""
    params, kw_only, values = [], [], []
    env: dict[str, Any] = {"MISSING": dataclasses.MISSING}
    for f in dataclasses.fields(cls):
        if f.default_factory is not dataclasses.MISSING:
            env[f"factory_{f.name}"] = f.default_factory
            param, value = f"{f.name}=MISSING", f"factory_{f.name}() if {f.name} is MISSING else {f.name}"
        elif f.default is not dataclasses.MISSING:
            env[f"default_{f.name}"] = f.default
            param, value = f"{f.name}=default_{f.name}", f.name
        else:
            param, value = f.name, f.name
        (kw_only if f.kw_only else params).append(param)
        values.append(f"{f.name!r}: {value}")
    signature = ", ".join(["self", *params, *(["*", *kw_only] if kw_only else [])])
    init = _define(f"init_{cls.__qualname__}", signature, [f"    self.__dict__.update({{{', '.join(values)}}})"], env)
    init.__name__, init.__qualname__, init.__doc__ = "__init__", f"{cls.__qualname__}.__init__", cls.__init__.__doc__
    init.__module__ = cls.__module__
    return init


def _define(name: str, params: str, body: list[str], env: dict[str, Any]) -> Callable[..., Any]:
    """The function ``name`` (any characters; made an identifier) of ``params`` whose
    indented source lines are ``body``, with globals ``env``."""
    local = re.sub(r"\W", "_", name)
    source = "\n".join([f"def {local}({params}):", *body])
    namespace: dict[str, Any] = {}
    env.setdefault("__name__", __name__)  # the module its functions name as theirs
    exec(compile(source, f"<{name}>", "exec"), env, namespace)  # noqa: S102 - source built here from declarations
    return namespace[local]


def _test(rule: FieldRule, env: dict[str, Any]) -> str:
    """The boolean expression accepting a valid value of ``rule``'s field (local ``v_<name>``)."""
    v, kind = f"v_{rule.name}", rule.kind
    if kind is np.ndarray:
        return _array_test(rule, env)
    if kind is bool:
        return f"type({v}) is bool"
    if kind in (int, float):
        return " and ".join([f"type({v}) is {kind.__name__}", *_number_tests(v, kind, rule.bounds)])
    if kind is str:
        test = " and ".join([f"isinstance({v}, str)", f"len({v}) <= {rule.max_len}", *_str_tests(v, rule.bounds, env)])
        if rule.bounds.pattern is None:
            return test
        env[f"known_{v}"] = set()
        return f"(type({v}) is str and {v} in known_{v}) or ({test} and remember(known_{v}, {v}))"
    if kind is dict:
        item = "type(k) is str and len(k) <= max_key_len"
        if rule.values is not None:
            item += " and " + _value_test("x", rule.values)
        return f"type({v}) is dict and len({v}) <= {rule.max_len} and all({item} for k, x in {v}.items())"
    raise TypeError(f"{rule.name}: no accept test for {kind!r}")


def _number_tests(v: str, kind: type, b: Any) -> list[str]:
    tests = []
    if kind is float:
        tests.append(f"{v} == {v}" if b.allow_inf else f"{v} - {v} == 0.0")  # not NaN / finite (inf - inf is NaN)
    for op, limit in ((">=", b.ge), (">", b.gt), ("<=", b.le)):
        if limit is not None:
            tests.append(f"{v} {op} {limit!r}")
    return tests


def _str_tests(v: str, b: Any, env: dict[str, Any]) -> list[str]:
    alternatives = []
    if b.choices is not None:
        env[f"choices_{v}"] = frozenset(b.choices)
        alternatives.append(f"{v} in choices_{v}")
    if b.pattern is not None:
        env[f"fullmatch_{v}"] = re.compile(b.pattern).fullmatch
        alternatives.append(f"fullmatch_{v}({v}) is not None")
    return ["(" + " or ".join(alternatives) + ")"] if alternatives else []


def _remember(known: set[str], v: str) -> bool:
    """Keep ``v``, a value its field accepts, in ``known`` if it is exactly a ``str`` and
    there is room; true (the test it ends has passed)."""
    if type(v) is str and len(known) < _KNOWN_STRINGS_KEPT:
        known.add(v)
    return True


def _value_test(x: str, kind: Any) -> str:
    """A ``dict`` field's value ``x`` is exactly of the declared ``kind`` (stricter than
    the full check's ``isinstance``: a subclass goes to the full check)."""
    if isinstance(kind, tuple):
        return " and ".join([f"type({x}) is list", f"len({x}) == {len(kind)}",
                             *(_value_test(f"{x}[{k}]", sub) for k, sub in enumerate(kind))])
    if kind is float:
        return f"(type({x}) is float or type({x}) is int)"
    return f"type({x}) is {kind.__name__}"


_ZEROS_KEPT = 64  # zero vectors kept for all_finite, by dtype and size (a graph has few sizes)
_zeros: dict[tuple[np.dtype, int], np.ndarray] = {}


def all_finite(v: np.ndarray) -> bool:
    """No NaN or Inf in float array ``v``: its dot product with zeros is 0 (NaN otherwise),
    one pass and no temporary array, as the full check tests it."""
    if not v.size:
        return True
    key = (v.dtype, v.size)
    zero = _zeros.get(key)
    if zero is None:
        zero = np.zeros(v.size, v.dtype)
        if len(_zeros) < _ZEROS_KEPT:
            _zeros[key] = zero
    return (v if v.ndim == 1 else v.reshape(-1)).dot(zero) == 0


def _array_test(rule: FieldRule, env: dict[str, Any]) -> str:
    v = f"v_{rule.name}"
    env[f"dtype_{v}"] = rule.dtype
    if rule.tied is not None:  # the factors are int fields declared (and tested) before the array
        shape = "(" + " * ".join(f"v_{n}" for n in rule.tied) + ",)"
    elif None not in rule.shape:
        shape = repr(tuple(rule.shape))
    else:
        shape = None
    tests = [f"type({v}) is ndarray", f"{v}.dtype is dtype_{v}"]
    if shape is not None:
        tests.append(f"{v}.shape == {shape}")
    else:
        tests.append(f"{v}.ndim == {len(rule.shape)}")
        tests += [f"{v}.shape[{k}] == {n}" for k, n in enumerate(rule.shape) if n is not None]
    if rule.finite and rule.dtype.kind == "f":
        if shape is not None and rule.tied is None and math.prod(rule.shape) <= _SUMMED_SIZE:
            tests.append(f"-inf < sum({v}.tolist()) < inf" if len(rule.shape) == 1 else
                         f"-inf < sum({v}.reshape(-1).tolist()) < inf")
        else:
            tests.append(f"all_finite({v})")
    return " and ".join(tests)

