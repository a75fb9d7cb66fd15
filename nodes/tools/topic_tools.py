"""``slipstack topic``: look at the running graph's topics (ros2cli conventions).

More in docs/modules.md, `nodes/tools/topic_tools.py`.
"""

from __future__ import annotations

import argparse
import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from slipstack.lib.errors import ConfigError
from slipstack.nodes.runtime.graph_info import RUN_DIR_HELP, find_run_dir, read_graph

if TYPE_CHECKING:
    from slipstack.messages import Message

__all__ = ["Endpoint", "TopicInfo", "load_graph", "graph_topics", "resolve_topic", "add_parser"]


@dataclass(frozen=True)
class Endpoint:
    """One node's end of a topic: its name and a socket address (pub, or inject for a subscriber)."""

    node: str
    address: str | None


@dataclass(frozen=True)
class TopicInfo:
    """A topic of the running graph.

    types: the distinct message type names declared by its publishers and subscribers
        (one, unless the graph is mis-wired).
    publishers: nodes publishing it, with their XPUB endpoints.
    subscribers: nodes subscribing to it, with the endpoint their SUB socket binds for
        injection (``topic pub``), ``None`` if the node has none.
    """

    name: str
    types: tuple[str, ...]
    publishers: tuple[Endpoint, ...]
    subscribers: tuple[Endpoint, ...]

    @property
    def type_name(self) -> str:
        return self.types[0] if len(self.types) == 1 else " | ".join(self.types)

    def message_type(self) -> type[Message]:
        """The registered message class of this topic.

        Raises:
            ConfigError: the topic's publishers and subscribers disagree on the type, or
                the type is not known to this installation.
        """
        from slipstack.messages import registry  # numpy: only for the verbs that decode

        if len(self.types) != 1:
            raise ConfigError(f"topic {self.name} is declared with several types: {', '.join(self.types)}")
        cls = registry.get(self.types[0])
        if cls is None:
            raise ConfigError(f"topic {self.name}: message type {self.types[0]!r} is not known here")
        return cls


def load_graph(run_dir: str | None) -> tuple[Path, dict[str, Any]]:
    """``(run_dir, graph)`` of the graph to attach to; ConfigError if none is running."""
    path = find_run_dir(run_dir)
    return path, read_graph(path)


def graph_topics(graph: dict[str, Any]) -> dict[str, TopicInfo]:
    """Every topic of ``graph`` (published or subscribed), by name, sorted."""
    types: dict[str, set[str]] = {}
    pubs: dict[str, list[Endpoint]] = {}
    subs: dict[str, list[Endpoint]] = {}
    for name, node in graph["nodes"].items():
        for topic, type_name in node.get("outputs", {}).items():
            types.setdefault(topic, set()).add(type_name)
            pubs.setdefault(topic, []).append(Endpoint(name, node.get("pub")))
        for topic, type_name in node.get("inputs", {}).items():
            types.setdefault(topic, set()).add(type_name)
            subs.setdefault(topic, []).append(Endpoint(name, node.get("inject", {}).get(topic)))
    return {
        t: TopicInfo(t, tuple(sorted(types[t])), tuple(pubs.get(t, ())), tuple(subs.get(t, ())))
        for t in sorted(types)
    }


def resolve_topic(graph: dict[str, Any], name: str) -> TopicInfo:
    """The topic called ``name`` (a leading ``/`` is ignored, as ROS users type it).

    Raises:
        ConfigError: unknown topic; the message lists the known ones.
    """
    topics = graph_topics(graph)
    info = topics.get(name) or topics.get(name.lstrip("/"))
    if info is None:
        raise ConfigError(f"unknown topic {name!r}; topics of this graph: {', '.join(topics) or 'none'}")
    return info


def _plural(n: int, word: str) -> str:
    return f"{n} {word}{'' if n == 1 else 's'}"


