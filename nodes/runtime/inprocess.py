"""The in-process executor: deterministic, no sockets, simulated clock.

Nodes are fed from a list of ``(t_ns, topic, message_or_payload)`` events (a
recording, or hand-made); frames still go through encode → decode so validation
and counting behave exactly as on the bus. Events, timers and the messages nodes
publish are processed in time order (ties: in the order they were scheduled), so a
replay is bit-for-bit repeatable.
"""

from __future__ import annotations

import heapq
import itertools
from collections import defaultdict
from typing import Iterable

from slipstack.messages import Message, decode, encode
from slipstack.nodes.runtime.host import DIAGNOSTICS_TOPIC, NodeHost
from slipstack.nodes.runtime.node import Node

__all__ = ["InProcessExecutor"]


class InProcessExecutor:
    """Run nodes in one thread on a simulated clock.

    Args:
        nodes: node objects; the same topic may connect several of them.
        remaps: per node instance name, default topic → topic.
        diagnostics_period_s: how often each node publishes ``diagnostics``
            (simulated seconds); ``None`` turns it off.

    After :meth:`run`, :attr:`published` maps topic → list of decoded messages in
    publication order.
    """

    def __init__(
        self,
        nodes: Iterable[Node],
        *,
        remaps: dict[str, dict[str, str]] | None = None,
        diagnostics_period_s: float | None = None,
        start_ns: int = 0,
    ) -> None:
        self.now = start_ns
        self._queue: list[tuple[int, int, str, object]] = []
        self._order = itertools.count()
        self.published: dict[str, list[Message]] = defaultdict(list)
        self.raw: list[tuple[int, str, bytes]] = []
        self.hosts: list[NodeHost] = []
        self.logs: list[str] = []
        self._subs: dict[str, list[tuple[NodeHost, str]]] = defaultdict(list)
        remaps = remaps or {}
        for node in nodes:
            host = NodeHost(
                node, lambda: self.now, self._send, remap=remaps.get(node.name), measure_handlers=False,
                log=lambda text, n=node.name: self.logs.append(f"[{n}] {text}"),
            )
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

    def _schedule(self, t_ns: int, item: object) -> None:
        heapq.heappush(self._queue, (t_ns, next(self._order), "", item))

    def _send(self, topic: str, payload: bytes) -> None:
        self.raw.append((self.now, topic, payload))
        self.published[topic].append(decode(payload))
        for host, input_name in self._subs.get(topic, ()):
            self._schedule(self.now, ("frame", host, input_name, payload))

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
        if not self._started:
            self._started = True
            for host in self.hosts:
                host.call("start", host.node.start, host)
                self._schedule_deadline(host)
        while self._queue and (until_ns is None or self._queue[0][0] <= until_ns):
            t_ns, _, _, item = heapq.heappop(self._queue)
            self.now = max(self.now, t_ns)
            kind = item[0]
            host = item[1]
            if host.shutdown_requested:
                continue
            if kind == "frame":
                _, host, input_name, payload = item
                msg = host.receive(input_name, payload)
                if msg is not None:
                    host.dispatch(input_name, msg)
            elif kind == "timer":
                _, host, timer, period = item
                host.fire_timer(timer)
                if until_ns is not None or self._has_frames():
                    self._schedule(t_ns + period, item)
            elif kind == "deadline":
                _, host, due = item
                if until_ns is None and not self._has_frames():
                    continue  # run-to-completion ends with the last frame, watchdogs too
                if host.node.next_deadline_ns() == due:  # still wanted
                    host.call("on_deadline", host.node.on_deadline, host)
            elif kind == "diag":
                _, host, period = item
                self._send(DIAGNOSTICS_TOPIC, host.diagnostics())
                if until_ns is not None or self._has_frames():
                    self._schedule(t_ns + period, item)
            self._schedule_deadline(host)
        if until_ns is not None:
            self.now = max(self.now, until_ns)

    def _schedule_deadline(self, host: NodeHost) -> None:
        due = host.node.next_deadline_ns()
        if due is not None and self._deadlines.get(id(host)) != due:
            self._deadlines[id(host)] = due
            self._schedule(max(due, self.now), ("deadline", host, due))

    def _has_frames(self) -> bool:
        return any(entry[3][0] == "frame" for entry in self._queue)

    def stop(self) -> None:
        """Call every node's ``stop``."""
        for host in self.hosts:
            host.call("stop", host.node.stop, host)
