"""Read the YAML flow values a user types on the command line (``topic pub``).

A small, strict subset of YAML 1.2 flow style, enough for message fields::

    {f_n_desired: 12.0, law: manual}
    force: [1.5, 0, -2e-3], status: "ok, really"      # outer braces may be left out

Scalars: integers, floats (``1.5``, ``-2e-3``, ``.inf``, ``-.inf``, ``.nan``),
``true``/``false``, ``null``/``~``, quoted strings (``"…"`` with JSON escapes or
``'…'`` with ``''`` for a quote) and plain strings. Nested ``{}`` and ``[]`` are
allowed. Anything else raises :class:`~slipstack.lib.errors.ConfigError` saying
where. (PyYAML is not a dependency; this covers what ``ros2 topic pub`` users type.)
"""

from __future__ import annotations

import json
import re
from typing import Any

from slipstack.lib.errors import ConfigError

__all__ = ["parse_flow"]

_INT = re.compile(r"[-+]?(0|[1-9][0-9_]*)")
_FLOAT = re.compile(r"[-+]?(\.[0-9]+|[0-9][0-9_]*(\.[0-9]*)?)([eE][-+]?[0-9]+)?")
_SPECIAL = {
    "true": True, "True": True, "false": False, "False": False, "null": None, "~": None,
    ".inf": float("inf"), "+.inf": float("inf"), "-.inf": float("-inf"), ".nan": float("nan"),
}
_DELIMS = ",:[]{}"


class _Reader:
    def __init__(self, text: str) -> None:
        self.text = text
        self.pos = 0

    def fail(self, what: str) -> ConfigError:
        return ConfigError(f"cannot read {self.text!r} at character {self.pos + 1}: {what}")

    def skip_space(self) -> None:
        while self.pos < len(self.text) and self.text[self.pos].isspace():
            self.pos += 1

    def peek(self) -> str:
        self.skip_space()
        return self.text[self.pos] if self.pos < len(self.text) else ""

    def expect(self, ch: str) -> None:
        if self.peek() != ch:
            raise self.fail(f"expected {ch!r}")
        self.pos += 1

    def value(self) -> Any:
        ch = self.peek()
        if ch == "{":
            return self.mapping()
        if ch == "[":
            return self.sequence()
        if ch in "\"'":
            return self.quoted()
        return self.plain()

    def mapping(self) -> dict[str, Any]:
        self.expect("{")
        out: dict[str, Any] = {}
        while self.peek() != "}":
            key = self.quoted() if self.peek() in "\"'" else self.plain(raw=True)
            if not key:
                raise self.fail("expected a key")
            self.expect(":")
            out[str(key)] = self.value()
            if self.peek() != ",":
                break
            self.pos += 1
        self.expect("}")
        return out

    def sequence(self) -> list[Any]:
        self.expect("[")
        out: list[Any] = []
        while self.peek() != "]":
            out.append(self.value())
            if self.peek() != ",":
                break
            self.pos += 1
        self.expect("]")
        return out

    def quoted(self) -> str:
        self.skip_space()
        quote = self.text[self.pos]
        if quote == '"':
            decoder = json.JSONDecoder()
            try:
                s, end = decoder.raw_decode(self.text, self.pos)
            except json.JSONDecodeError:
                raise self.fail("unterminated or invalid double-quoted string") from None
            self.pos = end
            return s
        end = self.pos + 1
        parts = []
        while True:
            nxt = self.text.find("'", end)
            if nxt < 0:
                raise self.fail("unterminated single-quoted string")
            parts.append(self.text[end:nxt])
            if self.text.startswith("''", nxt):
                parts.append("'")
                end = nxt + 2
                continue
            self.pos = nxt + 1
            return "".join(parts)

    def plain(self, raw: bool = False) -> Any:
        self.skip_space()
        start = self.pos
        while self.pos < len(self.text):
            ch = self.text[self.pos]
            # ':' ends a plain scalar only before a space or a delimiter (as in YAML).
            if ch in ",[]{}" or (ch == ":" and (self.pos + 1 == len(self.text) or self.text[self.pos + 1] in " \t" + _DELIMS)):
                break
            if ch == "#" and self.pos > start and self.text[self.pos - 1].isspace():
                raise self.fail("comments are not allowed")
            self.pos += 1
        token = self.text[start:self.pos].strip()
        if raw:
            return token
        if not token:
            raise self.fail("expected a value")
        if token in _SPECIAL:
            return _SPECIAL[token]
        if _INT.fullmatch(token):
            return int(token.replace("_", ""))
        if _FLOAT.fullmatch(token):
            return float(token.replace("_", ""))
        return token


def parse_flow(text: str) -> Any:
    """Parse one flow value; a bare ``key: value, …`` list is read as a mapping.

    Raises:
        ConfigError: the text is not in the supported subset (says where).
    """
    stripped = text.strip()
    if not stripped:
        return {}
    if stripped[0] not in "{[\"'" and re.match(r"^[^,\[\]{}]*?:(\s|$)", stripped):
        stripped = "{" + stripped + "}"
    reader = _Reader(stripped)
    value = reader.value()
    if reader.peek():
        raise reader.fail("unexpected text after the value")
    return value
