"""The process executor: one node in one OS process, ZeroMQ PUB/SUB, monotonic clock.

Life cycle: bind the XPUB, connect the SUBs, call ``node.start``, report *ready* to
the launcher, then hold all data flow (timers, device I/O, handlers) until every
subscriber the launch graph expects has subscribed — so nobody misses the first
message — and run the loop until SIGINT/SIGTERM. Timers are paced by absolute
deadlines; inputs are drained to the newest frame (``latest``) or queued
(``queue``); every drop and rejected frame is counted and published on
``diagnostics``.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import msgpack
import zmq

from slipstack.nodes.host import DIAGNOSTICS_TOPIC, NodeHost
from slipstack.nodes.node import Node
from slipstack.nodes.transport import make_pub, make_sub

__all__ = ["RunSpec", "ProcessExecutor"]

_DRAIN_LIMIT = 5000  # frames read from one socket per wake-up before others get a turn
_TIMER_CATCH_UP = 20  # late ticks of one timer fired per loop turn before ticks are skipped


@dataclass
class RunSpec:
    """How one node process is wired (written by the launcher, or built by hand).

    pub: endpoint to bind (``ipc://…`` or ``tcp://…``); ``None`` for a pure sink.
    subs: topic → endpoints publishing it.
    inject: topic → endpoint that one extra SUB socket of this node *binds* (the same
        endpoint for all its input topics), so a tool (``topic pub``, ``bag play``, a
        fault injector) can connect a PUB to it and reach the node.
    expected_subscribers: topic → number of subscriptions to wait for before data flows.
    control: the launcher's PULL endpoint for the ready report, or ``None``.
    """

    name: str
    pub: str | None = None
    subs: dict[str, list[str]] = field(default_factory=dict)
    remap: dict[str, str] = field(default_factory=dict)
    inject: dict[str, str] = field(default_factory=dict)
    expected_subscribers: dict[str, int] = field(default_factory=dict)
    control: str | None = None
    diagnostics_period_s: float = 1.0
    handshake_timeout_s: float = 10.0


class _Stop(Exception):
    pass


class ProcessExecutor:
    """Run ``node`` as this process's only node, wired by ``spec``."""

    def __init__(self, node: Node, spec: RunSpec) -> None:
        self.node = node
        self.spec = spec
        self.zctx = zmq.Context.instance()
        self.pub = make_pub(self.zctx, spec.pub) if spec.pub else None
        self.host = NodeHost(node, time.monotonic_ns, self._send, name=spec.name, remap=spec.remap, log=self._log)
        # One SUB socket per (input, publisher endpoint): sequence gaps are then tracked
        # per publisher, so several publishers on one topic (``diagnostics``) never look
        # like loss. One more SUB, bound, takes frames injected by tools.
        self._sub_topic: dict[zmq.Socket, tuple[str, bytes, str]] = {}
        for input_name, topic in self.host.input_topics.items():
            hwm = 1000 if node.inputs[input_name].policy == "queue" else 100
            for origin in spec.subs.get(topic, []):
                sock = make_sub(self.zctx, [origin], topic, rcvhwm=hwm)
                self._sub_topic[sock] = (input_name, topic.encode(), origin)
        self._inject_routes = {
            topic.encode(): [n for n, t in self.host.input_topics.items() if t == topic] for topic in spec.inject
        }
        self.inject_sock: zmq.Socket | None = None
        if self._inject_routes:
            self.inject_sock = make_sub(self.zctx, [], None, rcvhwm=1000)
            self.inject_sock.setsockopt(zmq.UNSUBSCRIBE, b"")
            for topic in self._inject_routes:
                self.inject_sock.setsockopt(zmq.SUBSCRIBE, topic)
            for endpoint in sorted(set(spec.inject.values())):
                self.inject_sock.bind(endpoint)
        self._queues = {n: deque(maxlen=i.depth) for n, i in node.inputs.items() if i.policy == "queue"}
        self._subscriptions: dict[bytes, int] = {}
        self._stopping = False

    # -- plumbing -----------------------------------------------------------------------
    def _log(self, text: str) -> None:
        print(text, file=sys.stderr, flush=True)

    def _send(self, topic: str, payload: bytes) -> None:
        if self.pub is None:
            raise RuntimeError(f"node {self.spec.name} has no publish endpoint")
        try:
            self.pub.send_multipart((topic.encode(), payload), flags=zmq.NOBLOCK, copy=True)
        except zmq.Again:
            self.host.count(f"out.{topic}.dropped_hwm")

    def _read_subscriptions(self) -> None:
        while True:
            try:
                frame = self.pub.recv(zmq.NOBLOCK)
            except zmq.Again:
                return
            if frame:
                delta = 1 if frame[0] == 1 else -1
                self._subscriptions[frame[1:]] = self._subscriptions.get(frame[1:], 0) + delta

    def _subscribers_of(self, topic: str) -> int:
        """Subscriptions matching ``topic`` (ZeroMQ filters are prefixes; b"" taps all)."""
        t = topic.encode()
        return sum(n for prefix, n in self._subscriptions.items() if t.startswith(prefix))

    def _subscribers_joined(self) -> bool:
        self._read_subscriptions()
        return all(self._subscribers_of(t) >= n for t, n in self.spec.expected_subscribers.items())

    def _report(self, event: str) -> None:
        if not self.spec.control:
            return
        sock = self.zctx.socket(zmq.PUSH)
        sock.setsockopt(zmq.LINGER, 1000)
        sock.connect(self.spec.control)
        sock.send(msgpack.packb({"node": self.spec.name, "event": event, "pid": os.getpid()}))
        sock.close()

    def _on_signal(self, signum: int, frame: Any) -> None:
        self._stopping = True

    # -- the loop -----------------------------------------------------------------------
    def _wait_for_subscribers(self) -> None:
        deadline = time.monotonic() + self.spec.handshake_timeout_s
        while not self._subscribers_joined():
            if self._stopping:
                raise _Stop
            if time.monotonic() > deadline:
                missing = {
                    t: f"{self._subscribers_of(t)}/{n}"
                    for t, n in self.spec.expected_subscribers.items()
                    if self._subscribers_of(t) < n
                }
                self._log(f"warning: subscribers still missing after {self.spec.handshake_timeout_s} s: {missing}; starting anyway")
                return
            time.sleep(0.002)

    def _drain(self, input_name: str, sock: zmq.Socket) -> None:
        _, want, origin = self._sub_topic[sock]
        host = self.host
        latest = None
        kept = 0
        queue = self._queues.get(input_name)
        for _ in range(_DRAIN_LIMIT):
            if not sock.getsockopt(zmq.EVENTS) & zmq.POLLIN:  # cheaper than a zmq.Again exception
                break
            parts = sock.recv_multipart(zmq.NOBLOCK, copy=True)
            if len(parts) != 2 or parts[0] != want:
                if len(parts) != 2:
                    host.count(f"in.{host.input_topics[input_name]}.rejected")
                    host.last_error = f"{host.input_topics[input_name]}: expected [topic, payload], got {len(parts)} parts"
                continue
            msg = host.receive(input_name, parts[1], origin)
            if msg is None:
                continue
            if queue is None:
                latest = msg
                kept += 1
            else:
                if len(queue) == queue.maxlen:
                    host.count_dropped(input_name, 1)
                queue.append(msg)
        if queue is None:
            if latest is not None:
                host.count_dropped(input_name, kept - 1)
                host.dispatch(input_name, latest)
        else:
            while queue:
                host.dispatch(input_name, queue.popleft())

    def _watch_io(self, poller: zmq.Poller, io: dict[int, object], handlers: dict) -> dict[int, object]:
        """Keep the poller in step with the node's current descriptors."""
        current = {src.fileno(): src for src in self.node.io_sources()}
        if current.keys() != io.keys():
            for fd in io.keys() - current.keys():
                poller.unregister(fd)
                handlers.pop(fd, None)
            for fd in current.keys() - io.keys():
                poller.register(fd, zmq.POLLIN)
        for fd, src in current.items():
            handlers[fd] = ("io", src)
        return current

    def _drain_injected(self) -> None:
        """Frames put in by tools: every valid one is handled, in order (no draining to latest)."""
        host = self.host
        for _ in range(_DRAIN_LIMIT):
            if not self.inject_sock.getsockopt(zmq.EVENTS) & zmq.POLLIN:
                break
            parts = self.inject_sock.recv_multipart(zmq.NOBLOCK)
            names = self._inject_routes.get(parts[0], []) if len(parts) == 2 else []
            if not names:
                host.count("in.injected.rejected")
                host.last_error = f"injected frame: expected [topic, payload] on an input topic, got {len(parts)} parts"
            for input_name in names:
                msg = host.receive(input_name, parts[1], "inject")
                if msg is not None:
                    host.dispatch(input_name, msg)

    def _sockets(self) -> list[zmq.Socket]:
        return [*self._sub_topic, *([self.inject_sock] if self.inject_sock else []), *([self.pub] if self.pub else [])]

    def run(self) -> int:
        """Run until SIGINT/SIGTERM; returns the process exit code."""
        signal.signal(signal.SIGINT, self._on_signal)
        signal.signal(signal.SIGTERM, self._on_signal)
        host = self.host
        try:
            self.node.start(host)
        except Exception as exc:  # cannot start: say why, exit non-zero, the launcher names us
            self._log(f"cannot start: {type(exc).__name__}: {exc}")
            for sock in self._sockets():
                sock.close(linger=0)
            return 1
        try:
            self._report("ready")
            if self.pub is not None:
                self._wait_for_subscribers()
            self._loop()
        except _Stop:
            pass
        finally:
            host.call("stop", self.node.stop, host)
            if self.pub is not None:
                self._send(DIAGNOSTICS_TOPIC, host.diagnostics())
            for sock in self._sockets():
                sock.close(linger=0)
        return 0

    def _loop(self) -> None:
        host, node = self.host, self.node
        poller = zmq.Poller()
        handlers: dict[object, tuple[str, object]] = {}
        for sock, (input_name, _, _) in self._sub_topic.items():
            poller.register(sock, zmq.POLLIN)
            handlers[sock] = ("input", input_name)
        if self.inject_sock is not None:
            poller.register(self.inject_sock, zmq.POLLIN)
            handlers[self.inject_sock] = ("inject", None)
        watches_io = type(node).io_sources is not Node.io_sources
        has_deadline = type(node).next_deadline_ns is not Node.next_deadline_ns
        # A timer-paced node (the rig, a source) may sleep to the exact tick; any other
        # node waits in poll, rounding its wake-up up to the next millisecond, so it
        # never sleeps deaf to input.
        precise = bool(node.timers) and getattr(node, "precise_timers", False)
        io: dict[int, object] = {}
        now = time.monotonic_ns()
        deadlines = {t: now + round(p * 1e9) for t, p in node.timers.items()}
        periods = {t: round(p * 1e9) for t, p in node.timers.items()}
        diag_period = round(self.spec.diagnostics_period_s * 1e9)
        next_diag = now + diag_period
        counters = host.counters
        while not (self._stopping or host.shutdown_requested):
            counters["loop.wakeups"] += 1
            if watches_io:
                io = self._watch_io(poller, io, handlers)
            node_deadline = node.next_deadline_ns() if has_deadline else None
            next_due = min(next_diag, *deadlines.values()) if deadlines else next_diag
            if node_deadline is not None and node_deadline < next_due:
                next_due = node_deadline
            wait_ns = next_due - time.monotonic_ns()
            if wait_ns <= 0:
                events = poller.poll(0)
            elif precise and wait_ns < 1_000_000:
                events = poller.poll(0)
                if not events:
                    time.sleep(wait_ns / 1e9)
            else:
                events = poller.poll(min(-(-wait_ns // 1_000_000), 50))
            for item, _ in events:
                kind, arg = handlers[item]
                if kind == "input":
                    self._drain(arg, item)
                elif kind == "io":
                    host.call("on_readable", node.on_readable, arg, host)
                else:
                    self._drain_injected()
            now = time.monotonic_ns()
            if has_deadline:
                node_deadline = node.next_deadline_ns()
                if node_deadline is not None and now >= node_deadline:
                    host.call("on_deadline", node.on_deadline, host)
            for timer, due in deadlines.items():
                if now < due:
                    continue
                period = periods[timer]
                fired = 0
                while now >= due and fired < _TIMER_CATCH_UP and not host.shutdown_requested:
                    # late ticks are made up, not lost
                    host.fire_timer(timer)
                    due += period
                    fired += 1
                if now >= due:  # hopelessly behind: skip ahead and say so
                    skipped = (now - due) // period + 1
                    host.count(f"timer.{timer}.skipped", skipped)
                    due += skipped * period
                deadlines[timer] = due
            if now >= next_diag:
                if self.pub is not None:
                    self._read_subscriptions()  # keep the XPUB's subscription queue short
                    self._send(DIAGNOSTICS_TOPIC, host.diagnostics())
                next_diag += diag_period
