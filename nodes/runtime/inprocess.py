"""The in-process executor: deterministic, no sockets, simulated clock.

More in docs/modules.md, `nodes/runtime/inprocess.py`.
"""

from __future__ import annotations

import heapq
import itertools
from collections import defaultdict
from typing import Callable, Collection, Iterable

from slipstack.messages import Header, Message, decode, encode, handed_over
from slipstack.nodes.runtime.host import DIAGNOSTICS_TOPIC, NodeHost
from slipstack.nodes.runtime.node import Node
from slipstack.nodes.runtime.stage_cpu import StageCpu

__all__ = ["InProcessExecutor"]


class InProcessExecutor:
    """Run nodes in one thread on a simulated clock.

    Args:
        nodes: node objects; the same topic may connect several of them. Their
            ``start`` runs in this order.
        names: instance names, one per node (default: each node class's ``name``).
        remaps: per node instance name, default topic → topic.
        diagnostics_period_s: how often each node publishes ``diagnostics``
            (simulated seconds); ``None`` turns it off.
        start_ns: the simulated clock's start (ns).
        keep_published: keep every frame in :attr:`published` and :attr:`raw`
            (off for long runs: they grow without bound; use ``on_frame``).
        on_frame: called as ``on_frame(t_ns, topic, payload)`` with every frame a node
            publishes, in publication order.
        on_frame_topics: the topics ``on_frame`` wants (``None``: all); the others are
            not encoded unless ``keep_published``.
        log: receives each node's log lines, ``[name] text`` (default: :attr:`logs`).
        stage_cpu: charges each node's decode, handler, encode and send to their stages
            (:mod:`slipstack.nodes.runtime.stage_cpu`; the rest is the executor's ``loop``).
        io_changes: a count that moves whenever something outside the bus may have moved
            the deadline of a node doing I/O of its own (a simulated device wrote to its
            driver); the executor then re-reads those deadlines before the clock moves,
            and only then. ``None``: re-read them before every move of the clock.

    After :meth:`run`, :attr:`published` maps topic → list of decoded messages in
    publication order.
    """

    def __init__(
        self,
        nodes: Iterable[Node],
        *,
        names: Iterable[str] | None = None,
        remaps: dict[str, dict[str, str]] | None = None,
        diagnostics_period_s: float | None = None,
        start_ns: int = 0,
        keep_published: bool = True,
        on_frame: Callable[[int, str, bytes], None] | None = None,
        on_frame_topics: Collection[str] | None = None,
        log: Callable[[str], None] | None = None,
        stage_cpu: StageCpu | None = None,
        io_changes: Callable[[], int] | None = None,
    ) -> None:
        self.now = start_ns
        self._io_changes = io_changes
        self._io_changes_seen: int | None = None
        self._queue: list[tuple[int, int, str, object]] = []
        self._order = itertools.count()
        self.published: dict[str, list[Message]] = defaultdict(list)
        self.raw: list[tuple[int, str, bytes]] = []
        self.hosts: list[NodeHost] = []
        self.logs: list[str] = []
        self._subs: dict[str, list[tuple[NodeHost, str]]] = defaultdict(list)
        self._keep = keep_published
        self._on_frame = on_frame
        self._on_frame_topics = None if on_frame_topics is None else frozenset(on_frame_topics)
        write_log = log or self.logs.append
        remaps = remaps or {}
        nodes = list(nodes)
        instance_names = [n.name for n in nodes] if names is None else list(names)
        if len(instance_names) != len(nodes):
            raise ValueError(f"{len(instance_names)} names for {len(nodes)} nodes")
        for node, name in zip(nodes, instance_names):
            host = NodeHost(
                node, lambda: self.now, self._record, name=name, remap=remaps.get(name), measure_handlers=False,
                log=lambda text, n=name: write_log(f"[{n}] {text}"), listened=self._encoded, send_raw=self._send,
                stage_cpu=stage_cpu,
            )
            host.on_publish = self._hand_over
            self.hosts.append(host)
            for input_name, topic in host.input_topics.items():
                self._subs[topic].append((host, input_name))
            for timer, period in node.timers.items():
                self._schedule(start_ns + round(period * 1e9), ("timer", host, timer, round(period * 1e9)))
            if diagnostics_period_s:
                p = round(diagnostics_period_s * 1e9)
                self._schedule(start_ns + p, ("diag", host, p))
        self._started = False
        self._deadlines: dict[int, int] = {}
        # nodes doing I/O of their own may become due from outside the bus (a simulated device written by another node)
        self._deadline_hosts = {h for h in self.hosts if type(h.node).next_deadline_ns is not Node.next_deadline_ns}
        self._io_hosts = [h for h in self.hosts if h in self._deadline_hosts
                          and type(h.node).io_sources is not Node.io_sources]
        self._by_name = {h.name: h for h in self.hosts}
        self._batch_inputs = {h: frozenset(n for n, i in h.node.inputs.items() if i.policy == "batch")
                              for h in self.hosts}  # per host: its ``batch`` inputs

    # -- the public driving API ----------------------------------------------------------
    @property
    def now_ns(self) -> int:
        """The simulated clock (ns)."""
        return self.now

    def host(self, name: str) -> NodeHost:
        """The host of the node named ``name`` (its counters, status, diagnostics)."""
        try:
            return self._by_name[name]
        except KeyError:
            raise KeyError(f"no node {name!r}; nodes: {', '.join(self._by_name)}") from None

    def inject(self, topic: str, item: Message | bytes, at_ns: int | None = None) -> None:
        """Deliver one frame on ``topic`` to its subscribers at ``at_ns`` (default: now)."""
        self.feed([(self.now if at_ns is None else at_ns, topic, item)])

    def advance(self, until_ns: int, *, stop_at_shutdown_of: Iterable[str] = ()) -> None:
        """Run every event, timer and deadline due up to ``until_ns``; the clock ends there, or
        once a node named in ``stop_at_shutdown_of`` has asked to shut down and every event of
        that instant has run (its last messages reach their subscribers)."""
        watched = {id(self.host(name)) for name in stop_at_shutdown_of}
        self._run(until_ns, watched)

    def finished(self) -> list[str]:
        """Names of the nodes that asked to shut down (``ctx.shutdown()``), in node order."""
        return [h.name for h in self.hosts if h.shutdown_requested]

    def _schedule(self, t_ns: int, item: object) -> None:
        heapq.heappush(self._queue, (t_ns, next(self._order), "", item))

    def _encoded(self, topic: str) -> bool:
        """Whether a publication on ``topic`` is encoded (kept, or wanted by ``on_frame``)."""
        if self._keep:
            return True
        return self._on_frame is not None and (self._on_frame_topics is None or topic in self._on_frame_topics)

    def _record(self, topic: str, payload: bytes) -> None:
        """Keep and pass on an encoded frame (its in-process subscribers are served apart)."""
        if self._keep:
            self.raw.append((self.now, topic, payload))
            self.published[topic].append(decode(payload))
        if self._on_frame is not None:
            self._on_frame(self.now, topic, payload)

    def _send(self, topic: str, payload: bytes) -> None:
        """An encoded frame (diagnostics, a raw frame) to the record and to its subscribers."""
        self._record(topic, payload)
        for host, input_name in self._subs.get(topic, ()):
            self._schedule(self.now, ("frame", host, input_name, payload))

    def _hand_over(self, topic: str, msg: Message, header: Header) -> None:
        """A published message to its subscribers, one checked object shared by all of them
        (an invalid one is rejected and counted by each, as on the bus)."""
        subscribers = self._subs.get(topic)
        if subscribers:
            delivered = handed_over(msg, header)
            for host, input_name in subscribers:
                self._schedule(self.now, ("message", host, input_name, delivered))

    def feed(self, events: Iterable[tuple[int, str, Message | bytes]]) -> None:
        """Schedule external frames: ``(t_ns, topic, message or encoded payload)``.

        A message keeps its own header (a recording's stamps and sequence numbers).
        """
        for t_ns, topic, item in events:
            payload = item if isinstance(item, (bytes, bytearray)) else encode(item)
            for host, input_name in self._subs.get(topic, ()):
                self._schedule(int(t_ns), ("frame", host, input_name, bytes(payload)))

    def run(self, until_ns: int | None = None) -> None:
        """Process events in time order up to ``until_ns``.

        With ``until_ns=None`` it runs until no fed or published frame is pending
        (timers and deadlines stop with the last frame); give ``until_ns`` to run
        timer-driven nodes.
        """
        self._run(until_ns, frozenset())

    def _run(self, until_ns: int | None, stop_hosts: frozenset[int] | set[int]) -> None:
        if not self._started:
            self._started = True
            for host in self.hosts:
                host.call("start", host.node.start, host)
                if host in self._deadline_hosts:
                    self._schedule_deadline(host)
        ending = False
        queue, pop = self._queue, heapq.heappop  # the loop runs once per event: locals, not attributes
        io_hosts, deadline_hosts, schedule_deadline = self._io_hosts, self._deadline_hosts, self._schedule_deadline
        deadlines, batch_inputs = self._deadlines, self._batch_inputs
        while True:
            while queue:  # a deadline its node has moved since: dropped before it could move the clock
                head = queue[0][3]
                if head[0] != "deadline" or deadlines.get(id(head[1])) == head[2]:
                    break
                pop(queue)
            if io_hosts and (not queue or queue[0][0] > self.now) and self._io_may_have_changed():
                due_now = self._reread_io_deadlines(until_ns)  # before the clock moves on: a device may have work
                for k, (io_host, due) in enumerate(due_now):  # as their deadline events would run: next, in order
                    if io_host.shutdown_requested or not self._run_deadline(io_host, due, until_ns, asked=k == 0):
                        continue
                    schedule_deadline(io_host)
                    if io_host.shutdown_requested and id(io_host) in stop_hosts:
                        ending = True
                if due_now:
                    continue
            if not queue or (until_ns is not None and queue[0][0] > until_ns):
                break
            if ending and queue[0][0] > self.now:
                return
            t_ns, _, _, item = pop(queue)
            if t_ns > self.now:
                self.now = t_ns
            kind, host = item[0], item[1]
            if host.shutdown_requested:
                continue
            # the kinds by how often they come: a published message, a timer, a deadline, a frame, diagnostics
            if kind == "message":
                if item[2] in batch_inputs[host]:
                    self._run_batch(item, t_ns)
                else:
                    msg, rejection = item[3]
                    host.receive_local(item[2], msg, rejection)
            elif kind == "timer":
                _, host, timer, period = item
                host.fire_timer(timer)
                if until_ns is not None or self._has_frames():
                    self._schedule(t_ns + period, item)
            elif kind == "deadline":
                if not self._run_deadline(host, item[2], until_ns):
                    continue
            elif kind == "frame":
                if item[2] in batch_inputs[host]:
                    self._run_batch(item, t_ns)
                else:
                    _, host, input_name, payload = item
                    msg = host.receive(input_name, payload)
                    if msg is not None:
                        host.dispatch(input_name, msg)
            elif kind == "diag":
                _, host, period = item
                self._send(DIAGNOSTICS_TOPIC, host.diagnostics())
                if until_ns is not None or self._has_frames():
                    self._schedule(t_ns + period, item)
            if host in deadline_hosts:
                schedule_deadline(host)
            if host.shutdown_requested and id(host) in stop_hosts:
                ending = True
        if until_ns is not None:
            self.now = max(self.now, until_ns)

    def _io_may_have_changed(self) -> bool:
        """Whether the I/O nodes' deadlines must be re-read (see ``io_changes``)."""
        if self._io_changes is None:
            return True
        changes = self._io_changes()
        if changes == self._io_changes_seen:
            return False
        self._io_changes_seen = changes
        return True

    def _run_batch(self, first: tuple, t_ns: int) -> None:
        """``first`` and the messages for the same ``batch`` input due next at ``t_ns``, in one
        call; those beyond the input's depth, the oldest, are counted as received and dropped."""
        _, host, input_name, _ = first
        items = [first]
        queue = self._queue
        while queue and queue[0][0] == t_ns:
            nxt = queue[0][3]
            if nxt[0] not in ("message", "frame") or nxt[1] is not host or nxt[2] != input_name:
                break
            items.append(heapq.heappop(queue)[3])
        host.dispatch_batch(input_name, items, lambda item, _: (
            host.accept_local(input_name, *item[3]) if item[0] == "message" else host.receive(input_name, item[3])))

    def _run_deadline(self, host: NodeHost, due: int, until_ns: int | None, *, asked: bool = False) -> bool:
        """A deadline event of ``host`` for ``due``: its ``on_deadline`` if it still wants that time
        (``asked``: it said so just now, no node has run since); False if the event is dropped
        (run-to-completion ends with the last frame, watchdogs too)."""
        if until_ns is None and not self._has_frames():
            return False
        if asked or host.node.next_deadline_ns() == due:
            host.call("on_deadline", host.node.on_deadline, host)
        return True

    def _reread_io_deadlines(self, until_ns: int | None) -> list[tuple[NodeHost, int]]:
        """Re-read the I/O nodes' deadlines (called when no event is due at this instant or before).

        A new deadline in the future is scheduled; the ``(host, due)`` of those due by now are
        returned, in node order, for the caller to run at once: scheduled, their events would be
        the next ones, in that order, so the queue trip (push, pop, a loop turn each: once per
        device read) changes nothing. Past ``until_ns`` they are scheduled, to run in a later call.
        """
        due_now = []
        runnable = until_ns is None or self.now <= until_ns
        for host in self._io_hosts:
            due = self._new_deadline(host)
            if due is None:
                continue
            if runnable and due <= self.now:
                due_now.append((host, due))
            else:
                self._schedule(max(due, self.now), ("deadline", host, due))
        return due_now

    def _schedule_deadline(self, host: NodeHost) -> None:
        due = self._new_deadline(host)
        if due is not None:
            self._schedule(max(due, self.now), ("deadline", host, due))

    def _new_deadline(self, host: NodeHost) -> int | None:
        """Read ``host``'s deadline and record it; the time if it is a new one, else ``None`` (unchanged,
        or cleared: the same instant asked again later is a new deadline)."""
        due = host.node.next_deadline_ns()
        if due is None:
            self._deadlines.pop(id(host), None)
            return None
        if self._deadlines.get(id(host)) == due:
            return None
        self._deadlines[id(host)] = due
        return due

    def _has_frames(self) -> bool:
        return any(entry[3][0] in ("frame", "message") for entry in self._queue)

    def stop(self, order: Iterable[str] | None = None) -> None:
        """Call every node's ``stop``, in ``order`` (node names; default: node order)."""
        hosts = self.hosts if order is None else [self.host(name) for name in order]
        for host in hosts:
            host.call("stop", host.node.stop, host)
