"""Messages as text for ``topic echo``: YAML-ish blocks, one field, CSV rows.

A message is first turned into a plain tree (:func:`as_tree`: dicts, scalars and
numpy arrays, the header first), which every output form walks. Arrays print
compactly: up to ``truncate`` values in flow style, then ``'...'`` and a YAML
comment with dtype, shape, min and max; ``no_arr`` replaces them with a summary
string, like ``ros2 topic echo --no-arr``.
"""

from __future__ import annotations

import dataclasses
import json
import re
from typing import Any, Iterator

import numpy as np

from slipstack.lib.errors import ConfigError
from slipstack.messages import Header, Message

__all__ = ["as_tree", "pick", "check_field", "render_yaml", "flatten", "csv_cell"]

_PLAIN = re.compile(r"[A-Za-z_/][\w./+-]*")
_RESERVED = {"true", "false", "null", "~", "yes", "no", "on", "off", "True", "False", "Null", "NULL"}


def as_tree(msg: Message) -> dict[str, Any]:
    """``{"header": {...}, field: value, ...}`` in declared order; arrays stay arrays."""
    tree: dict[str, Any] = {"header": dataclasses.asdict(msg.header)}
    for name in msg._body_fields:  # type: ignore[attr-defined]
        tree[name] = getattr(msg, name)
    return tree


def pick(tree: Any, path: str) -> tuple[bool, Any]:
    """Follow ``a.b.c`` into ``tree``; returns ``(found, value)``.

    Map keys may contain dots themselves (``counters.in.ft/wrench.rejected``): the
    longest key that matches a prefix of the remaining path wins; a key absent from a
    map is ``(False, None)`` (another message may have it). Arrays take a flat index
    (``pressure_pa.17`` is row 1, column 1 of a 16-column pad, as in the CSV columns).

    Raises:
        ConfigError: the path indexes an array out of range or goes into a scalar; no
            message of the same type can have it.
    """
    rest = path
    node = tree
    while rest:
        done = path[: len(path) - len(rest)].rstrip(".") or "the message"
        if isinstance(node, dict):
            for key in sorted((k for k in node if rest == k or rest.startswith(k + ".")), key=len, reverse=True):
                node, rest = node[key], rest[len(key) + 1:]
                break
            else:
                return False, None
        elif isinstance(node, np.ndarray):
            head, _, rest = rest.partition(".")
            if not head.isdigit() or int(head) >= node.size:
                raise ConfigError(f"field {path!r}: {done} is an array of {node.size} value(s) "
                                  f"(shape {tuple(node.shape)}); index it with 0..{node.size - 1}, "
                                  f"e.g. --field {done}.0")
            node = node.reshape(-1)[int(head)].item()
        else:
            raise ConfigError(f"field {path!r}: {done} is a single value ({_scalar(node)}); "
                              f"nothing to index with {rest!r}: use --field {done}")
    return True, node


def check_field(msg_type: type[Message], path: str) -> None:
    """Raise :class:`ConfigError` if ``path`` cannot start with a field of ``msg_type`` (or,
    below ``header``, of the header: its fields are the same in every message)."""
    first, _, rest = path.partition(".")
    fields = ["header", *msg_type._body_fields]  # type: ignore[attr-defined]
    if first not in fields:
        raise ConfigError(f"{msg_type.TYPE} has no field {first!r}; fields: {', '.join(fields)}")
    header_fields = [f.name for f in dataclasses.fields(Header)]
    second = rest.split(".", 1)[0]
    if first == "header" and rest and second not in header_fields:
        raise ConfigError(f"field {path!r}: the header has no field {second!r}; its fields: "
                          f"{', '.join(header_fields)}")


def _scalar(v: Any) -> str:
    if v is None:
        return "null"
    if isinstance(v, (bool, np.bool_)):
        return "true" if v else "false"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        f = float(v)
        if f != f:
            return ".nan"
        if f in (float("inf"), float("-inf")):
            return ".inf" if f > 0 else "-.inf"
        return str(v) if isinstance(v, np.float32) else repr(f)
    s = str(v)
    if _PLAIN.fullmatch(s) and s not in _RESERVED:
        return s
    return json.dumps(s, ensure_ascii=False)


def _array_inline(a: np.ndarray, no_arr: bool, truncate: int) -> str:
    dtype = "bool" if a.dtype.kind == "b" else a.dtype.name
    if no_arr:
        return f"'<array {dtype} {tuple(a.shape)}>'"
    flat = a.reshape(-1)
    if flat.size <= truncate and a.ndim == 1:
        return "[" + ", ".join(_scalar(x) for x in flat) + "]"
    shown = ", ".join(_scalar(x) for x in flat[:truncate])
    summary = f"  # {dtype} {tuple(a.shape)}"
    if a.dtype.kind == "b":
        summary += f" {int(flat.sum())} true"
    elif flat.size:
        summary += f" min {_scalar(flat.min())} max {_scalar(flat.max())}"
    return f"[{shown}, '...']{summary}"


def render_yaml(value: Any, *, no_arr: bool = False, truncate: int = 16, indent: int = 0) -> list[str]:
    """Lines of YAML-ish text for ``value`` (a tree from :func:`as_tree` or a part of it)."""
    pad = "  " * indent
    if isinstance(value, dict):
        if not value:
            return [pad + "{}"]
        lines = []
        for k, v in value.items():
            key = _scalar(str(k))
            if isinstance(v, dict) and v:
                lines.append(f"{pad}{key}:")
                lines.extend(render_yaml(v, no_arr=no_arr, truncate=truncate, indent=indent + 1))
            elif isinstance(v, np.ndarray):
                lines.append(f"{pad}{key}: {_array_inline(v, no_arr, truncate)}")
            elif isinstance(v, list):
                lines.append(f"{pad}{key}: [" + ", ".join(_scalar(x) for x in v) + "]")
            else:
                lines.append(f"{pad}{key}: {'{}' if isinstance(v, dict) else _scalar(v)}")
        return lines
    if isinstance(value, np.ndarray):
        return [pad + _array_inline(value, no_arr, truncate)]
    if isinstance(value, list):
        return [pad + "[" + ", ".join(_scalar(x) for x in value) + "]"]
    return [pad + _scalar(value)]


def flatten(value: Any, prefix: str = "", *, no_arr: bool = False) -> Iterator[tuple[str, Any]]:
    """``(column, scalar)`` pairs: maps as ``a.b``, array elements as ``a.0``, ``a.1``…"""
    if isinstance(value, dict):
        for k, v in value.items():
            yield from flatten(v, f"{prefix}.{k}" if prefix else str(k), no_arr=no_arr)
    elif isinstance(value, np.ndarray):
        if not no_arr:
            for i, x in enumerate(value.reshape(-1).tolist()):
                yield f"{prefix}.{i}", x
    elif isinstance(value, list):
        for i, x in enumerate(value):
            yield from flatten(x, f"{prefix}.{i}", no_arr=no_arr)
    else:
        yield prefix or "value", value


def csv_cell(v: Any) -> str:
    """One CSV cell (the caller's csv writer quotes it if needed)."""
    if v is None:
        return ""
    return v if isinstance(v, str) else _scalar(v)
