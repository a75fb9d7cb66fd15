"""``slipstack topic pub``: publish messages by hand into the running graph.

More in docs/modules.md, `nodes/tools/topic_pub.py`.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
import typing
from typing import Any

import numpy as np

from slipstack.lib.errors import ConfigError, DecodeError
from slipstack.messages import Header, Message, encode, registry, validate
from slipstack.nodes.tools.topic_tools import TopicInfo, load_graph, resolve_topic
from slipstack.nodes.runtime.graph_info import INJECTION_REFUSED, time_base_clock
from slipstack.nodes.runtime.stop_signal import stop_on_signals
from slipstack.nodes.runtime.tool_pub import BusPublisher, InjectionSender, tool_name
from slipstack.nodes.tools.topic_yaml import parse_flow

__all__ = ["build_message", "refuse_protected", "split_type_and_values", "Injector", "main_pub"]


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
    """Injection into the nodes that subscribe to a topic (their ``inject`` endpoints).

    Args:
        info: the topic (its subscribers' ``inject`` endpoints are used).
        linger_s: how long closing waits for queued frames to go out.
        origin: the name the nodes track this sender's sequence numbers under.
    """

    def __init__(self, info: TopicInfo, *, linger_s: float = 1.0, origin: str | None = None) -> None:
        self.topic = info.name
        self.targets = [e for e in info.subscribers if e.address]
        if not self.targets:
            raise ConfigError(
                f"no node subscribes to {info.name} with an injection endpoint; "
                f"subscribers: {', '.join(e.node for e in info.subscribers) or 'none'}"
            )
        self._linger_s = linger_s
        self.addresses = sorted({e.address for e in self.targets})
        """Where the frames go: one per node here, one per other machine (its launcher subscribes for its nodes)."""
        self.sender = InjectionSender(self.addresses, origin or tool_name("topic_pub"))

    def wait_for_subscribers(self, timeout_s: float) -> int:
        """Wait until every address has subscribed to the topic; returns how many did."""
        return self.sender.wait_for_subscriptions({self.topic: len(self.addresses)}, timeout_s)[self.topic]

    def send(self, payload: bytes) -> None:
        """Put one frame on the wire (any bytes: fault injection too)."""
        self.sender.send(self.topic, payload)

    def close(self) -> None:
        self.sender.close(self._linger_s)


def refuse_protected(info: TopicInfo, cls: type[Message]) -> None:
    """Refuse a topic only the graph's own nodes may publish (``INJECTION_REFUSED``), unless the
    launch allowed it to one of its subscribers (which then has an injection endpoint).

    Raises:
        ConfigError: saying so and how a launch file allows it.
    """
    if cls.TYPE in INJECTION_REFUSED and info.subscribers and not any(e.address for e in info.subscribers):
        raise ConfigError(
            f"the running graph refuses {info.name} from tools: only its own nodes publish grip commands, slip "
            f"verdicts and the finger's report (docs/safety.md); a launch file that must allow it says "
            f'allow_inject = ["{info.name}"] under [launch]')


def split_type_and_values(info: TopicInfo, items: list[str]) -> tuple[type[Message], str]:
    """The topic's message class and the values text of ``topic pub``'s positionals.

    A first item naming a message type (``slipstack/GripCommand`` as ``topic list -t``
    prints it, or ``GripCommand``) is checked against the topic's and taken off.

    Raises:
        ConfigError: the named type is not the topic's.
    """
    cls = info.message_type()
    named = _message_type_named(items[0]) if items else None
    if named is not None:
        if named != cls.TYPE:
            raise ConfigError(f"topic {info.name} carries {cls.TYPE}, not {named}")
        items = items[1:]
    return cls, " ".join(items)


def _message_type_named(word: str) -> str | None:
    """The registered type ``word`` names, in full or by its short name; ``None`` if none."""
    if word in registry:
        return word
    return next((name for name in registry if name.rpartition("/")[2] == word), None)


def main_pub(args: argparse.Namespace) -> int:
    """Publish ``--once``, ``--times N`` or at ``--rate`` until Ctrl-C."""
    run_dir, graph = load_graph(args.run_dir)
    info = resolve_topic(graph, args.topic)
    cls, text = split_type_and_values(info, args.values)
    refuse_protected(info, cls)
    body = build_message(cls, parse_flow(text))
    if args.rate <= 0:
        raise ConfigError("--rate must be positive")
    times = 1 if args.once else args.times
    stop_on_signals()
    name = tool_name("topic_pub")
    injector = Injector(info, origin=name) if any(e.address for e in info.subscribers) else None
    bus = BusPublisher(run_dir, name, {info.name: cls.TYPE})
    try:
        recorders = sum(1 for n in graph["nodes"].values() if n.get("type") == "recorder")
        bus.wait_for_recorders(recorders, args.wait)
        joined = 0 if injector is None else injector.wait_for_subscribers(args.wait)
        if injector is not None and joined < len(injector.addresses):
            print(f"topic pub: only {joined} of {len(injector.addresses)} subscribers joined; publishing anyway",
                  file=sys.stderr)
        period = round(1e9 / args.rate)
        clock = time_base_clock(graph)  # stamps on the graph's clock (the first machine's, with machines)
        due = clock()
        seq = 0
        while times is None or seq < times:
            now = clock()
            if now < due:
                time.sleep((due - now) / 1e9)
                now = clock()
            payload = encode(dataclasses.replace(body, header=Header(now, seq, now, {})))
            bus.send(info.name, payload)
            if injector is not None:
                injector.send(payload)
            if args.print_nth and seq % args.print_nth == 0:
                print(f"publishing #{seq + 1} on {info.name}", flush=True)
            seq += 1
            due += period
    except KeyboardInterrupt:
        pass
    finally:
        if injector is not None:
            injector.close()
        bus.close()
    return 0
