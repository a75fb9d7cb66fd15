"""Loose values read into typed settings, with one error style.

A :class:`ConfigTable` wraps a table of loose values — a TOML table (a scene file), or
the text values of a device URL's query — and is consumed key by key: each getter
removes its key, checks the value's type and range and returns it typed; ``finish()``
rejects whatever is left (a misspelt key). Every error is a
:class:`~slipstack.lib.errors.ConfigError` worded ``<source>: <where>.<key>: <what is
wrong>``, e.g. ``fig15.toml: contact.mu: must be > 0, got -1.0`` or
``rdt://host?cpf=x: cpf: must be a number, got 'x'``.
"""

from __future__ import annotations

import math
from typing import Any, Mapping

from slipstack.lib.errors import ConfigError

__all__ = ["REQUIRED", "ConfigTable"]

REQUIRED: Any = object()
"""The default of a key that must be given."""

_TRUE = ("true", "1", "yes", "on")
_FALSE = ("false", "0", "no", "off")


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

    def error(self, name: str, message: str) -> ConfigError:
        """The error for key ``name``, in this module's wording."""
        return ConfigError(f"{self._source}: {self.key(name)}: {message}")

    def has(self, name: str) -> bool:
        return name in self._data

    def _pop(self, name: str, default: Any) -> Any:
        self._read.append(name)
        if name in self._data:
            return self._data.pop(name)
        if default is REQUIRED:
            raise self.error(name, "missing required key")
        return default

    def _number(self, name: str, value: Any, kind: type) -> Any:
        """``value`` as a ``kind`` (int or float), parsed if it is text and the table holds text."""
        if self._from_text and isinstance(value, str):
            try:
                return kind(value)
            except ValueError:
                pass
        elif not isinstance(value, bool) and isinstance(value, int if kind is int else (int, float)):
            return value
        raise self.error(name, f"must be {'an integer' if kind is int else 'a number'}, got {value!r}")

    def real(self, name: str, default: Any = REQUIRED, *, lo: float | None = None,
             hi: float | None = None, lo_open: bool = False) -> float:
        """A finite number (float) within ``lo`` (exclusive if ``lo_open``) … ``hi``; a
        ``None`` default passes through."""
        value = self._pop(name, default)
        if value is None:
            return value
        value = self._as_real(name, value)
        if lo is not None and (value < lo or (lo_open and value == lo)):
            raise self.error(name, f"must be {'>' if lo_open else '>='} {lo}, got {value}")
        if hi is not None and value > hi:
            raise self.error(name, f"must be <= {hi}, got {value}")
        return value

    def _as_real(self, name: str, value: Any) -> float:
        value = float(self._number(name, value, float))
        if not math.isfinite(value):
            raise self.error(name, f"must be finite, got {value}")
        return value

    def integer(self, name: str, default: Any = REQUIRED, *, lo: int | None = None, hi: int | None = None) -> int:
        """An integer within ``lo`` … ``hi``."""
        value = self._number(name, self._pop(name, default), int)
        if lo is not None and value < lo:
            raise self.error(name, f"must be >= {lo}, got {value}")
        if hi is not None and value > hi:
            raise self.error(name, f"must be <= {hi}, got {value}")
        return value

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
        if self._from_text and isinstance(value, str) and value.lower() in _TRUE + _FALSE:
            return value.lower() in _TRUE
        if value is not None and not isinstance(value, bool):
            raise self.error(name, f"must be true or false, got {value!r}")
        return value

    def vector(self, name: str, n: int, default: Any = REQUIRED, *,
               lo: float | None = None) -> tuple[float, ...] | None:
        """A list of ``n`` finite numbers, each >= ``lo`` if given."""
        value = self._pop(name, default)
        if value is None:
            return None
        if not isinstance(value, (list, tuple)) or len(value) != n:
            raise self.error(name, f"must be a list of {n} numbers, got {value!r}")
        out = tuple(self._as_real(name, v) for v in value)
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
