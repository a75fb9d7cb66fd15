"""Reading a TOML settings file (scene, material) with errors that name the file."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from slipstack.lib.errors import ConfigError

__all__ = ["read_toml"]


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
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path.name}: TOML syntax error: {exc}") from exc
