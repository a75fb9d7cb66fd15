"""Non-blocking serial link (pyserial) with reconnect, back-off and stale detection.

The port is a device path (``/dev/ttyUSB0``, a symlink such as an emulator's
stable pty path) or any pyserial URL (``loop://``, ``socket://host:port``). Reads
return the bytes available now and never wait; writes return how many bytes the
driver accepted. An I/O error (e.g. EIO when a USB adapter or a pty master goes
away) closes the port, reports ``disconnected`` and schedules a reopen with
exponential back-off; every successful (re)open calls ``on_open(now_ns)`` so the
protocol layer can redo its handshake. pyserial discards pending input at open.
"""

from __future__ import annotations

from typing import Callable

import serial

from . import ReconnectingLink

__all__ = ["SerialLink"]


class SerialLink(ReconnectingLink[serial.SerialBase]):
    """One serial port; all times are the caller's clock in integer ns."""

    def __init__(
        self, port: str, *, baudrate: int, stale_after_s: float, backoff_min_s: float = 0.05,
        backoff_max_s: float = 2.0, on_open: Callable[[int], None] | None = None,
        max_read: int = 1 << 16,
    ) -> None:
        super().__init__(stale_after_s=stale_after_s, backoff_min_s=backoff_min_s,
                         backoff_max_s=backoff_max_s, on_open=on_open)
        self.port = port
        self.baudrate = baudrate
        self.max_read = max_read
        self.write_shortfall = 0

    def _connect(self) -> serial.SerialBase:
        return serial.serial_for_url(self.port, baudrate=self.baudrate, timeout=0, write_timeout=0, exclusive=True)

    def _disconnect(self, handle: serial.SerialBase) -> None:
        try:
            handle.close()
        except (serial.SerialException, OSError):
            pass

    def _fileno(self, handle: serial.SerialBase) -> int | None:
        try:
            return handle.fileno()
        except (AttributeError, OSError, serial.SerialException):
            return None  # URL ports (loop://) have no descriptor

    def read(self, now_ns: int) -> bytes:
        """Bytes available now (b"" if none); reopens a lost port when its retry is due."""
        ser = self._ensure_open(now_ns)
        if ser is None:
            return b""
        try:
            data = ser.read(self.max_read)
        except (serial.SerialException, OSError) as e:
            self._lost(now_ns, e)
            return b""
        if data:
            self.freshness.touch(now_ns)
        return data

    def write(self, data: bytes, now_ns: int) -> int:
        """Queue *data* without blocking; returns bytes accepted (0 if not open)."""
        if self._handle is None:
            return 0
        try:
            n = self._handle.write(data) or 0
        except (serial.SerialException, OSError) as e:
            self._lost(now_ns, e)
            return 0
        self.write_shortfall += len(data) - n
        return n
