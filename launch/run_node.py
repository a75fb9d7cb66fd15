"""``slipstack run NODE``: one node as a process (or ``run container``: several).

The launcher starts ``python -m slipstack.launch.run_node NODE --spec FILE`` (a JSON
:class:`RunSpec` plus parameters; for a container ``{"container": NAME, "members":
[{"type": …, spec…}]}``): that entry imports only what the node needs, not every
command and node type as ``slipstack`` does, so a respawned node is back sooner. By
hand, ``slipstack run NODE`` with endpoints as ``--pub`` and ``--sub TOPIC=ENDPOINT``
and parameters as ``name:=value``.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import re
import signal
import sys
from pathlib import Path
from typing import Callable

import zmq

from slipstack.lib.errors import ConfigError, SlipstackError
from slipstack.nodes.catalog import NODE_TYPES, node_class
from slipstack.nodes.runtime.node import Node, make_params, param_help
from slipstack.nodes.runtime.process import ProcessExecutor, RunSpec

__all__ = ["add_parser", "main_run", "main_spawned", "parse_assignments", "set_parent_death_signal"]

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
            one = item.partition("=")
            hint = f" (did you mean {one[0]}:={one[2]}?)" if one[1] and one[0] else ""
            raise ConfigError(f"expected name:=value, got {item!r}{hint}")
        out[name] = value
    return out


_RST_ROLE = re.compile(r":[a-z]+:`~?([^`]*)`")


def _plain_summary(doc: str | None) -> str:
    """A docstring's first paragraph on one line, without reStructuredText markup
    (``x`` → x, :class:`~a.b.C` → C)."""
    text = " ".join((doc or "").strip().split("\n\n")[0].split())
    text = _RST_ROLE.sub(lambda m: m.group(1).rpartition(".")[2], text)
    return text.replace("``", "")


def _node_epilog(types: list[str] | None = None) -> str:
    """The node types (default: all) with their parameters, for ``--help``."""
    lines = ["container: the nodes of a launch-file container in one process (needs --spec from the launcher)",
             "", "node types and their parameters:"]
    for type_name in types or sorted(NODE_TYPES):
        cls = node_class(type_name)
        lines.append(f"  {type_name}: {_plain_summary(cls.__doc__)}")
        for name, typ, default, help_text in param_help(cls.Params):
            lines.append(f"      {name} ({typ}, default {default}) {help_text}")
    return "\n".join(lines)


class _NodeHelp(argparse.Action):
    """``--help``: the parameters of the node type given before it (``run rig --help``), else of every type."""

    def __init__(self, option_strings: list[str], dest: str = argparse.SUPPRESS, help: str | None = None) -> None:
        super().__init__(option_strings, dest=dest, default=argparse.SUPPRESS, nargs=0, help=help)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: object,
                 option_string: str | None = None) -> None:
        node = getattr(namespace, "node", None)
        parser.epilog = _node_epilog([node] if node in NODE_TYPES else None)
        parser.print_help()
        parser.exit()


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run",
        help="run one node as a process",
        description="Run one node as a process. Parameters are given as name:=value.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        add_help=False,
    )
    p.add_argument("-h", "--help", action=_NodeHelp,
                   help="show this help (with NODE before it: that node's parameters only) and exit")
    p.add_argument("node", help="node type (see the list below), or 'container'")
    p.add_argument("assignments", nargs="*", metavar="name:=value", help="parameter overrides")
    p.add_argument("--name", help="instance name (default: the node type)")
    p.add_argument("--spec", help="JSON run spec written by the launcher")
    p.add_argument("--pub", help="endpoint to bind for publishing, e.g. ipc:///tmp/x.pub or tcp://*:5555 "
                                 "(default: attach to the running graph, else a default endpoint, said on stderr)")
    p.add_argument("--sub", action="append", default=[], metavar="TOPIC=ENDPOINT", help="where to find a topic (repeatable)")
    p.add_argument("--log-level", metavar="LEVEL", default=None,
                   help="least level of the log lines shown: debug, info (default), warning, error")
    p.set_defaults(func=main_run)


def _member(raw: dict) -> tuple[Node, RunSpec]:
    """A node and its spec from one spec document (parameters under "params")."""
    raw = dict(raw)
    cls = node_class(raw.pop("type"))
    values = raw.pop("params", {})
    spec = RunSpec(**raw)
    return cls(make_params(cls.Params, values, spec.name)), spec


def _executor(members: list[tuple[Node, RunSpec]], clock: Callable[[], int] | None = None) -> ProcessExecutor:
    """The executor of ``members`` (binds their sockets); SlipstackError, one line, if an address is taken."""
    try:
        return ProcessExecutor(members, clock=clock)
    except zmq.ZMQError as exc:
        if exc.errno != zmq.EADDRINUSE:
            raise
        names = ", ".join(spec.name for _, spec in members)
        raise SlipstackError(
            f"{names}: cannot bind its socket: {exc}. Another process holds that address: stop it (`ss -ltnp` "
            "shows who) or give another address"
        ) from None


def main_run(args: argparse.Namespace) -> int:
    from slipstack.nodes.runtime.logs import configure_logging

    configure_logging(getattr(args, "log_level", None))  # None: the launcher's, from the environment
    if args.node == "container":
        if not args.spec or args.assignments:
            raise ConfigError("run container needs --spec FILE (written by the launcher) and no name:=value")
        with open(args.spec) as fh:
            doc = json.load(fh)
        set_parent_death_signal()
        return _executor([_member(m) for m in doc["members"]]).run()
    node_class(args.node)  # an unknown type fails here, with the list of known ones
    if args.spec:
        with open(args.spec) as fh:
            raw = json.load(fh)
        set_parent_death_signal()
    else:
        subs: dict[str, list[str]] = {}
        for item in args.sub:
            topic, sep, ep = item.partition("=")
            if not sep:
                raise ConfigError(f"--sub expects TOPIC=ENDPOINT, got {item!r}")
            subs.setdefault(topic, []).append(ep)
        raw = {"name": args.name or args.node, "pub": args.pub, "subs": subs}
    raw.setdefault("params", {}).update(parse_assignments(args.assignments))
    member = _member({**raw, "type": args.node})  # parameter errors first
    if args.spec or args.pub:
        return _executor([member]).run()
    return _run_attached(args, raw)


def _run_attached(args: argparse.Namespace, raw: dict) -> int:
    """A node run by hand without ``--pub``: attached to the running graph (its inputs from the
    graph's publishers, its endpoint registered beside the graph's tools, so that ``topic echo``
    and the recorders see it; the graph's time base), else publishing on a default endpoint in
    the run root. Says where on stderr."""
    from slipstack.nodes.runtime.graph_info import find_run_dir, read_graph, register_tool, topic_endpoints
    from slipstack.nodes.runtime.graph_info import time_base_clock
    from slipstack.nodes.runtime.host import DIAGNOSTICS_TOPIC
    from slipstack.messages import Diagnostics
    from slipstack.nodes.runtime.run_dir import run_root
    from slipstack.nodes.runtime.transport import ipc_endpoint

    try:
        run_dir: Path | None = find_run_dir(None)
        graph = read_graph(run_dir)
    except ConfigError:
        run_dir, graph = None, {"nodes": {}}
    name = args.name or f"{args.node}-{os.getpid()}"  # beside a graph that may run a node of the same type
    raw = {**raw, "name": name, "pub": ipc_endpoint(run_dir or run_root(), name)}
    publishers = topic_endpoints(graph)
    inputs = [i.topic for i in node_class(args.node).inputs.values()]
    node, spec = _member({**raw, "type": args.node,
                          "subs": {**{t: publishers[t] for t in inputs if t in publishers}, **raw["subs"]}})
    outputs = {o.topic: o.type.TYPE for o in node.outputs.values()}
    where = f"the graph in {run_dir}" if run_dir is not None else "no running graph"
    print(f"{name}: {where}; publishing {', '.join([*outputs, 'diagnostics'])} on {spec.pub}"
          + (f"; inputs from {', '.join(sorted(spec.subs))}" if spec.subs else "")
          + ("" if run_dir is not None else f" (a consumer: --sub TOPIC={spec.pub})"), file=sys.stderr, flush=True)
    registration = (register_tool(run_dir, name, spec.pub, {**outputs, DIAGNOSTICS_TOPIC: Diagnostics.TYPE})
                    if run_dir is not None else None)
    try:
        return _executor([(node, spec)], time_base_clock(graph) if run_dir is not None else None).run()
    finally:
        if registration is not None:
            registration.unlink(missing_ok=True)


def main_spawned(argv: list[str] | None = None) -> int:
    """``python -m slipstack.launch.run_node NODE --spec FILE``: the launcher's lean way to start a process."""
    from slipstack.lib.errors import run_guarded

    parser = argparse.ArgumentParser(
        prog="python -m slipstack.launch.run_node",
        description="Run a node (or 'container') from a run spec written by `slipstack launch`.",
    )
    parser.add_argument("node", help="node type, or 'container'")
    parser.add_argument("--spec", required=True, help="JSON run spec written by the launcher")
    parser.add_argument("--standby", action="store_true",
                        help="import the node's modules, then wait for a line on stdin before starting "
                             "(end of stdin: exit without starting)")
    args = parser.parse_args(argv)
    args.assignments, args.name, args.pub, args.sub = [], None, None, []
    if args.standby and not _wait_for_go(args.node, args.spec):
        return 0
    return run_guarded("run", lambda: main_run(args))


def _wait_for_go(node_type: str, spec_path: str) -> bool:
    """Import the modules of the node(s) to run, then block until stdin says go (True) or ends (False)."""
    set_parent_death_signal()
    with open(spec_path) as fh:
        doc = json.load(fh)
    for name in [m["type"] for m in doc["members"]] if node_type == "container" else [node_type]:
        node_class(name)
    # loading the numba kernels is the slow part of the start of the nodes that use them
    kernels = sys.modules.get("slipstack.lib.limit_set")
    if kernels is not None:
        kernels.compile_kernels()
    return bool(sys.stdin.readline())


if __name__ == "__main__":
    sys.exit(main_spawned())
