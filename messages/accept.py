"""One generated function per message type that accepts a valid message in a single pass.

The decoder's checks (:mod:`slipstack.messages.base`) are one closure per field, each
with its own error text; calling them one by one for every message a node publishes
or receives cost 1–10 µs a message (a closure call, a ``zip`` step and a type dispatch
per field). :func:`compile_accept` writes, once per message type when it is declared,
one function with the same checks inlined as a single ``and`` chain over the fields in
declared order (like the ``__init__`` :mod:`dataclasses` generates)::

    def accept_slipstack_Wrench(fields):
        v_force = fields['force']
        ...
        return ((type(v_force) is ndarray and v_force.dtype is dtype_v_force and v_force.shape == (3,)
                 and v_force.dot(v_force) < inf)
                ...
                and (type(v_device_seq) is int and v_device_seq >= -1) ...)

It only answers *accepted or not*: a message it does not accept goes through the
field-by-field checks, which name the first failing field with the same text as
ever, or pass it after all. So each test is at most as permissive as the check it
stands for, never more, and may be stricter where that is cheaper:

* a float is accepted only as exactly ``float`` (an ``int`` or a numpy float goes to the
  full check, which accepts and converts it); a finite float is ``-inf < v < inf``
  (false for NaN);
* an array's dtype must be the declared dtype object itself (numpy keeps one object per
  built-in dtype; an equal but distinct object goes to the full check);
* a small float array of fixed size is finite when the sum of its values as Python
  floats is (NaN or Inf makes it NaN or Inf; a finite array whose sum overflows goes to
  the full check); a larger one as the full check tests it (:func:`all_finite`);
* ``str`` values are tested with the very operations the full check uses (``len``,
  membership in the choices, the pattern's ``fullmatch``), so a ``str`` enumeration
  member passes both;
* a ``dict`` field's keys must be exactly ``str`` and its values exactly the declared
  types (``int`` or ``float`` for a number, a ``list`` for a fixed-length list).

``tests/property/test_accept_matches_checks.py`` checks on random valid and invalid
values, for every registered type, that an accepted message passes the full checks.
"""

from __future__ import annotations

import math
import re
from typing import Any, Callable, Sequence

import numpy as np

__all__ = ["FieldRule", "compile_accept", "all_finite"]

_SUMMED_SIZE = 16
"""Float arrays of a fixed size up to this are tested finite by summing their values as
Python floats (~0.1 µs for a 3-vector, half of a numpy ``dot``'s call overhead)."""


class FieldRule:
    """What :func:`compile_accept` needs of one body field: its name and declaration.

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
    env: dict[str, Any] = {"ndarray": np.ndarray, "inf": math.inf, "max_key_len": max_key_len, "all_finite": all_finite}
    tests = [_test(rule, env) for rule in rules]
    local = "accept_" + re.sub(r"\W", "_", type_name)
    lines = [f"def {local}(fields):"]
    lines += [f"    v_{rule.name} = fields[{rule.name!r}]" for rule in rules]
    lines.append("    return (" + "\n            and ".join(f"({t})" for t in tests) + ")" if tests else "    return True")
    namespace: dict[str, Any] = {}
    exec(compile("\n".join(lines), f"<accept {type_name}>", "exec"), env, namespace)  # noqa: S102 - code built above from declarations
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
        return " and ".join([f"isinstance({v}, str)", f"len({v}) <= {rule.max_len}", *_str_tests(v, rule.bounds, env)])
    if kind is dict:
        item = "type(k) is str and len(k) <= max_key_len"
        if rule.values is not None:
            item += " and " + _value_test("x", rule.values)
        return f"type({v}) is dict and len({v}) <= {rule.max_len} and all({item} for k, x in {v}.items())"
    raise TypeError(f"{rule.name}: no accept test for {kind!r}")


def _number_tests(v: str, kind: type, b: Any) -> list[str]:
    tests = []
    if kind is float:
        tests.append(f"{v} == {v}" if b.allow_inf else f"-inf < {v} < inf")  # not NaN / finite
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

