"""``slipstack topic echo``: print a topic's messages as they arrive.

More in docs/modules.md, `nodes/tools/topic_echo.py`.
"""

from __future__ import annotations

import argparse
import csv
import io
import os
import sys
import time
from pathlib import Path
from typing import Any, Callable, TextIO

import numpy as np
import zmq

from slipstack.lib.errors import ConfigError, DecodeError
from slipstack.messages import Message, decode
from slipstack.messages.frame import SeqTracker
from slipstack.nodes.tools.topic_format import as_tree, check_field, csv_cell, flatten, pick, render_yaml
from slipstack.nodes.runtime.graph_info import read_graph
from slipstack.nodes.runtime.stop_signal import stop_on_signals
from slipstack.nodes.tools.topic_tools import TopicInfo, graph_topics, load_graph, resolve_topic
from slipstack.nodes.runtime.transport import make_sub

__all__ = ["MessagePrinter", "main_echo"]

BATCH = 500  # frames read from one publisher before the output is written
REFRESH_PERIOD_S = 0.5  # how often the graph is re-read for new publishers (tools that publish)
MAX_PUBLISHERS = 256  # publishers of one topic listened to at most
MISSING_NOTE_AFTER = 20  # messages without the --field's map key before saying so
_FILTER_BUILTINS = {f.__name__: f for f in (abs, all, any, len, max, min, round, sum, float, int, bool, str)}


class MessagePrinter:
    """Turns messages into output text: YAML blocks, one field, or CSV rows.

    Args:
        field: ``a.b`` path to print instead of the whole message (``None``: all).
        csv_mode: one CSV row per message, after a header row (columns from the first).
        no_arr: hide array values.
        truncate: array values shown before ``'...'``.
    """

    def __init__(self, *, field: str | None, csv_mode: bool, no_arr: bool, truncate: int) -> None:
        self.field = field
        self.csv_mode = csv_mode
        self.no_arr = no_arr
        self.truncate = truncate
        self.columns: list[str] | None = None
        self._buf = io.StringIO()
        self._csv = csv.writer(self._buf, lineterminator="\n")

    def format(self, msg: Message) -> str | None:
        """Text for one message, or ``None`` if it lacks the requested map key.

        Raises:
            ConfigError: the field path cannot exist in this message type (bad index).
        """
        tree: Any = as_tree(msg)
        if self.field is not None:
            found, tree = pick(tree, self.field)
            if not found:
                return None
        if not self.csv_mode:
            if self.field is not None and not isinstance(tree, dict):
                return "\n".join(render_yaml(tree, no_arr=self.no_arr, truncate=self.truncate)).lstrip() + "\n---\n"
            return "\n".join(render_yaml(tree, no_arr=self.no_arr, truncate=self.truncate)) + "\n---\n"
        cells = dict(flatten(tree, "" if self.field is None else self.field, no_arr=self.no_arr))
        self._buf.seek(0)
        self._buf.truncate()
        if self.columns is None:
            self.columns = list(cells)
            self._csv.writerow(self.columns)
        self._csv.writerow([csv_cell(cells.get(c)) for c in self.columns])
        return self._buf.getvalue()


def _compile_filter(expr: str | None) -> Callable[[Message], bool] | None:
    if expr is None:
        return None
    try:
        code = compile(expr, "<--filter>", "eval")
    except SyntaxError as exc:
        raise ConfigError(f"--filter {expr!r} is not a Python expression: {exc.msg}") from None
    env = {"__builtins__": _FILTER_BUILTINS, "np": np}
    return lambda m: bool(eval(code, env, {"m": m}))  # noqa: S307 - the user's own expression, as in ros2


def _write(stream: TextIO, text: str) -> None:
    if text:
        stream.write(text)
        stream.flush()


def _published(run_dir: Path, graph: dict[str, Any], topic: str, deadline: float | None) -> TopicInfo | None:
    """The topic once a publisher of it is in the graph (a node not started yet, a tool such as
    ``bag play`` or ``topic pub``, a machine coming up): said once on stderr and waited for, as
    ros2 does, re-reading the graph; ``None`` if ``deadline`` passed first."""
    said = False
    while True:
        try:
            info = resolve_topic(graph, topic)
            if any(e.address for e in info.publishers):
                return info
            why = "subscribed but not published yet"
        except ConfigError:
            why = f"not in the graph yet; its topics: {', '.join(graph_topics(graph)) or 'none'}"
        if not said:
            print(f"topic echo: waiting for {topic} ({why})", file=sys.stderr, flush=True)
            said = True
        if deadline is not None and time.monotonic() >= deadline:
            return None
        time.sleep(REFRESH_PERIOD_S)
        try:
            graph = read_graph(run_dir)
        except (OSError, ValueError):
            pass  # the graph file is being rewritten: read it next time


