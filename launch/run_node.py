"""``slipstack run NODE``: one node as a process.

The launcher calls it with ``--spec FILE`` (a JSON :class:`RunSpec` plus
parameters); by hand, give endpoints with ``--pub`` and ``--sub TOPIC=ENDPOINT``
and parameters as ``name:=value``.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import signal

from slipstack.lib.errors import ConfigError
from slipstack.nodes.catalog import NODE_TYPES, node_class
from slipstack.nodes.node import make_params, param_help
from slipstack.nodes.process import ProcessExecutor, RunSpec

__all__ = ["add_parser", "main_run", "parse_assignments", "set_parent_death_signal"]

_PR_SET_PDEATHSIG = 1


def set_parent_death_signal(sig: int = signal.SIGTERM) -> None:
    """Ask Linux to send ``sig`` to this process when its parent dies (no orphans)."""
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(_PR_SET_PDEATHSIG, int(sig), 0, 0, 0)
    except OSError:
        pass


def parse_assignments(items: list[str]) -> dict[str, str]:
    """``["a:=1", "b:=x"]`` → ``{"a": "1", "b": "x"}``; raises ConfigError on other forms."""
    out = {}
    for item in items:
        name, sep, value = item.partition(":=")
        if not sep or not name:
            raise ConfigError(f"expected name:=value, got {item!r}")
        out[name] = value
    return out


def _node_epilog() -> str:
    lines = ["node types and their parameters:"]
    for type_name in sorted(NODE_TYPES):
        cls = node_class(type_name)
        doc = (cls.__doc__ or "").strip().splitlines()[0] if cls.__doc__ else ""
        lines.append(f"  {type_name}: {doc}")
        for name, typ, default, help_text in param_help(cls.Params):
            lines.append(f"      {name} ({typ}, default {default}) {help_text}")
    return "\n".join(lines)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run",
        help="run one node as a process",
        description="Run one node as a process. Parameters are given as name:=value.",
        epilog=_node_epilog(),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("node", help="node type (see the list below)")
    p.add_argument("assignments", nargs="*", metavar="name:=value", help="parameter overrides")
    p.add_argument("--name", help="instance name (default: the node type)")
    p.add_argument("--spec", help="JSON run spec written by the launcher")
    p.add_argument("--pub", help="endpoint to bind for publishing, e.g. ipc:///tmp/x.pub or tcp://*:5555")
    p.add_argument("--sub", action="append", default=[], metavar="TOPIC=ENDPOINT", help="where to find a topic (repeatable)")
    p.set_defaults(func=main_run)


def main_run(args: argparse.Namespace) -> int:
    cls = node_class(args.node)
    if args.spec:
        with open(args.spec) as fh:
            raw = json.load(fh)
        values = raw.pop("params", {})
        spec = RunSpec(**raw)
        set_parent_death_signal()
    else:
        subs: dict[str, list[str]] = {}
        for item in args.sub:
            topic, sep, ep = item.partition("=")
            if not sep:
                raise ConfigError(f"--sub expects TOPIC=ENDPOINT, got {item!r}")
            subs.setdefault(topic, []).append(ep)
        spec = RunSpec(name=args.name or args.node, pub=args.pub, subs=subs)
        values = {}
    values.update(parse_assignments(args.assignments))
    node = cls(make_params(cls.Params, values, spec.name))
    return ProcessExecutor(node, spec).run()