def main_list(args: argparse.Namespace) -> int:
    _, graph = load_graph(args.run_dir)
    topics = graph_topics(graph)
    if args.count_topics:
        print(len(topics))
        return 0
    if not args.verbose:
        for t in topics.values():
            print(f"{t.name} [{t.type_name}]" if args.show_types else t.name)
        return 0
    for title, attr, word in (("Published topics:", "publishers", "publisher"),
                              ("Subscribed topics:", "subscribers", "subscriber")):
        print(title)
        for t in topics.values():
            ends: tuple[Endpoint, ...] = getattr(t, attr)
            if ends:
                print(f" * {t.name} [{t.type_name}] {_plural(len(ends), word)}: "
                      + ", ".join(f"{e.node} ({e.address or 'no endpoint'})" for e in ends))
        print()
    return 0


def main_info(args: argparse.Namespace) -> int:
    _, graph = load_graph(args.run_dir)
    t = resolve_topic(graph, args.topic)
    print(f"Type: {t.type_name}")
    print(f"Publisher count: {len(t.publishers)}")
    if args.verbose:
        for e in t.publishers:
            print(f"  Node name: {e.node}\n  Endpoint: {e.address}\n")
    print(f"Subscription count: {len(t.subscribers)}")
    if args.verbose:
        for e in t.subscribers:
            print(f"  Node name: {e.node}\n  Injection endpoint: {e.address or 'none'}\n")
    return 0


def _run_dir_option(p: argparse.ArgumentParser) -> None:
    p.add_argument("--run-dir", metavar="DIR", help=RUN_DIR_HELP)


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Add ``topic`` and its verbs to the ``slipstack`` command (the verbs' modules are
    imported when the verb runs)."""

    topic = sub.add_parser("topic", help="inspect and poke the running graph's topics",
                           description="Inspect and poke the topics of a running graph.")
    verbs = topic.add_subparsers(dest="verb", required=True, metavar="VERB")

    p = verbs.add_parser("list", help="list the topics", description="List the topics of the running graph.")
    p.add_argument("-t", "--show-types", action="store_true", help="also show each topic's message type")
    p.add_argument("-c", "--count-topics", action="store_true", help="only print the number of topics")
    p.add_argument("-v", "--verbose", action="store_true", help="list publishers and subscribers with endpoints")
    _run_dir_option(p)
    p.set_defaults(func=main_list)

    p = verbs.add_parser("info", help="type, publishers and subscribers of a topic",
                         description="Print a topic's type and its publisher and subscription counts.")
    _topic_argument(p)
    p.add_argument("-v", "--verbose", action="store_true", help="list the nodes and their endpoints")
    _run_dir_option(p)
    p.set_defaults(func=main_info)

    for add in (_add_echo, _add_hz, _add_delay, _add_bw, _add_pub):
        _run_dir_option(add(verbs))


def _topic_argument(p: argparse.ArgumentParser, example: str = "ft/wrench") -> None:
    """The TOPIC positional, completed in the shell with the running graph's topics."""
    p.add_argument("topic", help=f"topic name, e.g. {example}").completer = _running_topics  # type: ignore[attr-defined]


def _running_topics(**_: object) -> list[str]:
    """Shell completion of a topic: the running graph's topics (none if no graph runs)."""
    try:
        return sorted(graph_topics(load_graph(None)[1]))
    except (ConfigError, OSError, ValueError):
        return []


def _lazy(module: str, function: str) -> Callable[[argparse.Namespace], int]:
    """``module.function``, imported when called."""

    def run(args: argparse.Namespace) -> int:
        return getattr(importlib.import_module(module), function)(args)

    return run


