"""The launchers of a graph over several machines: who is up, which nodes are ready, the clock offset.

More in docs/modules.md, `launch/peers.py`.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Callable

import msgpack
import zmq

from slipstack.launch.launch_file import Machine
from slipstack.lib.clock_offset import ClockOffset, OffsetEstimate
from slipstack.nodes.runtime.curve import secure_bind, secure_connect
from slipstack.nodes.runtime.transport import bound_socket, tcp_endpoint

__all__ = ["PeerLinks", "Peer", "launcher_endpoint", "PING_PERIOD_S", "QUIET_AFTER_S"]

PING_PERIOD_S = 0.1
QUIET_AFTER_S = 1.0
MAX_FRAME_BYTES = 64 * 1024
"""Longest frame a launcher accepts from a peer (a status lists node names)."""
_HWM = 20


def launcher_endpoint(machine: Machine) -> str:
    """Where the launcher of ``machine`` listens: its address, the first of its ports."""
    return tcp_endpoint(machine.address, machine.ports[0])


def _ns(value: int) -> bytes:
    return value.to_bytes(8, "big", signed=True)


def _int(frame: bytes) -> int:
    return int.from_bytes(frame, "big", signed=True)


@dataclass
class Peer:
    """What this launcher knows of another machine's launcher."""

    machine: Machine
    sock: zmq.Socket
    clock: ClockOffset = field(default_factory=ClockOffset)
    state: str = ""
    """"" before its first answer, then its launcher's state: starting, running, stopped."""
    ready: frozenset[str] = frozenset()
    heard_at: float | None = None
    quiet: bool = False
    next_ping: float = 0.0
    stopped_at: int | None = None
    """Its clock (ns) when it said goodbye: its answers from before then are old news."""

    @property
    def label(self) -> str:
        return f"machine {self.machine.name} ({self.machine.address})"

    def offset(self) -> OffsetEstimate | None:
        """Its clock minus ours (ns), with the uncertainty; None before the first answer."""
        return self.clock.estimate()


BYE_LINGER_MS = 2000
"""How long a closing launcher repeats its goodbye until each peer acknowledges it (ms): a
loaded machine can need well over 200 ms, and a lost goodbye leaves the peers running,
holding in fail-safe, instead of stopping with it."""
BYE_REPEAT_MS = 100


