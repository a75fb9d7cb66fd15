"""Non-blocking UDP client link (for ATI RDT) with reconnect and stale detection.

The socket is ``connect()``-ed to the device, so only its datagrams are received
and an ICMP port-unreachable (device gone) surfaces as ECONNREFUSED on the next
send/recv: the link then closes, reports ``disconnected`` and reopens a fresh
socket with exponential back-off, calling ``on_open(now_ns)`` after each open so
the protocol layer can send its start request again.
"""

from __future__ import annotations

import socket
from typing import Callable

from . import ReconnectingLink

__all__ = ["UdpLink"]


class UdpLink(ReconnectingLink[socket.socket]):
    """UDP client for one device address; all times are the caller's clock in ns."""

    def __init__(
        self, host: str, port: int, *, stale_after_s: float, backoff_min_s: float = 0.05,
        backoff_max_s: float = 2.0, on_open: Callable[[int], None] | None = None,
        max_datagrams: int = 1024, rcvbuf: int = 1 << 20,
    ) -> None:
        super().__init__(stale_after_s=stale_after_s, backoff_min_s=backoff_min_s,
                         backoff_max_s=backoff_max_s, on_open=on_open)
        self.address = (host, port)
        self.max_datagrams = max_datagrams
        self.rcvbuf = rcvbuf

    def _connect(self) -> socket.socket:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setblocking(False)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, self.rcvbuf)
            sock.connect(self.address)
        except OSError:
            sock.close()
            raise
        return sock

    def _disconnect(self, handle: socket.socket) -> None:
        handle.close()

    def _fileno(self, handle: socket.socket) -> int | None:
        return handle.fileno()

    def send(self, data: bytes, now_ns: int) -> bool:
        """Send one datagram; False if closed, full or refused (refused closes the link)."""
        if self._handle is None:
            return False
        try:
            self._handle.send(data)
        except BlockingIOError:
            return False
        except OSError as e:
            self._lost(now_ns, e)
            return False
        return True

    def recv(self, now_ns: int) -> list[bytes]:
        """Every datagram available now (up to max_datagrams); reopens when due."""
        sock = self._ensure_open(now_ns)
        if sock is None:
            return []
        out: list[bytes] = []
        try:
            while len(out) < self.max_datagrams:
                out.append(sock.recv(65536))
        except BlockingIOError:
            pass
        except OSError as e:
            self._lost(now_ns, e)
        if out:
            self.freshness.touch(now_ns)
        return out
