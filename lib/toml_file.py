"""Finding and reading a TOML settings file (launch, scene, material); errors name the file."""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Any

from slipstack.lib.errors import ConfigError

__all__ = ["read_toml", "resolve_path", "loads", "toml_value", "SHIPPED_ROOT"]

#: Where the shipped launch files (``files/``), scenes and materials live.
SHIPPED_ROOT = Path(__file__).resolve().parents[1] / "launch"


def loads(text: str) -> dict[str, Any]:
    """``tomllib.loads``; nesting deeper than the parser can follow is a ``TOMLDecodeError`` like
    any other syntax error (the parser recurses, and ran out of stack: a traceback)."""
    try:
        return tomllib.loads(text)
    except RecursionError:
        raise tomllib.TOMLDecodeError("arrays or tables nested too deeply") from None


def toml_value(value: Any) -> str:
    """``value`` as a TOML file writes it (``true``, ``3.0``, ``nan``, ``"text"``, ``[1, 2]``,
    ``{a = 1}``); ``None``, which TOML has not, as ``none`` (what ``name:=none`` gives)."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)  # JSON's escapes are TOML's basic string's
    if isinstance(value, float) and not math.isfinite(value):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {toml_value(v)}" for k, v in value.items()) + "}"
    return repr(value)


def read_toml(path: str | Path, kind: str) -> dict[str, Any]:
    """The parsed TOML of ``path``, a ``kind`` file ("scene", "material").

    Raises:
        ConfigError: unreadable file or TOML syntax error, naming the file.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot read {kind} file {path}: {exc.strerror}") from exc
    try:
        return loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path.name}: TOML syntax error: {exc}") from exc


def resolve_path(value: str, base: Path, folder: str) -> Path:
    """The file a launch or scene file names: shipped first, a file of your own only as a path.

    A bare name (``fig15``, ``stack.toml``) is the shipped file in ``launch/<folder>/``;
    if none is shipped, a name ending in ``.toml`` is looked for in ``base``. A name with
    a ``/`` is a path, relative to ``base``. So a stray file in the current directory
    never shadows a shipped one.

    Raises:
        ConfigError: no such file (says where it looked).
    """
    shipped = SHIPPED_ROOT / folder
    if "/" in value:
        cands = [base / value]
    else:
        cands = [shipped / value, shipped / f"{value}.toml"] + ([base / value] if value.endswith(".toml") else [])
    for cand in cands:
        if cand.is_file():
            return cand.resolve()
    hint = "" if "/" in value else f"; for a file of your own give a path, e.g. ./{value}"
    if "=" in value and ":=" not in value:
        name, _, arg = value.partition("=")
        hint = f"; launch arguments take ':=': {name}:={arg}"
    elif folder == "files":
        hint += f". Shipped launch files: {', '.join(sorted(f.stem for f in shipped.glob('*.toml')))}"
    raise ConfigError(f"cannot find {value!r} (looked in {', '.join(str(c) for c in cands)}){hint}")
