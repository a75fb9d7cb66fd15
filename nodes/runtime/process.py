"""The process executor: one node — or a container of nodes — in one OS process,
ZeroMQ PUB/SUB, monotonic clock.

More in docs/modules.md, `nodes/runtime/process.py`.
"""

from __future__ import annotations

import os
import signal
import sys
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Callable

import msgpack
import zmq

from slipstack.messages import Header, Message, handed_over
from slipstack.messages.codec import MAX_PAYLOAD_BYTES
from slipstack.nodes.runtime.host import DIAGNOSTICS_TOPIC, NodeHost
from slipstack.nodes.runtime.logs import node_log
from slipstack.nodes.runtime.node import Node
from slipstack.nodes.runtime.rate_limit import TokenBucket
from slipstack.nodes.runtime.scheduling import runs_realtime
from slipstack.nodes.runtime.stage_cpu import StageCpu, stage_cpu_from_env
from slipstack.nodes.runtime.curve import secure_bind
from slipstack.nodes.runtime.time_base import graph_clock
from slipstack.nodes.runtime.transport import MAX_ORIGIN_BYTES, bound_socket, make_pub, make_sub

__all__ = ["ProcessExecutor", "RunSpec"]

_EVENTS, _POLLIN = int(zmq.EVENTS), int(zmq.POLLIN)  # plain ints: `&` of pyzmq's enums costs ~0.5 µs a test
_NOBLOCK, _SEND_MORE = int(zmq.NOBLOCK), int(zmq.NOBLOCK | zmq.SNDMORE)
_DRAIN_LIMIT = 2000  # frames read from one bus socket per wake-up before others get a turn
_DECODE_TRIES = 16  # newest frames of a ``latest`` backlog decoded in search of a valid one
_INJECT_READ_LIMIT = 512  # injected frames read per wake-up (the rest wait in the socket, bounded by its HWM)
_INJECT_HWM = 200  # injected frames queued in the node's injection socket: the backlog a flood leaves
_OVER_RATE_READS = 64  # frames over the injection rate read (and dropped) per wake-up before a pause
_INJECT_PAUSE_NS = 10_000_000  # how long a node over its injection rate leaves the injection socket unread
_TIMER_CATCH_UP = 20  # late ticks of one timer fired per loop turn before ticks are skipped
_CLOSE_LINGER_MS = 200  # at exit, how long frames still queued for a subscriber may take to leave
_REPORT_LINGER_MS = 1000  # how long a report to the launcher may take to leave before the process goes on
_FINAL_QUIET_MS = 200  # at exit, a node that outlives the graph reads its inputs until none came for this long,
_FINAL_DRAIN_S = 10.0  # or for this long at most (its inputs' depths bound the frames)
_now_ns = graph_clock()  # monotonic ns, on the reference machine's time base (nodes/runtime/time_base.py)


@dataclass
class RunSpec:
    """How one node process is wired (written by the launcher, or built by hand).

    pub: endpoint to bind (``ipc://…`` or ``tcp://…``); ``None`` for a pure sink.
    pub_remote: a tcp endpoint the publisher binds as well, for subscribers and tools on
        other machines of the graph (``None``: all on this one).
    subs: topic → endpoints publishing it.
    inject: topic → endpoint that one extra SUB socket of this node *binds* (frames
        ``[topic, payload]`` or ``[topic, payload, origin]``, sequence gaps tracked per
        origin; the same
        endpoint for all its input topics), so a tool (``topic pub``, ``bag play``, a
        fault injector) can connect a PUB to it and reach the node.
    expected_subscribers: topic → number of subscriptions to wait for before data flows.
    control: the launcher's PULL endpoint for the ready report, or ``None``.
    local: topic → names of members of this node's container that publish it: their
        messages are handed over in-process (and their endpoints are not in ``subs``).
    inject_rate_hz, inject_burst: the token bucket all frames injected into this
        node share (frames/s, frames back to back); the excess is dropped undecoded
        and counted as ``inject.dropped_rate``.
    inject_bytes_per_s, inject_burst_bytes: likewise in bytes (``inject.dropped_bytes``);
        a frame larger than the burst is never admitted.
    inject_work_share, inject_work_burst_s: the share of the node's time injected frames
        may take (0..1: CPU time of its thread per second), and how much of it at once (s).
    """

    name: str
    pub: str | None = None
    pub_remote: str | None = None
    subs: dict[str, list[str]] = field(default_factory=dict)
    remap: dict[str, str] = field(default_factory=dict)
    inject: dict[str, str] = field(default_factory=dict)
    expected_subscribers: dict[str, int] = field(default_factory=dict)
    control: str | None = None
    diagnostics_period_s: float = 1.0
    handshake_timeout_s: float = 10.0
    local: dict[str, list[str]] = field(default_factory=dict)
    inject_rate_hz: float = 2000.0
    inject_burst: int = 200
    inject_bytes_per_s: float = 4e6
    inject_burst_bytes: int = MAX_PAYLOAD_BYTES
    inject_work_share: float = 0.2
    inject_work_burst_s: float = 0.02


