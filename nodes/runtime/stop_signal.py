"""Ctrl-C and SIGTERM stop a bus tool, whatever signal handling it inherited.

A process started in the background by a non-interactive shell (a script's ``cmd &``,
a CI job) inherits SIGINT *ignored*, and Python then never raises KeyboardInterrupt:
``kill -INT`` of such a ``topic pub`` was ignored until it had sent all its messages.
The tools that run until stopped take both signals over at start, so they always end
through their ``except KeyboardInterrupt`` and ``finally`` (closing sockets, removing
their registration from the run directory).
"""

from __future__ import annotations

import signal
from types import FrameType

__all__ = ["stop_on_signals"]


def _interrupt(signum: int, frame: FrameType | None) -> None:
    raise KeyboardInterrupt(signal.Signals(signum).name)


def stop_on_signals() -> None:
    """SIGINT and SIGTERM raise KeyboardInterrupt in the main thread from now on."""
    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, _interrupt)
