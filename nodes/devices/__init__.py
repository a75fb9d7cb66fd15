"""Device transport layers, driver back-ends and device emulators.

``serial_link`` / ``udp_link`` move bytes without blocking, ``backends`` turn them
into samples (chosen by URL, e.g. ``rdt://127.0.0.1:49152``), ``emulators`` speak
the device side over a pty or loopback UDP. This module holds the link state the
two transports and the back-ends share. Times are integer nanoseconds of the
caller's clock (``now_ns``); nothing here reads a clock or sleeps.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from enum import Enum
from typing import Callable, Generic, TypeVar

__all__ = ["LinkStatus", "Backoff", "Freshness", "ReconnectingLink"]

H = TypeVar("H")


class LinkStatus(str, Enum):
    """``ok``: data within the stale limit; ``stale``: open but silent;
    ``disconnected``: not open (a reconnect is scheduled)."""

    OK = "ok"
    STALE = "stale"
    DISCONNECTED = "disconnected"


class Backoff:
    """Exponential reconnect back-off: min_s, 2·min_s, … capped at max_s."""

    def __init__(self, min_s: float, max_s: float) -> None:
        self.min_ns = int(min_s * 1e9)
        self.max_ns = int(max_s * 1e9)
        self._delay_ns = self.min_ns
        self.next_attempt_ns: int | None = None

    def failed(self, now_ns: int) -> None:
        """Schedule the next attempt after the current delay, then double the delay."""
        self.next_attempt_ns = now_ns + self._delay_ns
        self._delay_ns = min(2 * self._delay_ns, self.max_ns)

    def succeeded(self) -> None:
        self._delay_ns = self.min_ns
        self.next_attempt_ns = None

    def due(self, now_ns: int) -> bool:
        return self.next_attempt_ns is None or now_ns >= self.next_attempt_ns


class Freshness:
    """Remembers when something last arrived; stale after ``stale_after_s``."""

    def __init__(self, stale_after_s: float) -> None:
        self.stale_after_ns = int(stale_after_s * 1e9)
        self.last_ns: int | None = None

    def touch(self, now_ns: int) -> None:
        self.last_ns = now_ns

    def is_stale(self, now_ns: int) -> bool:
        return self.last_ns is None or now_ns - self.last_ns > self.stale_after_ns

    def deadline_ns(self) -> int | None:
        """First instant at which it is stale if nothing arrives (None without data)."""
        return None if self.last_ns is None else self.last_ns + self.stale_after_ns + 1


class ReconnectingLink(ABC, Generic[H]):
    """Open/lost/reopen bookkeeping shared by the serial and UDP links.

    A subclass says how to connect (``_connect`` raising OSError-like errors on
    failure), disconnect and get a descriptor; it calls ``_ensure_open`` before I/O
    and ``_lost`` when I/O fails. ``on_open(now_ns)`` runs after every open.
    """

    def __init__(self, *, stale_after_s: float, backoff_min_s: float, backoff_max_s: float,
                 on_open: Callable[[int], None] | None) -> None:
        self.on_open = on_open
        self.backoff = Backoff(backoff_min_s, backoff_max_s)
        self.freshness = Freshness(stale_after_s)
        self.reconnects = 0
        self.last_error = ""
        self._handle: H | None = None
        self._opened_once = False
        self._wanted = False

    @abstractmethod
    def _connect(self) -> H:
        """Open the transport; raise OSError or ValueError on failure."""

    @abstractmethod
    def _disconnect(self, handle: H) -> None:
        """Close the transport, ignoring errors."""

    @abstractmethod
    def _fileno(self, handle: H) -> int | None: ...

    @property
    def is_open(self) -> bool:
        return self._handle is not None

    def open(self, now_ns: int) -> bool:
        """Try to open now; on failure schedule a retry with back-off. True if open."""
        self._wanted = True
        if self._handle is not None:
            return True
        try:
            self._handle = self._connect()
        except (OSError, ValueError) as e:  # SerialException is an OSError
            self.last_error = str(e)
            self.backoff.failed(now_ns)
            return False
        self.backoff.succeeded()
        if self._opened_once:
            self.reconnects += 1
        self._opened_once = True
        if self.on_open is not None:
            self.on_open(now_ns)
        return True

    def _ensure_open(self, now_ns: int) -> H | None:
        """The open handle, reopening when a retry is due; None if still closed."""
        if self._handle is None and self._wanted and self.backoff.due(now_ns):
            self.open(now_ns)
        return self._handle

    def _lost(self, now_ns: int, error: Exception) -> None:
        self.last_error = str(error)
        handle, self._handle = self._handle, None
        if handle is not None:
            self._disconnect(handle)
        self.backoff.failed(now_ns)

    def drop(self, now_ns: int, reason: str) -> None:
        """Close the link because the protocol gave up on it (``reason``); reopen after the back-off."""
        if self._handle is not None:
            self._lost(now_ns, OSError(reason))

    def status(self, now_ns: int) -> LinkStatus:
        """ok / stale (nothing received for stale_after_s) / disconnected."""
        if self._handle is None:
            return LinkStatus.DISCONNECTED
        return LinkStatus.STALE if self.freshness.is_stale(now_ns) else LinkStatus.OK

    def fileno(self) -> int | None:
        """Descriptor to wait on; None while closed. Changes across reconnects."""
        return None if self._handle is None else self._fileno(self._handle)

    def next_attempt_ns(self) -> int | None:
        """When a lost link will be retried (None while open or after close())."""
        return None if self._handle is not None or not self._wanted else self.backoff.next_attempt_ns

    def close(self) -> None:
        """Close; nothing reopens it until open() is called again."""
        self._wanted = False
        handle, self._handle = self._handle, None
        if handle is not None:
            self._disconnect(handle)
