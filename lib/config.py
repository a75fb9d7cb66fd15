"""Loose values read into typed settings, with one error style.

One value: :func:`read_flag`, :func:`read_number` and :func:`read_typed` (by a type
hint, for node parameters and launch arguments). A table of them: a
:class:`ConfigTable` wraps a TOML table (a scene file, a launch file's node entry) or
the text values of a device URL's query, and is consumed key by key: each getter
removes its key, checks the value's type and range and returns it typed; ``finish()``
rejects whatever is left (a misspelt key).

More in docs/modules.md, `lib/config.py`.
"""

from __future__ import annotations

import math
import types
import typing
from typing import Any, Mapping

from slipstack.lib.errors import ConfigError

__all__ = ["REQUIRED", "ConfigTable", "read_flag", "read_number", "read_typed"]

REQUIRED: Any = object()
"""The default of a key that must be given."""

_TRUE = ("true", "1", "yes", "on")
_FALSE = ("false", "0", "no", "off")


def read_flag(value: Any, where: str, *, from_text: bool = True) -> bool:
    """``value`` as a bool: a bool, or (``from_text``) one of the flag words."""
    if isinstance(value, bool):
        return value
    if from_text and isinstance(value, str) and value.strip().lower() in _TRUE + _FALSE:
        return value.strip().lower() in _TRUE
    raise ConfigError(f"{where}: must be true or false, got {value!r}")


def read_number(value: Any, where: str, kind: type = float, *, from_text: bool = True, finite: bool = True,
                lo: float | None = None, hi: float | None = None, lo_open: bool = False) -> Any:
    """``value`` as a ``kind`` (float or int) within ``lo`` (exclusive if ``lo_open``) … ``hi``.

    A bool is no number; an int is a float; a float is an int only if it is whole;
    text is parsed if ``from_text``; ``finite`` refuses NaN and ±inf.
    """
    number: Any = None
    if isinstance(value, str):
        if from_text:
            try:
                number = kind(value.strip())
            except ValueError:
                pass
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        if kind is float:
            number = float(value)
        elif isinstance(value, int) or value.is_integer():
            number = int(value)
    if number is None:
        raise ConfigError(f"{where}: must be {'an integer' if kind is int else 'a number'}, got {value!r}")
    if finite and not math.isfinite(number):
        raise ConfigError(f"{where}: must be finite, got {value!r}")
    if lo is not None and (number < lo or (lo_open and number == lo)):
        raise ConfigError(f"{where}: must be {'>' if lo_open else '>='} {lo}, got {value!r}")
    if hi is not None and number > hi:
        raise ConfigError(f"{where}: must be <= {hi}, got {value!r}")
    return number


def read_typed(value: Any, hint: Any, where: str) -> Any:
    """``value`` (typed, or text) as type ``hint``: bool, int, float (NaN and ±inf
    allowed: a parameter may mean "unset" by NaN), str, a list or tuple of those (text:
    comma-separated), dict, or ``X | None`` (``None`` or ``"none"`` give None)."""
    origin = typing.get_origin(hint) or hint
    if origin is typing.Union or origin is types.UnionType:
        if value is None or value == "none":
            return None
        return read_typed(value, next(a for a in typing.get_args(hint) if a is not type(None)), where)
    if origin is bool:
        return read_flag(value, where)
    if origin in (int, float):
        return read_number(value, where, origin, finite=origin is int)
    if origin is str:
        if isinstance(value, (dict, list, tuple)):
            raise ConfigError(f"{where}: must be a string, got {value!r}")
        return str(value)
    if origin in (list, tuple):
        if isinstance(value, str):
            value = [v for v in value.split(",") if v]
        if not isinstance(value, (list, tuple)):
            raise ConfigError(f"{where}: must be a list, got {value!r}")
        (item,) = typing.get_args(hint)[:1] or (str,)
        return origin(read_typed(v, item, where) for v in value)
    if origin is dict:
        if not isinstance(value, Mapping):
            raise ConfigError(f"{where}: must be a table, got {value!r}")
        return dict(value)
    return value


