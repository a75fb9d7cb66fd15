"""The one exception tree of slipstack (docs/architecture.md §10.2), and how a command reports it."""

from __future__ import annotations

import sys
from typing import Callable

__all__ = [
    "SlipstackError",
    "DecodeError",
    "ConfigError",
    "run_guarded",
]


class SlipstackError(Exception):
    """Base class of every error slipstack raises on purpose."""


class DecodeError(SlipstackError):
    """A message frame could not be decoded or failed validation; names the field."""


class ConfigError(SlipstackError):
    """A parameter, launch file or scene file is invalid; says what to change."""

def run_guarded(command: str, func: Callable[[], int | None]) -> int:
    """The exit code of ``func()``; a SlipstackError becomes one line on stderr and exit 2."""
    try:
        return int(func() or 0)
    except SlipstackError as exc:
        print(f"slipstack {command}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # output piped into `head` and closed: not an error
        sys.stderr.close()
        return 0
