"""The public port of the ``foxglove`` node, for both names of the Foxglove WebSocket protocol.

The Foxglove SDK accepts only the subprotocol ``foxglove.sdk.v1``. Older Foxglove and Lichtblick
clients ask for ``foxglove.websocket.v1``, the same protocol under its older name (Foxglove's
stance, quoted in lichtblick-suite/lichtblick PR 819), and the SDK answers them "400 Missing
expected sec-websocket-protocol header". :class:`SubprotocolFront` reads each handshake. It
passes ``foxglove.sdk.v1`` to the SDK on a loopback port, renames the older name both ways,
and tells any other client in a 400 what it speaks. Then it copies bytes. It is bounded (clients,
handshake bytes and time).
"""

from __future__ import annotations

import socket
import threading

__all__ = ["SubprotocolFront", "SDK_SUBPROTOCOL", "OLD_SUBPROTOCOL"]

SDK_SUBPROTOCOL = b"foxglove.sdk.v1"
OLD_SUBPROTOCOL = b"foxglove.websocket.v1"
MAX_CLIENTS = 8
MAX_HEAD_BYTES = 8192
HEAD_TIMEOUT_S = 2.0
_HEADER = b"sec-websocket-protocol:"


def _offered(head: bytes) -> list[bytes]:
    """The subprotocols a client's handshake offers (``Sec-WebSocket-Protocol`` values)."""
    out: list[bytes] = []
    for line in head.split(b"\r\n")[1:]:
        if line.lower().startswith(_HEADER):
            out += [p.strip() for p in line[len(_HEADER):].split(b",")]
    return out


def _renamed(head: bytes, old: bytes, new: bytes) -> bytes:
    """``head`` with the ``Sec-WebSocket-Protocol`` header saying ``new`` where it said ``old``."""
    lines = head.split(b"\r\n")
    return b"\r\n".join(line.replace(old, new) if line.lower().startswith(_HEADER) else line for line in lines)


def _read_head(sock: socket.socket) -> tuple[bytes, bytes] | None:
    """(the HTTP head up to its blank line, the bytes after it), or None (too long, too slow, closed)."""
    data = b""
    while b"\r\n\r\n" not in data:
        if len(data) > MAX_HEAD_BYTES:
            return None
        chunk = sock.recv(4096)
        if not chunk:
            return None
        data += chunk
    head, _, rest = data.partition(b"\r\n\r\n")
    return head + b"\r\n\r\n", rest


class SubprotocolFront:
    """Listens on ``host:port``; hands clients to the SDK's server at ``127.0.0.1:sdk_port``."""

    def __init__(self, host: str, port: int, sdk_port: int) -> None:
        self.sdk_port = sdk_port
        self._listener = socket.create_server((host, port), reuse_port=False)
        self.port = self._listener.getsockname()[1]
        self._clients = threading.BoundedSemaphore(MAX_CLIENTS)
        self._open: set[socket.socket] = set()
        self._lock = threading.Lock()
        threading.Thread(target=self._accept, name="foxglove-front", daemon=True).start()

    def close(self) -> None:
        self._listener.close()
        with self._lock:
            for sock in list(self._open):
                _close(sock)

    def _accept(self) -> None:
        while True:
            try:
                client, _ = self._listener.accept()
            except OSError:  # closed
                return
            if not self._clients.acquire(blocking=False):
                _answer(client, b"503 Service Unavailable", f"at most {MAX_CLIENTS} viewers at once\n".encode())
                continue
            threading.Thread(target=self._serve, args=(client,), daemon=True).start()

    def _serve(self, client: socket.socket) -> None:
        upstream = None
        try:
            self._track(client)
            client.settimeout(HEAD_TIMEOUT_S)
            got = _read_head(client)
            if got is None:
                return
            head, rest = got
            offered = _offered(head)
            if SDK_SUBPROTOCOL not in offered and OLD_SUBPROTOCOL not in offered:
                _answer(client, b"400 Bad Request",
                        b"This is the Foxglove WebSocket protocol, as subprotocol foxglove.sdk.v1 (foxglove.websocket."
                        b"v1 is accepted too). Open ws://HOST:PORT in Foxglove (Open connection > Foxglove WebSocket); "
                        b"a client of your own must offer one of the two in Sec-WebSocket-Protocol.\n")
                return
            rename = SDK_SUBPROTOCOL not in offered
            upstream = socket.create_connection(("127.0.0.1", self.sdk_port), timeout=HEAD_TIMEOUT_S)
            self._track(upstream)
            upstream.sendall((_renamed(head, OLD_SUBPROTOCOL, SDK_SUBPROTOCOL) if rename else head) + rest)
            if rename:
                answer = _read_head(upstream)
                if answer is None:
                    return
                client.sendall(_renamed(answer[0], SDK_SUBPROTOCOL, OLD_SUBPROTOCOL) + answer[1])
            client.settimeout(None)
            upstream.settimeout(None)
            threading.Thread(target=_copy, args=(upstream, client), daemon=True).start()
            _copy(client, upstream)
        except OSError:
            pass
        finally:
            for sock in (client, upstream):
                if sock is not None:
                    self._untrack(sock)
                    _close(sock)
            self._clients.release()

    def _track(self, sock: socket.socket) -> None:
        with self._lock:
            self._open.add(sock)

    def _untrack(self, sock: socket.socket) -> None:
        with self._lock:
            self._open.discard(sock)


def _copy(source: socket.socket, sink: socket.socket) -> None:
    """Copy bytes until either side closes; then shut both down (the other copy ends too)."""
    try:
        while chunk := source.recv(65536):
            sink.sendall(chunk)
    except OSError:
        pass
    for sock in (source, sink):
        try:
            sock.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass


def _answer(client: socket.socket, status: bytes, body: bytes) -> None:
    try:
        client.sendall(b"HTTP/1.1 " + status + b"\r\nContent-Type: text/plain\r\nContent-Length: "
                       + str(len(body)).encode() + b"\r\nConnection: close\r\n\r\n" + body)
    except OSError:
        pass
    _close(client)


def _close(sock: socket.socket) -> None:
    try:
        sock.close()
    except OSError:
        pass
