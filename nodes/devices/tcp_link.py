"""Non-blocking TCP client link (for the WSG gripper) with reconnect and stale detection.

The connect never waits: it starts (``EINPROGRESS``) and completes on a later read or
write, once the socket is writable; a refused or failed connect, a reset, or the peer
closing (a read of zero bytes) closes the link, reports ``disconnected`` and reconnects
with exponential back-off, calling ``on_open(now_ns)`` after each connect so the protocol
layer can redo its handshake. Writes that the socket cannot take now wait in a bounded
buffer (:data:`MAX_PENDING_BYTES`); beyond it bytes are dropped and counted.
"""

from __future__ import annotations

import errno
import select
import socket
from typing import Callable

from . import ReconnectingLink

__all__ = ["TcpLink", "MAX_PENDING_BYTES"]

MAX_PENDING_BYTES = 1 << 16
"""Bytes waiting to be sent, at most; a command link that falls this far behind is stuck."""


class _Connection:
    """A socket and what is still to be sent on it; ``connected`` once the connect completed."""

    def __init__(self, sock: socket.socket, connected: bool) -> None:
        self.sock = sock
        self.connected = connected
        self.pending = bytearray()


class TcpLink(ReconnectingLink[_Connection]):
    """One TCP connection to ``(host, port)``; all times are the caller's clock in ns."""

    def __init__(self, host: str, port: int, *, stale_after_s: float, backoff_min_s: float = 0.05,
                 backoff_max_s: float = 2.0, on_open: Callable[[int], None] | None = None,
                 max_read: int = 1 << 16) -> None:
        super().__init__(stale_after_s=stale_after_s, backoff_min_s=backoff_min_s,
                         backoff_max_s=backoff_max_s, on_open=on_open)
        self.address = (host, port)
        self.max_read = max_read
        self.write_shortfall = 0

    def _connect(self) -> _Connection:
        sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            sock.setblocking(False)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            code = sock.connect_ex(self.address)
            if code not in (0, errno.EINPROGRESS):
                raise OSError(code, f"connect to {self.address[0]}:{self.address[1]}: {errno.errorcode.get(code, code)}")
        except OSError:
            sock.close()
            raise
        return _Connection(sock, code == 0)

    def _disconnect(self, handle: _Connection) -> None:
        handle.sock.close()

    def _fileno(self, handle: _Connection) -> int | None:
        return handle.sock.fileno()

    def _ready(self, now_ns: int) -> _Connection | None:
        """The connection once its connect completed (None while pending or closed)."""
        conn = self._ensure_open(now_ns)
        if conn is None or conn.connected:
            return conn
        _, writable, _ = select.select([], [conn.sock], [], 0)
        if not writable:
            return None
        code = conn.sock.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR)
        if code:
            self._lost(now_ns, OSError(code, f"connect to {self.address[0]}:{self.address[1]}: "
                                             f"{errno.errorcode.get(code, code)}"))
            return None
        conn.connected = True
        return conn

    @property
    def connected(self) -> bool:
        """The connect completed (and the link has not been lost since)."""
        return self._handle is not None and self._handle.connected

    def read(self, now_ns: int) -> bytes:
        """Bytes available now (b"" if none, while connecting or closed); flushes pending writes."""
        conn = self._ready(now_ns)
        if conn is None:
            return b""
        self._flush(conn, now_ns)
        try:
            data = conn.sock.recv(self.max_read)
        except BlockingIOError:
            return b""
        except OSError as e:
            self._lost(now_ns, e)
            return b""
        if not data:
            self._lost(now_ns, OSError(f"{self.address[0]}:{self.address[1]} closed the connection"))
            return b""
        self.freshness.touch(now_ns)
        return data

    def write(self, data: bytes, now_ns: int) -> int:
        """Queue ``data`` and send what the socket takes now; bytes accepted (0 if closed, or
        the pending buffer is full)."""
        conn = self._handle
        if conn is None or len(conn.pending) + len(data) > MAX_PENDING_BYTES:
            self.write_shortfall += len(data)
            return 0
        conn.pending += data
        if self._ready(now_ns) is conn:
            self._flush(conn, now_ns)
        return len(data)

    def _flush(self, conn: _Connection, now_ns: int) -> None:
        if not conn.pending:
            return
        try:
            sent = conn.sock.send(conn.pending)
        except BlockingIOError:
            return
        except OSError as e:
            self._lost(now_ns, e)
            return
        del conn.pending[:sent]
