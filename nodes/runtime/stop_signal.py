"""SIGINT and SIGTERM as a flag: a bus tool finishes its file or socket, then stops."""

from __future__ import annotations

import signal
from types import FrameType, TracebackType

__all__ = ["StopSignal"]


class StopSignal:
    """While entered, SIGINT/SIGTERM set :attr:`requested` instead of interrupting;
    the previous handlers come back on exit."""

    def __init__(self) -> None:
        self.requested = False
        self._old: dict[int, object] = {}

    def _set(self, signum: int, frame: FrameType | None) -> None:
        self.requested = True

    def install(self) -> "StopSignal":
        """Take over SIGINT and SIGTERM; returns self."""
        self._old = {s: signal.signal(s, self._set) for s in (signal.SIGINT, signal.SIGTERM)}
        return self

    def restore(self) -> None:
        """Give SIGINT and SIGTERM back to their previous handlers."""
        for s, handler in self._old.items():
            signal.signal(s, handler)
        self._old = {}

    def __enter__(self) -> "StopSignal":
        return self.install()

    def __exit__(self, exc_type: type | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        self.restore()