def _add_echo(verbs: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = verbs.add_parser(
        "echo", help="print a topic's messages",
        description="Print the messages of TOPIC as YAML-ish text (one message per block, "
                    "separated by '---'), or as CSV. A topic not published yet is waited for. Lost "
                    "messages (sequence gaps, per publisher) and rejected frames are reported on stderr.",
    )
    _topic_argument(p)
    p.add_argument("--once", action="store_true", help="print one message and exit")
    p.add_argument("--count", type=int, metavar="N", help="print N messages and exit")
    p.add_argument("--field", metavar="a.b", help="print only this field, e.g. force or header.stamp_ns")
    p.add_argument("--csv", action="store_true", help="one CSV line per message (arrays flattened), after a header line")
    p.add_argument("--no-arr", action="store_true", help="hide array values (show dtype and shape)")
    p.add_argument("--truncate-length", type=int, default=16, metavar="N",
                   help="array values shown before '...' (default 16)")
    p.add_argument("--filter", metavar="EXPR",
                   help="print only messages for which the Python expression is true, e.g. 'm.node == \"relay\"'")
    p.add_argument("--timeout", type=float, metavar="S",
                   help="exit S seconds after the start, however many messages came (exit code 1 if "
                        "none was printed)")
    p.add_argument("--qos-depth", type=int, default=2000, metavar="N",
                   help="frames queued per publisher before the publisher drops for us (default 2000)")
    p.set_defaults(func=_lazy("slipstack.nodes.tools.topic_echo", "main_echo"))
    return p


def _window_verb(verbs: argparse._SubParsersAction, name: str, help_text: str, description: str,
                 function: str) -> argparse.ArgumentParser:
    """A verb of :mod:`.topic_hz` (TOPIC, --window, --duration), running ``function`` there."""
    p = verbs.add_parser(name, help=help_text, description=description)
    _window_options(p)
    p.set_defaults(func=_lazy("slipstack.nodes.tools.topic_hz", function))
    return p


def _add_hz(verbs: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = _window_verb(verbs, "hz", "print a topic's rate",
                     "Print the average rate and period min/max/std of TOPIC over the last --window "
                     "messages, once per second, from receive times (or header stamps).", "main_hz")
    p.add_argument("--use-stamps", action="store_true",
                   help="use the messages' header.stamp_ns instead of receive times")
    return p


def _add_delay(verbs: argparse._SubParsersAction) -> argparse.ArgumentParser:
    return _window_verb(verbs, "delay", "print a topic's sample-to-here latency",
                        "Print the average, min, max and std of (receive time - header.stamp_ns) of TOPIC over "
                        "the last --window messages, once per second. The stamp is the time of the sensor "
                        "sample a message derives from, so this is the latency from the sample to this tool.",
                        "main_delay")


def _add_bw(verbs: argparse._SubParsersAction) -> argparse.ArgumentParser:
    return _window_verb(verbs, "bw", "print a topic's bandwidth",
                        "Print the bytes per second of TOPIC's payloads (MessagePack, as on the wire) and their "
                        "mean, min and max size over the last --window messages, once per second.", "main_bw")


def _window_options(p: argparse.ArgumentParser) -> None:
    _topic_argument(p)
    p.add_argument("-w", "--window", type=int, default=10000, metavar="N",
                   help="messages the statistics cover (default 10000)")
    p.add_argument("--duration", type=float, metavar="S", help="exit after S seconds (default: until Ctrl-C)")


def _add_pub(verbs: argparse._SubParsersAction) -> argparse.ArgumentParser:
    p = verbs.add_parser(
        "pub", help="publish messages by hand",
        description="Publish a message on TOPIC to the nodes that subscribe to it (through their "
                    "injection endpoints) and on the bus, where topic echo and the recorders see it. "
                    "VALUES are YAML flow text; unset fields keep defaults. "
                    "Example: slipstack topic pub grip/command '{f_n_desired: 12.0, law: manual}' --rate 10",
    )
    _topic_argument(p, "grip/command")
    p.add_argument("values", nargs="*", metavar="[TYPE] VALUES",
                   help="optional message type (slipstack/Wrench or Wrench; checked against the graph), then the field "
                        "values")
    p.add_argument("-r", "--rate", type=float, default=1.0, metavar="HZ", help="publishing rate (default 1 Hz)")
    once = p.add_mutually_exclusive_group()
    once.add_argument("-1", "--once", action="store_true", help="publish one message and exit")
    once.add_argument("-t", "--times", type=int, metavar="N", help="publish N messages and exit")
    p.add_argument("-w", "--wait", type=float, default=3.0, metavar="S",
                   help="how long to wait for the subscribers to join (default 3 s)")
    p.add_argument("-p", "--print", dest="print_nth", type=int, default=1, metavar="N",
                   help="print every N-th publication (0: never; default 1)")
    p.set_defaults(func=_lazy("slipstack.nodes.tools.topic_pub", "main_pub"))
    return p