class ConfigTable:
    """A table of loose values being consumed key by key; errors name ``where.key``.

    Args:
        data: the values (a mapping; anything else is an error naming ``where``).
        where: the table's dotted place in its source ("" for the top level).
        source: what the values came from (a file name, a URL), first in every error.
        from_text: the values are text (a URL query, a command line): numbers and
            flags are parsed from it (``true``/``false``/``1``/``0``/``yes``/``no``/
            ``on``/``off``).
    """

    def __init__(self, data: Any, where: str, source: str, *, from_text: bool = False) -> None:
        if not isinstance(data, Mapping):
            raise ConfigError(f"{source}: {where or 'top level'}: must be a table")
        self._data = dict(data)
        self._where = where
        self._source = source
        self._from_text = from_text
        self._read: list[str] = []

    def key(self, name: str) -> str:
        """The dotted name of key ``name`` (``where.name``)."""
        return f"{self._where}.{name}" if self._where else name

    def _at(self, name: str) -> str:
        """Where key ``name`` is, as errors say it: ``<source>: <where>.<name>``."""
        return f"{self._source}: {self.key(name)}"

    def error(self, name: str, message: str) -> ConfigError:
        """The error for key ``name``, in this module's wording."""
        return ConfigError(f"{self._at(name)}: {message}")

    def has(self, name: str) -> bool:
        return name in self._data

    def _pop(self, name: str, default: Any) -> Any:
        self._read.append(name)
        if name in self._data:
            return self._data.pop(name)
        if default is REQUIRED:
            raise self.error(name, "missing required key")
        return default

    def real(self, name: str, default: Any = REQUIRED, *, lo: float | None = None,
             hi: float | None = None, lo_open: bool = False) -> float:
        """A finite number (float) within ``lo`` (exclusive if ``lo_open``) … ``hi``; a
        ``None`` default passes through."""
        value = self._pop(name, default)
        if value is None:
            return value
        return read_number(value, self._at(name), float, from_text=self._from_text, lo=lo, hi=hi, lo_open=lo_open)

    def integer(self, name: str, default: Any = REQUIRED, *, lo: int | None = None, hi: int | None = None) -> int:
        """An integer within ``lo`` … ``hi``."""
        return read_number(self._pop(name, default), self._at(name), int, from_text=self._from_text, lo=lo, hi=hi)

    def text(self, name: str, default: Any = REQUIRED, *, choices: tuple[str, ...] = ()) -> str:
        """A string, one of ``choices`` if given."""
        value = self._pop(name, default)
        if not isinstance(value, str):
            raise self.error(name, f"must be a string, got {value!r}")
        if choices and value not in choices:
            raise self.error(name, f"must be one of {', '.join(choices)}; got {value!r}")
        return value

    def flag(self, name: str, default: Any = REQUIRED) -> bool:
        """``true`` or ``false`` (in a text table also 1/0, yes/no, on/off); a ``None``
        default passes through."""
        value = self._pop(name, default)
        return value if value is None else read_flag(value, self._at(name), from_text=self._from_text)

    def vector(self, name: str, n: int, default: Any = REQUIRED, *,
               lo: float | None = None) -> tuple[float, ...] | None:
        """A list of ``n`` finite numbers, each >= ``lo`` if given."""
        value = self._pop(name, default)
        if value is None:
            return None
        if not isinstance(value, (list, tuple)) or len(value) != n:
            raise self.error(name, f"must be a list of {n} numbers, got {value!r}")
        out = tuple(read_number(v, self._at(name), float, from_text=self._from_text) for v in value)
        if lo is not None and min(out) < lo:
            raise self.error(name, f"entries must be >= {lo}, got {list(out)}")
        return out

    def raw(self, name: str, default: Any = REQUIRED) -> Any:
        """The value as given (the caller checks it, raising :meth:`error`)."""
        return self._pop(name, default)

    def table(self, name: str, required: bool = False) -> ConfigTable:
        """The sub-table under ``name`` (empty if absent and not ``required``)."""
        value = self._pop(name, REQUIRED if required else {})
        return ConfigTable(value, self.key(name), self._source, from_text=self._from_text)

    def child(self, data: Any, name: str) -> ConfigTable:
        """A table nested in this one under the display name ``name`` (e.g. "segments[0]")."""
        return ConfigTable(data, self.key(name), self._source, from_text=self._from_text)

    def finish(self) -> None:
        """Reject the keys nobody read, naming the ones that are known here."""
        if self._data:
            name = sorted(self._data)[0]
            known = ", ".join(sorted(set(self._read))) or "none"
            raise self.error(name, f"unknown key; known here: {known}")