class _Stop(Exception):
    pass


def _read_frame(sock: zmq.Socket) -> list[bytes]:
    """One multipart frame, without blocking (``zmq.Again`` if none waits), each part as bytes.

    Same result as ``recv_multipart(NOBLOCK)`` at about 60 % of its cost: pyzmq's
    version asks ZeroMQ for RCVMORE through its option enum after every part (~0.6 µs
    each), where a zero-copy receive carries the flag on the frame it returns.
    """
    part = sock.recv(_NOBLOCK, copy=False)
    parts = [part.bytes]
    while part.more:
        part = sock.recv(_NOBLOCK, copy=False)
        parts.append(part.bytes)
    return parts


def _log(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


class _Member:
    """One node of a :class:`ProcessExecutor`: its host, sockets, timers and deadlines."""

    def __init__(self, node: Node, spec: RunSpec, zctx: zmq.Context, *, name_logs: bool = False,
                 stage_cpu: StageCpu | None = None, clock: Callable[[], int] = _now_ns) -> None:
        self.node = node
        self.spec = spec
        self.zctx = zctx
        self.pub = make_pub(zctx, spec.pub, unsubscriptions=True, remote=spec.pub_remote) if spec.pub else None
        log = node_log(spec.name, f"{spec.name}: " if name_logs else "")  # a container's members name themselves
        self.subscriptions: dict[bytes, int] = {}
        self.listened_topics: dict[str, bool] = {}  # topic → someone subscribes (cleared when subscriptions change)
        self.host = NodeHost(node, clock, self.send, name=spec.name, remap=spec.remap, log=log,
                             stage_cpu=stage_cpu, listened=self.listened if self.pub is not None else None)
        # One SUB socket per (input, publisher endpoint): sequence gaps are then tracked
        # per publisher, so several publishers on one topic (``diagnostics``) never look
        # like loss. One more SUB, bound, takes frames injected by tools.
        self.sub_topic: dict[zmq.Socket, tuple[str, bytes, str]] = {}
        for input_name, topic in self.host.input_topics.items():
            policy, depth = node.inputs[input_name].policy, node.inputs[input_name].depth
            hwm = 100 if policy == "latest" else max(1000, depth) if policy == "queue" else 1000  # a queue's backlog fits
            for origin in spec.subs.get(topic, []):
                sock = make_sub(zctx, [origin], topic, rcvhwm=hwm)
                self.sub_topic[sock] = (input_name, topic.encode(), origin)
        self.inject_routes = {
            topic.encode(): [n for n, t in self.host.input_topics.items() if t == topic] for topic in spec.inject
        }
        self.inject_sock: zmq.Socket | None = None
        self.inject_bucket = TokenBucket(spec.inject_rate_hz, spec.inject_burst)
        self.inject_bytes = TokenBucket(spec.inject_bytes_per_s, spec.inject_burst_bytes)
        self.inject_work = TokenBucket(spec.inject_work_share * 1e9, spec.inject_work_burst_s * 1e9)  # ns of work
        self.inject_resume_ns: int | None = None  # set while injected frames are left unread (over the rate)
        self.inject_backlog = False  # after a pause: what queued meanwhile is dropped before anything is admitted
        if self.inject_routes:
            self.inject_sock = make_sub(zctx, [], None, rcvhwm=_INJECT_HWM)
            self.inject_sock.setsockopt(zmq.UNSUBSCRIBE, b"")
            for topic in self.inject_routes:
                self.inject_sock.setsockopt(zmq.SUBSCRIBE, topic)
            for endpoint in sorted(set(spec.inject.values())):
                secure_bind(self.inject_sock, endpoint)
                self.inject_sock.bind(endpoint)
        self.queues = {n: deque(maxlen=i.depth) for n, i in node.inputs.items() if i.policy == "queue"}
        self.batch_inputs = {n for n, i in node.inputs.items() if i.policy == "batch"}
        self.watches_io = type(node).io_sources is not Node.io_sources
        self.has_deadline = type(node).next_deadline_ns is not Node.next_deadline_ns
        self.precise = bool(node.timers) and getattr(node, "precise_timers", False)
        self.io: dict[int, object] = {}
        self.periods = {t: round(p * 1e9) for t, p in node.timers.items()}
        self.deadlines: dict[str, int] = {}
        self.diag_period = round(spec.diagnostics_period_s * 1e9)
        self.next_diag = 0
        self.due = 0  # the earliest timer tick or diagnostics (ns), kept by start_clock and fire_due

    # -- plumbing -----------------------------------------------------------------------
    def send(self, topic: str, payload: bytes) -> None:
        if self.pub is None:
            raise RuntimeError(f"node {self.spec.name} has no publish endpoint")
        try:  # two sends: send_multipart type-checks every part first; a frame is queued whole or not at all
            self.pub.send(topic.encode(), _SEND_MORE)
            self.pub.send(payload, _NOBLOCK)
        except zmq.Again:
            self.host.count(f"out.{topic}.dropped_hwm")

    def read_subscriptions(self) -> None:
        while True:
            try:
                frame = self.pub.recv(zmq.NOBLOCK)
            except zmq.Again:
                return
            if frame:
                delta = 1 if frame[0] == 1 else -1
                self.subscriptions[frame[1:]] = self.subscriptions.get(frame[1:], 0) + delta
                self.listened_topics.clear()

    def listened(self, topic: str) -> bool:
        """True while a subscriber (outside this process: a container's members hand over
        in-process) wants ``topic``; subscriptions are read as they arrive (the XPUB is polled)."""
        hit = self.listened_topics.get(topic)
        if hit is None:
            hit = self.listened_topics[topic] = self.subscribers_of(topic) > 0
        return hit

    def subscribers_of(self, topic: str) -> int:
        """Subscriptions matching ``topic`` (ZeroMQ filters are prefixes; b"" taps all)."""
        t = topic.encode()
        return sum(n for prefix, n in self.subscriptions.items() if t.startswith(prefix))

    def missing_subscribers(self) -> dict[str, str]:
        """Topics still short of the subscribers the graph expects: topic → "have/want"."""
        if self.pub is None:
            return {}
        self.read_subscriptions()
        return {
            t: f"{self.subscribers_of(t)}/{n}"
            for t, n in self.spec.expected_subscribers.items()
            if self.subscribers_of(t) < n
        }

    def report(self, event: str, **details: Any) -> None:
        """Tell the launcher ``event`` (``ready``; ``stopped`` with what it published)."""
        if not self.spec.control:
            return
        # a context of its own, terminated here: the report has left when this returns (Python's
        # exit does not wait for ZeroMQ's I/O thread: a stop report was lost about one run in five)
        zctx = zmq.Context()
        try:
            sock = bound_socket(zctx, zmq.PUSH, sndhwm=10, rcvhwm=10, max_msg_bytes=1024)
            sock.setsockopt(zmq.LINGER, _REPORT_LINGER_MS)
            sock.connect(self.spec.control)
            sock.send(msgpack.packb({"node": self.spec.name, "event": event, "pid": os.getpid(), **details}))
            sock.close()
        finally:
            zctx.term()

    def drain_delivered(self, clock: Callable[[], int]) -> None:
        """Handle what was delivered to the inputs before ``stop``: frames are read until none came
        for :data:`_FINAL_QUIET_MS`, for at most :data:`_FINAL_DRAIN_S` and as many frames as the
        inputs' depths (a node that sums up the run judges all of it; what is left it counts itself)."""
        if not self.sub_topic:
            return
        poller = zmq.Poller()
        for sock in self.sub_topic:
            poller.register(sock, zmq.POLLIN)
        budget = sum(i.depth for i in self.node.inputs.values())
        deadline = clock() + round(_FINAL_DRAIN_S * 1e9)
        while budget > 0 and clock() < deadline:
            events = poller.poll(_FINAL_QUIET_MS)
            if not events:
                return
            for sock, _ in events:
                budget -= self.drain(self.sub_topic[sock][0], sock)

    def sockets(self) -> list[zmq.Socket]:
        return [*self.sub_topic, *([self.inject_sock] if self.inject_sock else []), *([self.pub] if self.pub else [])]

    # -- input --------------------------------------------------------------------------
    def drain(self, input_name: str, sock: zmq.Socket) -> int:
        """Read and handle at most :data:`_DRAIN_LIMIT` frames waiting on ``sock``; returns how many were read."""
        _, want, origin = self.sub_topic[sock]
        host = self.host
        topic = host.input_topics[input_name]
        payloads: list[bytes] = []
        stage = host.stage_cpu
        if stage is not None:
            resume = stage.enter(host.stage_keys["receive"])
        for n in range(_DRAIN_LIMIT):
            # poll found the socket readable, so the first read needs no test of its own;
            # the next ones test EVENTS, which costs less than a zmq.Again exception
            if n and not sock.getsockopt(_EVENTS) & _POLLIN:
                break
            try:
                parts = _read_frame(sock)
            except zmq.Again:
                break
            if len(parts) == 2 and parts[0] == want:
                payloads.append(parts[1])
            elif len(parts) != 2:
                host.count(f"in.{topic}.rejected")
                host.last_error = f"{topic}: expected [topic, payload], got {len(parts)} parts"
        if stage is not None:
            stage.enter(resume)
        queue = self.queues.get(input_name)
        if queue is None:
            if input_name in self.batch_inputs:
                self._dispatch_batch(input_name, payloads, origin)
            else:
                self._dispatch_newest(input_name, payloads, origin)
            return len(payloads)
        for payload in payloads:
            msg = host.receive(input_name, payload, origin)
            if msg is not None:
                if len(queue) == queue.maxlen:
                    host.count_dropped(input_name, 1)
                queue.append(msg)
        while queue:
            host.dispatch(input_name, queue.popleft())
        return len(payloads)

    def _dispatch_newest(self, input_name: str, payloads: list[bytes], origin: str) -> None:
        """Handle the newest valid frame of a ``latest`` input's backlog; the older ones are
        skipped undecoded (counted as received and dropped, not as lost)."""
        host = self.host
        for k in range(len(payloads) - 1, max(len(payloads) - 1 - _DECODE_TRIES, -1), -1):
            msg = host.receive(input_name, payloads[k], origin, skipped=k)
            if msg is not None:
                host.skip(input_name, k)
                host.dispatch(input_name, msg)
                return
        host.skip(input_name, max(len(payloads) - _DECODE_TRIES, 0))

    def _dispatch_batch(self, input_name: str, payloads: list[bytes], origin: str) -> None:
        """Handle the valid frames of a ``batch`` input's backlog in one call, oldest first; the
        frames beyond its depth, oldest first, are skipped undecoded (received and dropped)."""
        host = self.host
        host.dispatch_batch(input_name, payloads,
                            lambda payload, skipped: host.receive(input_name, payload, origin, skipped=skipped))

    def drain_injected(self, now_ns: int) -> None:
        """Frames put in by tools, within the node's injection budgets: a ``queue`` input
        handles each valid one in order, a ``latest`` input the newest valid one, a ``batch``
        input its valid ones in one call (at most its depth, the newest). Sets
        :attr:`inject_resume_ns` when a flood calls for a pause (module docstring); the
        caller charges the time it took with :meth:`charge_injected_work`."""
        host = self.host
        frames, size, work = self.inject_bucket, self.inject_bytes, self.inject_work
        for bucket in (frames, size, work):
            bucket.refill(now_ns)
        t0 = time.thread_time_ns()  # work is this thread's CPU time: a busy host's waits are not charged
        newest: dict[str, tuple[Message, str]] = {}
        batches: dict[str, tuple[list[Message], str]] = {}
        over_rate = over_bytes = backlog = 0
        flushing, self.inject_backlog = self.inject_backlog, False
        for _ in range(_INJECT_READ_LIMIT):
            if not self.inject_sock.getsockopt(_EVENTS) & _POLLIN:
                break
            if not flushing and time.thread_time_ns() - t0 >= work.tokens:  # the share of work is spent
                break
            parts = _read_frame(self.inject_sock)
            n_bytes = sum(len(part) for part in parts)
            if flushing:  # what queued while the node was over budget (one wake-up's worth): a flood's
                backlog += 1
                continue
            if frames.tokens < 1.0 or size.tokens < n_bytes:  # dropped before it is decoded
                over_rate += frames.tokens < 1.0
                over_bytes += frames.tokens >= 1.0
                if over_rate + over_bytes >= _OVER_RATE_READS:
                    self.inject_resume_ns = now_ns + _INJECT_PAUSE_NS
                    self.inject_backlog = True
                    host.count("inject.pauses")
                    break
                continue
            frames.take()
            size.take(n_bytes)
            names = self.inject_routes.get(parts[0], []) if len(parts) in (2, 3) else []
            if not names:
                host.count("in.injected.rejected")
                host.last_error = (f"injected frame: expected [topic, payload(, origin)] on an input topic, "
                                   f"got {len(parts)} parts")
            sender = parts[2][:MAX_ORIGIN_BYTES].decode(errors="replace") if len(parts) == 3 else ""
            origin = f"inject/{sender}" if sender else "inject"
            for input_name in names:
                msg = host.receive(input_name, parts[1], origin)
                if msg is None:
                    continue
                if input_name in self.queues:
                    host.dispatch(input_name, msg, sender=sender or "inject")
                elif input_name in self.batch_inputs:
                    batches.setdefault(input_name, ([], sender))[0].append(msg)
                else:
                    if input_name in newest:
                        host.count_dropped(input_name, 1)
                    newest[input_name] = (msg, sender)
        if over_rate:
            host.count("inject.dropped_rate", over_rate)
        if over_bytes:
            host.count("inject.dropped_bytes", over_bytes)
        if backlog:
            host.count("inject.dropped_backlog", backlog)
        for input_name, (msg, sender) in newest.items():
            host.dispatch(input_name, msg, sender=sender or "inject")
        for input_name, (msgs, sender) in batches.items():
            depth = self.node.inputs[input_name].depth
            host.count_dropped(input_name, max(len(msgs) - depth, 0))
            host.dispatch(input_name, tuple(msgs[-depth:]), sender=sender or "inject")

    def charge_injected_work(self, work_ns: int, now_ns: int) -> None:
        """Charge ``work_ns`` spent on injected frames (their decode, handlers and hand-overs) to
        the node's share; a share used up leaves them unread until half its burst is earned back
        (at least :data:`_INJECT_PAUSE_NS`)."""
        work = self.inject_work
        work.spend(work_ns)
        if work.tokens < 1.0:
            resume = now_ns + max(work.ns_until(work.burst / 2), _INJECT_PAUSE_NS)
            self.inject_resume_ns = max(resume, self.inject_resume_ns or 0)
            self.inject_backlog = True
            self.host.count("inject.work_pauses")

    def watch_io(self, poller: zmq.Poller, handlers: dict) -> None:
        """Keep the poller in step with the node's current descriptors."""
        sources = self.node.io_sources()
        if len(sources) == 1 and len(self.io) == 1 and self.io.get(sources[0].fileno()) is sources[0]:
            return  # a driver's one device, unchanged since the last turn: nothing to re-register
        current = {src.fileno(): src for src in sources}
        if current.keys() != self.io.keys():
            for fd in self.io.keys() - current.keys():
                poller.unregister(fd)
                handlers.pop(fd, None)
            for fd in current.keys() - self.io.keys():
                poller.register(fd, zmq.POLLIN)
        for fd, src in current.items():
            handlers[fd] = ("io", self, src)
        self.io = current

    # -- time ---------------------------------------------------------------------------
    def start_clock(self, now: int) -> None:
        self.deadlines = {t: now + p for t, p in self.periods.items()}
        self.next_diag = now + self.diag_period
        self._keep_due()

    def _keep_due(self) -> None:
        self.due = min(self.next_diag, *self.deadlines.values()) if self.deadlines else self.next_diag

    def next_due(self) -> int:
        due = self.due
        if self.inject_resume_ns is not None and self.inject_resume_ns < due:
            due = self.inject_resume_ns
        if self.has_deadline:
            node_deadline = self.node.next_deadline_ns()
            if node_deadline is not None and node_deadline < due:
                due = node_deadline
        return due

    def fire_due(self, now: int) -> None:
        """The node's deadline, due timer ticks (late ones made up) and diagnostics."""
        host = self.host
        if self.has_deadline:
            node_deadline = self.node.next_deadline_ns()
            if node_deadline is not None and now >= node_deadline:
                host.call("on_deadline", self.node.on_deadline, host)
        for timer, due in self.deadlines.items():
            if now < due:
                continue
            period = self.periods[timer]
            fired = 0
            while now >= due and fired < _TIMER_CATCH_UP and not host.shutdown_requested:
                # late ticks are made up, not lost
                host.fire_timer(timer)
                due += period
                fired += 1
            if now >= due:  # hopelessly behind: skip ahead and say so
                skipped = (now - due) // period + 1
                host.count(f"timer.{timer}.skipped", skipped)
                if runs_realtime():  # raising its priority is then no remedy: the summary's advice differs
                    host.count(f"timer.{timer}.skipped_realtime", skipped)
                due += skipped * period
            self.deadlines[timer] = due
        if now >= self.next_diag:
            if self.pub is not None:
                self.read_subscriptions()  # keep the XPUB's subscription queue short
                self.send(DIAGNOSTICS_TOPIC, host.diagnostics())
            self.next_diag += self.diag_period
        self._keep_due()


class ProcessExecutor:
    """Run the nodes of ``members`` (one, or a container's) in this process, each wired by its spec.

    ``clock``: the graph's time base (ns) the nodes run on; default this process's
    (``$SLIPSTACK_CLOCK_OFFSET_NS``, set by the launcher). A tool started outside the
    launch passes the graph's (``graph_info.time_base_clock``)."""

    def __init__(self, members: Sequence[tuple[Node, RunSpec]], *, clock: Callable[[], int] | None = None) -> None:
        if not members:
            raise ValueError("ProcessExecutor needs at least one node")
        self.zctx = zmq.Context.instance()
        self.clock = clock or _now_ns
        self.stage_cpu = stage_cpu_from_env(members[0][1].name)
        self.members = [_Member(node, spec, self.zctx, name_logs=len(members) > 1, stage_cpu=self.stage_cpu,
                                clock=self.clock) for node, spec in members]
        by_name = {m.spec.name: m for m in self.members}
        for m in self.members[1:]:  # a container's members share one process: one share of work for tools
            m.inject_work = self.members[0].inject_work
        # (publisher name, topic) → the members' inputs it feeds in-process
        self._routes: dict[tuple[str, str], list[tuple[_Member, str]]] = {}
        for m in self.members:
            for topic, publishers in m.spec.local.items():
                for pub in publishers:
                    if pub not in by_name:
                        raise ValueError(f"{m.spec.name}: local publisher {pub!r} of {topic!r} is not in this process")
                    for input_name, t in m.host.input_topics.items():
                        if t == topic:
                            self._routes.setdefault((pub, topic), []).append((m, input_name))
        self._handover: deque[tuple[_Member, str, tuple[Message, str | None] | None]] = deque()  # (message, rejection)
        # (member, input) of a ``batch`` input → its (message, rejection) pairs gathered for one call
        # (the hand-over queue holds ``None`` in their place, once)
        self._batch_waiting: dict[tuple[_Member, str], list[tuple[Message, str | None]]] = {
            (m, n): [] for m in self.members for n in m.batch_inputs
        }
        # (member, input) of a ``latest`` input → its messages in the hand-over queue
        self._latest_queued: dict[tuple[_Member, str], int] = {
            (m, n): 0 for m in self.members for n, i in m.node.inputs.items() if i.policy == "latest"
        }
        for m in self.members:
            if any(pub == m.spec.name for pub, _ in self._routes):
                m.host.on_publish = self._hand_over_from(m.spec.name)
        self._stopping = False

    def _hand_over_from(self, publisher: str):
        routes = self._routes
        handover = self._handover
        latest_queued = self._latest_queued
        batch_waiting = self._batch_waiting

        def hand_over(topic: str, msg: Message, header: Header) -> None:
            targets = routes.get((publisher, topic))
            if targets:
                delivered = handed_over(msg, header)
                for member, input_name in targets:
                    key = (member, input_name)
                    batch = batch_waiting.get(key)
                    if batch is not None:
                        if not batch:
                            handover.append((member, input_name, None))
                        batch.append(delivered)
                        continue
                    handover.append((member, input_name, delivered))
                    if key in latest_queued:
                        latest_queued[key] += 1

        return hand_over

    def _run_handovers(self) -> None:
        """Messages published to members of this process, in order (new ones appended while
        running); a ``latest`` input with a newer message waiting skips the older one, as
        its bus socket would (a driver in the container publishes a device read's batch); a
        ``batch`` input takes all of its waiting messages in one call."""
        handover = self._handover
        latest_queued = self._latest_queued
        while handover:
            member, input_name, delivered = handover.popleft()
            key = (member, input_name)
            if delivered is None:
                self._run_batch(member, input_name, self._batch_waiting[key])
                continue
            msg, rejection = delivered
            waiting = latest_queued.get(key)
            if waiting is not None:
                latest_queued[key] = waiting - 1
                if waiting > 1:
                    member.host.skip(input_name, 1)
                    continue
            member.host.receive_local(input_name, msg, rejection)

    @staticmethod
    def _run_batch(member: _Member, input_name: str, waiting: list[tuple[Message, str | None]]) -> None:
        """The messages handed over to a ``batch`` input since its last call, in one call
        (emptied); those beyond its depth, the oldest, are counted as received and dropped."""
        host = member.host
        host.dispatch_batch(input_name, waiting, lambda delivered, _: host.accept_local(input_name, *delivered))
        waiting.clear()

    def _on_signal(self, signum: int, frame: Any) -> None:
        self._stopping = True

    def _sockets(self) -> list[zmq.Socket]:
        return [s for m in self.members for s in m.sockets()]

    # -- the loop -----------------------------------------------------------------------
    def _wait_for_subscribers(self) -> None:
        timeout = max(m.spec.handshake_timeout_s for m in self.members)
        deadline = time.monotonic() + timeout
        while True:
            missing = {m.spec.name: gap for m in self.members if (gap := m.missing_subscribers())}
            if not missing:
                return
            if self._stopping:
                raise _Stop
            if time.monotonic() > deadline:
                _log(f"warning: subscribers still missing after {timeout} s: {missing}; starting anyway")
                return
            time.sleep(0.002)

    def run(self) -> int:
        """Run until SIGINT/SIGTERM; returns the process exit code."""
        signal.signal(signal.SIGINT, self._on_signal)
        signal.signal(signal.SIGTERM, self._on_signal)
        started: list[_Member] = []
        for m in self.members:
            try:
                m.node.start(m.host)
            except Exception as exc:  # cannot start: say why, exit non-zero, the launcher names us
                _log(f"{m.spec.name}: cannot start: {type(exc).__name__}: {exc}")
                for other in started:
                    other.host.call("stop", other.node.stop, other.host)
                for sock in self._sockets():
                    sock.close(linger=0)
                return 1
            started.append(m)
        try:
            for m in self.members:
                m.report("ready")
            self._wait_for_subscribers()
            self._loop()
        except _Stop:
            pass
        finally:
            for m in self.members:
                if m.node.outlives_graph:
                    m.drain_delivered(self.clock)
                m.host.call("stop", m.node.stop, m.host)
                if m.pub is not None:
                    m.send(DIAGNOSTICS_TOPIC, m.host.diagnostics(final=True))
                    m.report("stopped", numbered=m.host.numbered())  # what a recording of it must hold
            for sock in self._sockets():  # the last frames and diagnostics leave, if their subscribers take them
                sock.close(linger=_CLOSE_LINGER_MS if sock.type == zmq.XPUB else 0)
        return 0

    def _loop(self) -> None:
        members = self.members
        _now_ns = self.clock  # the module's clock, or the one a tool gave (a local: looked up fast)
        poller = zmq.Poller()
        handlers: dict[object, tuple[str, _Member, object]] = {}
        for m in members:
            for sock, (input_name, _, _) in m.sub_topic.items():
                poller.register(sock, zmq.POLLIN)
                handlers[sock] = ("input", m, input_name)
            if m.inject_sock is not None:
                poller.register(m.inject_sock, zmq.POLLIN)
                handlers[m.inject_sock] = ("inject", m, None)
            if m.pub is not None:  # (un)subscriptions: what is sent at all follows them at once
                poller.register(m.pub, zmq.POLLIN)
                handlers[m.pub] = ("subscriptions", m, None)
        watching = [m for m in members if m.watches_io]
        # A timer-paced node (the rig, a source) may sleep to the exact tick; any other
        # node waits in poll, rounding its wake-up up to the next millisecond, so it
        # never sleeps deaf to input.
        precise = any(m.precise for m in members)
        now = _now_ns()
        for m in members:
            m.start_clock(now)
        hosts = [m.host for m in members]
        wakeup_counts = [h.counters for h in hosts]
        stage = self.stage_cpu
        poll_key = (members[0].spec.name, "poll")
        handover = self._handover
        next_due = members[0].next_due if len(members) == 1 else lambda: min(m.next_due() for m in members)
        while not (self._stopping or any(h.shutdown_requested for h in hosts)):
            for counters in wakeup_counts:
                counters["loop.wakeups"] += 1
            for m in watching:
                m.watch_io(poller, handlers)
            wait_ns = next_due() - _now_ns()
            if stage is not None:
                resume = stage.enter(poll_key)
            if wait_ns <= 0:
                events = poller.poll(0)
            elif precise and wait_ns < 1_000_000:
                events = poller.poll(0)
                if not events:
                    time.sleep(wait_ns / 1e9)
            elif not poller.sockets:  # nothing to watch (a device not open, no inputs): zmq would not wait
                events = []
                time.sleep(min(wait_ns, 50_000_000) / 1e9)
            else:
                events = poller.poll(min(-(-wait_ns // 1_000_000), 50))
            if stage is not None:
                stage.enter(resume)
            for item, _ in events:
                kind, m, arg = handlers[item]
                if kind == "input":
                    m.drain(arg, item)
                elif kind == "io":
                    m.host.call("on_readable", m.node.on_readable, arg, m.host)
                elif kind == "subscriptions":
                    m.read_subscriptions()
                else:
                    work0 = time.thread_time_ns()
                    m.drain_injected(_now_ns())
                    if handover:
                        self._run_handovers()
                    m.charge_injected_work(time.thread_time_ns() - work0, _now_ns())
                    if m.inject_resume_ns is not None:
                        poller.unregister(item)  # over budget: unread until the pause ends
                    continue
                if handover:
                    self._run_handovers()
            now = _now_ns()
            for m in members:
                if m.inject_resume_ns is not None and now >= m.inject_resume_ns:
                    m.inject_resume_ns = None
                    poller.register(m.inject_sock, zmq.POLLIN)
                if now >= m.due or m.has_deadline:  # the node's own deadline moves with its state
                    m.fire_due(now)
                    if handover:
                        self._run_handovers()