def main_echo(args: argparse.Namespace) -> int:
    """Run ``topic echo``; returns 0, or 1 if ``--timeout`` passed without any message printed.

    Raises:
        ConfigError: a field path no message can have, or a ``--filter`` that raises.
    """
    run_dir, graph = load_graph(args.run_dir)
    keep = _compile_filter(args.filter)
    deadline = None if args.timeout is None else time.monotonic() + args.timeout
    info = _published(run_dir, graph, args.topic, deadline)
    if info is None:
        print(f"topic echo: {args.topic} was not published within {args.timeout:g} s", file=sys.stderr)
        return 1
    cls = info.message_type()
    if args.field:
        check_field(cls, args.field)
    limit = 1 if args.once else args.count
    printer = MessagePrinter(field=args.field, csv_mode=args.csv, no_arr=args.no_arr, truncate=args.truncate_length)

    ctx = zmq.Context.instance()
    topic_b = info.name.encode()
    socks: dict[zmq.Socket, str] = {}
    trackers: dict[str, SeqTracker] = {}
    poller = zmq.Poller()
    connected: set[str] = set()

    def connect_new(found: TopicInfo) -> None:
        """A SUB for each publisher not yet connected (tools such as ``topic pub`` come and go)."""
        for e in found.publishers:
            if e.address and e.address not in connected and len(connected) < MAX_PUBLISHERS:
                sock = make_sub(ctx, [e.address], found.name, rcvhwm=args.qos_depth)
                socks[sock] = e.node
                trackers.setdefault(e.node, SeqTracker())
                poller.register(sock, zmq.POLLIN)
                connected.add(e.address)

    connect_new(info)
    next_refresh = time.monotonic() + REFRESH_PERIOD_S
    out, err = sys.stdout, sys.stderr
    printed = rejected = missing = 0
    stop_on_signals()
    try:
        while limit is None or printed < limit:
            if deadline is not None and time.monotonic() >= deadline:
                if printed == 0:
                    print(f"topic echo: no message on {info.name} within {args.timeout:g} s"
                          + (" (none passed --filter)" if keep is not None else ""), file=err)
                    return 1
                return 0
            if time.monotonic() >= next_refresh:
                next_refresh = time.monotonic() + REFRESH_PERIOD_S
                try:
                    connect_new(resolve_topic(read_graph(run_dir), info.name))
                except (OSError, ValueError, ConfigError):
                    pass  # the graph file is being rewritten or the launch ended: keep what we have
            ready = dict(poller.poll(200))
            if not ready:
                continue
            chunks: list[str] = []
            notes: list[str] = []
            for sock in ready:
                node = socks[sock]
                for _ in range(BATCH):
                    try:
                        topic, *rest = sock.recv_multipart(zmq.NOBLOCK)
                    except zmq.Again:
                        break
                    if topic != topic_b:
                        continue  # a longer topic sharing the subscription prefix
                    try:
                        if len(rest) != 1:
                            raise DecodeError(f"expected [topic, payload], got {len(rest) + 1} parts")
                        msg = decode(rest[0], cls)
                    except DecodeError as exc:
                        rejected += 1
                        notes.append(f"topic echo: rejected a frame from {node}: {exc}")
                        continue
                    seq = msg.header.seq
                    tracker = trackers[node]
                    before = tracker.restarts
                    gap = tracker.update(seq)
                    if gap:
                        notes.append(f"topic echo: lost {gap} message(s) from {node} before seq {seq} "
                                     f"(total lost {tracker.lost})")
                    elif tracker.restarts != before:
                        notes.append(f"topic echo: {node} restarted its sequence (seq {seq})")
                    if keep is not None:
                        try:
                            if not keep(msg):
                                continue
                        except Exception as exc:  # the user's expression: say why and stop
                            raise ConfigError(
                                f"--filter {args.filter!r} raised {type(exc).__name__}: {exc} on a "
                                f"{cls.TYPE} message; the message is `m`, e.g. 'm.header.seq % 10 == 0'"
                            ) from None
                    text = printer.format(msg)
                    if text is None:
                        missing += 1
                        if missing == MISSING_NOTE_AFTER and not printed:
                            notes.append(f"topic echo: {missing} messages so far have no {args.field} (a key of a "
                                         "map, which another message may have); still waiting: check the spelling "
                                         "(`--once` prints the whole message), or Ctrl-C")
                        continue
                    chunks.append(text)
                    printed += 1
                    if limit is not None and printed >= limit:
                        break
                if limit is not None and printed >= limit:
                    break
            _write(out, "".join(chunks))
            if notes:
                _write(err, "\n".join(notes) + "\n")
    except KeyboardInterrupt:
        pass
    except BrokenPipeError:  # `| head`: the reader went away
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    finally:
        for s in socks:
            s.close(linger=0)
    lost = sum(t.lost for t in trackers.values())
    if lost or rejected:
        print(f"topic echo: {printed} printed, {lost} lost, {rejected} rejected", file=err)
    return 0
