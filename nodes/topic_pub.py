"""``slipstack topic pub``: publish messages by hand into the running graph.

Mechanism: the graph's subscribers never connect to new publishers, but each
node's SUB socket also *binds* an injection endpoint per input (``inject`` in
``graph.json``). ``topic pub`` connects one XPUB socket to the injection endpoints
of every subscriber of the topic, waits until each has subscribed (verbose XPUB:
no slow-joiner loss), then publishes with its own header sequence from 0 and
``stamp_ns = pub_ns = CLOCK_MONOTONIC`` (the executors' clock). Several ``topic
pub`` processes can inject at once: ZeroMQ lets many peers connect to one bound SUB.

Values are YAML flow text (:mod:`slipstack.nodes.topic_yaml`), e.g.
``'{f_n_desired: 12.0, law: manual}'``; fields left out keep their defaults, and the
message is validated exactly as a subscriber would before it is sent.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
import typing
from typing import Any

import numpy as np
import zmq

from slipstack.lib.errors import ConfigError, DecodeError
from slipstack.messages import Header, Message, encode, registry, validate
from slipstack.nodes.topic_tools import TopicInfo, load_graph, resolve_topic
from slipstack.nodes.transport import MAX_SUBSCRIPTION_BYTES, SUBSCRIPTION_HWM, bound_socket
from slipstack.nodes.topic_yaml import parse_flow

__all__ = ["build_message", "Injector", "add_arguments", "main_pub"]


def build_message(cls: type[Message], values: Any) -> Message:
    """A validated ``cls`` from a mapping of field values (arrays as lists).

    Raises:
        ConfigError: not a mapping, an unknown field (lists the fields), or a value the
            decoder would reject (names the field).
    """
    if not isinstance(values, dict):
        raise ConfigError(f"values for {cls.TYPE} must be a mapping like '{{field: value}}', got {values!r}")
    fields = {f.name: f for f in dataclasses.fields(cls) if f.name != "header"}
    hints = typing.get_type_hints(cls)
    unknown = sorted(set(values) - set(fields))
    if unknown:
        raise ConfigError(f"{cls.TYPE} has no field(s) {', '.join(unknown)}; fields: {', '.join(fields)}")
    kwargs: dict[str, Any] = {}
    for name, v in values.items():
        spec = fields[name].metadata.get("array")
        try:
            if spec is not None:
                v = np.asarray(v, dtype=spec.dtype)
            elif hints[name] is float and isinstance(v, int) and not isinstance(v, bool):
                v = float(v)
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"{cls.TYPE}.{name}: {exc}") from None
        kwargs[name] = v
    try:
        return validate(cls(**kwargs))
    except DecodeError as exc:
        raise ConfigError(str(exc)) from None


class Injector:
    """An XPUB connected to the injection endpoints of a topic's subscribers.

    Args:
        info: the topic (its subscribers' ``inject`` endpoints are used).
        linger_s: how long closing waits for queued frames to go out.
    """

    def __init__(self, info: TopicInfo, *, linger_s: float = 1.0) -> None:
        self.topic = info.name
        self.targets = [e for e in info.subscribers if e.address]
        if not self.targets:
            raise ConfigError(
                f"no node subscribes to {info.name} with an injection endpoint; "
                f"subscribers: {', '.join(e.node for e in info.subscribers) or 'none'}"
            )
        self.sock = bound_socket(zmq.Context.instance(), zmq.XPUB, sndhwm=1000, rcvhwm=SUBSCRIPTION_HWM,
                                 max_msg_bytes=MAX_SUBSCRIPTION_BYTES)
        self.sock.setsockopt(zmq.LINGER, round(linger_s * 1000))
        self.sock.setsockopt(zmq.XPUB_VERBOSE, 1)
        for address in sorted({e.address for e in self.targets}):
            self.sock.connect(address)
        self._joined = 0

    def wait_for_subscribers(self, timeout_s: float) -> int:
        """Wait until every target has subscribed to the topic; returns how many did."""
        want = b"\x01" + self.topic.encode()
        deadline = time.monotonic() + timeout_s
        while self._joined < len(self.targets):
            left = deadline - time.monotonic()
            if left <= 0 or not self.sock.poll(max(1, round(left * 1000))):
                break
            if self.sock.recv() == want:
                self._joined += 1
        return self._joined

    def send(self, payload: bytes) -> None:
        """Put one ``[topic, payload]`` frame on the wire (any bytes: fault injection too)."""
        self.sock.send_multipart((self.topic.encode(), payload))

    def close(self) -> None:
        self.sock.close()


def _split_positionals(info: TopicInfo, items: list[str]) -> tuple[type[Message], str]:
    cls = info.message_type()
    if items and items[0] in registry:
        if items[0] != cls.TYPE:
            raise ConfigError(f"topic {info.name} carries {cls.TYPE}, not {items[0]}")
        items = items[1:]
    return cls, " ".join(items)


def main_pub(args: argparse.Namespace) -> int:
    """Publish ``--once``, ``--times N`` or at ``--rate`` until Ctrl-C."""
    _, graph = load_graph(args.run_dir)
    info = resolve_topic(graph, args.topic)
    cls, text = _split_positionals(info, args.values)
    body = build_message(cls, parse_flow(text))
    if args.rate <= 0:
        raise ConfigError("--rate must be positive")
    times = 1 if args.once else args.times
    injector = Injector(info)
    try:
        joined = injector.wait_for_subscribers(args.wait)
        if joined == 0:
            print(f"topic pub: no subscriber of {info.name} joined within {args.wait:g} s", file=sys.stderr)
            return 1
        if joined < len(injector.targets):
            print(f"topic pub: only {joined} of {len(injector.targets)} subscribers joined; publishing anyway",
                  file=sys.stderr)
        period = round(1e9 / args.rate)
        due = time.monotonic_ns()
        seq = 0
        while times is None or seq < times:
            now = time.monotonic_ns()
            if now < due:
                time.sleep((due - now) / 1e9)
                now = time.monotonic_ns()
            injector.send(encode(dataclasses.replace(body, header=Header(now, seq, now, {}))))
            if args.print_nth and seq % args.print_nth == 0:
                print(f"publishing #{seq + 1} on {info.name}", flush=True)
            seq += 1
            due += period
    except KeyboardInterrupt:
        pass
    finally:
        injector.close()
    return 0


def add_arguments(verbs: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = verbs.add_parser(
        "pub", help="publish messages by hand",
        description="Publish a message on TOPIC to the nodes that subscribe to it (through their "
                    "injection endpoints). VALUES are YAML flow text; unset fields keep defaults. "
                    "Example: slipstack topic pub grip/command '{f_n_desired: 12.0, law: manual}' --rate 10",
    )
    p.add_argument("topic", help="topic name, e.g. grip/command")
    p.add_argument("values", nargs="*", metavar="[TYPE] VALUES",
                   help="optional message type (checked against the graph), then the field values")
    p.add_argument("-r", "--rate", type=float, default=1.0, metavar="HZ", help="publishing rate (default 1 Hz)")
    once = p.add_mutually_exclusive_group()
    once.add_argument("-1", "--once", action="store_true", help="publish one message and exit")
    once.add_argument("-t", "--times", type=int, metavar="N", help="publish N messages and exit")
    p.add_argument("-w", "--wait", type=float, default=3.0, metavar="S",
                   help="how long to wait for the subscribers to join (default 3 s)")
    p.add_argument("-p", "--print", dest="print_nth", type=int, default=1, metavar="N",
                   help="print every N-th publication (0: never; default 1)")
    p.set_defaults(func=main_pub)
    return p