class PeerLinks:
    """This launcher's links to the other machines' launchers, run by a thread; :meth:`service`
    prints what it reports. ``state`` and ``ready`` are what this launcher answers with."""

    def __init__(self, zctx: zmq.Context, machines: dict[str, Machine], me: str,
                 echo: Callable[[str], None]) -> None:
        self.me = machines[me]
        self.echo = echo
        self.state = "starting"
        self.ready: list[str] = []
        self._reports: deque[str] = deque(maxlen=100)
        self._stop = threading.Event()
        self.server = bound_socket(zctx, zmq.ROUTER, sndhwm=_HWM, rcvhwm=_HWM, max_msg_bytes=MAX_FRAME_BYTES)
        endpoint = launcher_endpoint(self.me)
        secure_bind(self.server, endpoint)
        self.server.bind(endpoint)
        self.peers: dict[str, Peer] = {}
        for name, m in machines.items():
            if name == me:
                continue
            sock = bound_socket(zctx, zmq.DEALER, sndhwm=_HWM, rcvhwm=_HWM, max_msg_bytes=MAX_FRAME_BYTES)
            sock.setsockopt(zmq.IMMEDIATE, 1)  # no pings queued for a peer not connected
            sock.setsockopt(zmq.RECONNECT_IVL, 100)
            sock.setsockopt(zmq.RECONNECT_IVL_MAX, 1000)
            secure_connect(sock, launcher_endpoint(m))
            sock.connect(launcher_endpoint(m))
            self.peers[name] = Peer(m, sock)
        self._thread = threading.Thread(target=self._run, name="peer-links", daemon=True)
        self._thread.start()

    def service(self) -> None:
        """Print what the links reported since the last call (peers gone quiet, back, stopped)."""
        while self._reports:
            self.echo(self._reports.popleft())

    def _run(self) -> None:
        poller = zmq.Poller()
        poller.register(self.server, zmq.POLLIN)
        for peer in self.peers.values():
            poller.register(peer.sock, zmq.POLLIN)
        while not self._stop.is_set():
            now = time.monotonic()
            wait_ms = max(0, min((p.next_ping - now for p in self.peers.values()), default=PING_PERIOD_S) * 1e3)
            events = dict(poller.poll(min(wait_ms, PING_PERIOD_S * 1e3)))
            if self.server in events:
                self._answer()
            now = time.monotonic()
            for peer in self.peers.values():
                if peer.sock in events:
                    self._read(peer, now)
                if now >= peer.next_ping:
                    peer.next_ping = now + PING_PERIOD_S
                    self._send(peer.sock, [b"ping", _ns(time.monotonic_ns()), self.me.name.encode()])
                silent = peer.heard_at is not None and now - peer.heard_at > QUIET_AFTER_S
                if silent and not peer.quiet and peer.state != "stopped":
                    peer.quiet = True
                    self._reports.append(
                        f"[launch] WARNING: {peer.label} went quiet: no answer for {now - peer.heard_at:.1f} s; its "
                        "nodes' data is stale (the grip controller holds) until it is back")

    def _answer(self) -> None:
        while self.server.poll(0):
            parts = self.server.recv_multipart()
            t2 = time.monotonic_ns()
            if len(parts) == 4 and parts[1] == b"ping" and len(parts[2]) == 8:
                status = msgpack.packb({"machine": self.me.name, "state": self.state, "ready": list(self.ready)})
                self._send(self.server, [parts[0], b"pong", parts[2], _ns(t2), _ns(time.monotonic_ns()), status])
            elif len(parts) == 4 and parts[1] == b"bye" and len(parts[3]) == 8:
                self._send(self.server, [parts[0], b"bye-ack"])
                peer = self.peers.get(parts[2].decode(errors="replace"))
                if peer is not None and peer.stopped_at is None:
                    peer.state, peer.ready, peer.stopped_at = "stopped", frozenset(), _int(parts[3])
                    self._reports.append(f"[launch] {peer.label} stopped (its launcher exited with its nodes)")

    def _read(self, peer: Peer, now: float) -> None:
        while peer.sock.poll(0):
            parts = peer.sock.recv_multipart()
            t4 = time.monotonic_ns()
            if len(parts) != 5 or parts[0] != b"pong" or not all(len(p) == 8 for p in parts[1:4]):
                continue
            try:
                status = msgpack.unpackb(parts[4])
                state, ready = str(status["state"]), frozenset(str(n) for n in status["ready"])
            except (ValueError, TypeError, KeyError, msgpack.ExtraData):
                continue
            peer.clock.add(_int(parts[1]), _int(parts[2]), _int(parts[3]), t4)
            if peer.stopped_at is not None:
                if _int(parts[3]) <= peer.stopped_at:
                    continue  # answered before its goodbye, arrived after it
                peer.stopped_at = None  # a new launcher there
            if peer.quiet:
                self._reports.append(f"[launch] {peer.label} is back after {now - peer.heard_at:.1f} s")
                peer.quiet = False
            elif peer.state == "stopped" and state != "stopped":
                self._reports.append(f"[launch] {peer.label} is up again")
            peer.state, peer.ready, peer.heard_at = state, ready, now

    @staticmethod
    def _send(sock: zmq.Socket, parts: list[bytes]) -> None:
        try:
            sock.send_multipart(parts, flags=zmq.NOBLOCK)
        except zmq.Again:  # peer not connected or not reading: the next ping will do
            pass

    def close(self) -> None:
        """Stop the thread, say goodbye to every peer, close the sockets."""
        self._stop.set()
        self._thread.join()
        self.service()
        bye = [b"bye", self.me.name.encode(), _ns(time.monotonic_ns())]
        waiting = [p for p in self.peers.values() if p.state not in ("", "stopped")]  # who may still listen
        deadline = time.monotonic() + BYE_LINGER_MS / 1e3
        while waiting and time.monotonic() < deadline:
            for peer in waiting:
                self._send(peer.sock, bye)
            end = min(deadline, time.monotonic() + BYE_REPEAT_MS / 1e3)
            while waiting and time.monotonic() < end:
                for peer in list(waiting):
                    while peer.sock.poll(0):
                        if peer.sock.recv_multipart() == [b"bye-ack"]:
                            waiting.remove(peer)
                            break
                time.sleep(0.005)
        for peer in self.peers.values():
            peer.sock.close(linger=0)
        self.server.close(linger=0)
