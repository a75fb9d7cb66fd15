"""``slipstack param list | get | set``: a running node's parameters (ros2's ``param`` verbs).

The values in effect are the node's run spec (``<run_dir>/<process>.spec.json``) over its
type's defaults. ``set`` asks the launcher (its control endpoint, in ``graph.json``) to write
the new value into the spec and restart the node's process, which starts with it: a node's
state is built from its parameters at start, and a restart is the start every node is made
safe for (a grip controller starts from the force the pad measures). Only a process the
launch file lets restart (``respawn = true``) is; the launcher answers in
``<run_dir>/param-reply-<pid>.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import time
import typing
from pathlib import Path
from typing import Any

from slipstack.lib.errors import ConfigError
from slipstack.lib.toml_file import toml_value
from slipstack.nodes.runtime.graph_info import PARAM_REPLY, RUN_DIR_HELP, find_run_dir, read_graph
from slipstack.nodes.tools.node_tools import newest_diagnostics, node_params

__all__ = ["add_parser"]


def add_parser(sub: argparse._SubParsersAction) -> None:
    param = sub.add_parser("param", help="a running node's parameters: list, get, set (restarts its process)",
                           description="The parameters of a running graph's nodes: the values in effect, and a "
                                       "new value (the node's process restarts with it).")
    verbs = param.add_subparsers(dest="verb", required=True, metavar="VERB")
    p = verbs.add_parser("list", help="every parameter of a node, with its value and meaning")
    p.add_argument("node", help="node name (see `slipstack node list`)")
    p.add_argument("--run-dir", metavar="DIR", help=RUN_DIR_HELP)
    p.set_defaults(func=main_list)
    p = verbs.add_parser("get", help="one parameter's value")
    p.add_argument("node", help="node name")
    p.add_argument("name", help="parameter name (see `slipstack param list NODE`)")
    p.add_argument("--run-dir", metavar="DIR", help=RUN_DIR_HELP)
    p.set_defaults(func=main_get)
    p = verbs.add_parser("set", help="give a parameter a new value: the node's process restarts with it",
                         description="Set a parameter of a running node. The launcher writes it into the node's "
                                     "run spec and restarts the node's process (a container: all its nodes), "
                                     "if the launch file lets it restart (respawn = true); the node starts with "
                                     "the new value as it does after any restart.")
    p.add_argument("node", help="node name")
    p.add_argument("name", help="parameter name")
    p.add_argument("value", help="the new value, as in name:=value")
    p.add_argument("--timeout", type=float, default=30.0, metavar="S",
                   help="how long to wait for the node to be back (default 30 s)")
    p.add_argument("--run-dir", metavar="DIR", help=RUN_DIR_HELP)
    p.set_defaults(func=main_set)


def _node(run_dir: Path, graph: dict[str, Any], name: str) -> tuple[dict[str, Any], type, dict[str, Any]]:
    """(graph entry, node class, parameters in effect) of node ``name``."""
    from slipstack.nodes.catalog import node_class

    entry = graph["nodes"].get(name)
    if entry is None or entry.get("tool"):
        raise ConfigError(f"no node {name!r} in the running graph; nodes: "
                          f"{', '.join(sorted(n for n, e in graph['nodes'].items() if not e.get('tool')))}")
    cls = node_class(entry["type"])
    return entry, cls, node_params(run_dir, name) or {}


def _values(cls: type, given: dict[str, Any]) -> dict[str, tuple[str, str]]:
    """name → (value in effect as a launch file writes it, help), the given ones (read as the
    node reads them: ``param set`` stores its text) over the type's defaults."""
    from slipstack.lib.config import read_typed
    from slipstack.nodes.runtime.node import param_help

    hints = typing.get_type_hints(cls.Params)
    return {name: (toml_value(read_typed(given[name], hints[name], name)) if name in given else default, text)
            for name, _, default, text in param_help(cls.Params)}


def main_list(args: argparse.Namespace) -> int:
    run_dir = find_run_dir(args.run_dir)
    _, cls, given = _node(run_dir, read_graph(run_dir), args.node)
    for name, (value, text) in _values(cls, given).items():
        print(f"{name} = {value}" + (f"  # {text}" if text else ""))
    return 0


def main_get(args: argparse.Namespace) -> int:
    run_dir = find_run_dir(args.run_dir)
    _, cls, given = _node(run_dir, read_graph(run_dir), args.node)
    values = _values(cls, given)
    if args.name not in values:
        raise ConfigError(f"{args.node} has no parameter {args.name!r}; its parameters: {', '.join(values)}")
    print(values[args.name][0])
    return 0


def main_set(args: argparse.Namespace) -> int:
    from slipstack.nodes.runtime.node import make_params

    run_dir = find_run_dir(args.run_dir)
    graph = read_graph(run_dir)
    entry, cls, given = _node(run_dir, graph, args.node)
    if graph.get("state") == "starting":
        raise ConfigError("the graph is still starting: set it once `slipstack node list` shows it up")
    if entry.get("pid") is None:
        raise ConfigError(f"{args.node} does not run on this machine (or has not started): set it where its "
                          "launcher runs")
    params = make_params(cls.Params, {**given, args.name: args.value}, args.node)  # a wrong name or type
    try:  # a value the node refuses fails here, as its restarted process would: never a crash loop of it
        cls(params)
    except Exception as exc:  # noqa: BLE001 - any refusal of the node, said in one line
        raise ConfigError(f"{args.node} refuses {args.name} := {args.value}: {exc or type(exc).__name__}; "
                          "nothing was changed") from None
    before = entry.get("restarts", 0)
    reply = run_dir / f"{PARAM_REPLY}{os.getpid()}.json"
    _ask_launcher(graph, {"event": "set_param", "node": args.node, "name": args.name, "value": args.value,
                          "reply": os.getpid()})
    deadline = time.monotonic() + args.timeout
    answer = _wait_for(lambda: reply.exists(), deadline) and json.loads(reply.read_text())
    reply.unlink(missing_ok=True)
    if not answer:
        raise ConfigError(f"the launcher did not answer within {args.timeout:g} s (is the graph still running?)")
    if not answer["ok"]:
        raise ConfigError(f"{args.node} {args.name}: {answer['message']}")
    print(f"{args.node}: {args.name} := {args.value}; {answer['message']}", flush=True)
    restarted = _wait_for(lambda: read_graph(run_dir)["nodes"][args.node].get("restarts", 0) > before, deadline)
    back = restarted and newest_diagnostics(read_graph(run_dir)["nodes"][args.node]["pub"], args.node,
                                            max(deadline - time.monotonic(), 0.1))
    if not back:
        raise ConfigError(f"{args.node} was not back within {args.timeout:g} s; see the launch's output")
    print(f"{args.node} is back: {back.status}")
    return 0


def _ask_launcher(graph: dict[str, Any], event: dict[str, Any]) -> None:
    import msgpack
    import zmq

    sock = zmq.Context.instance().socket(zmq.PUSH)
    sock.setsockopt(zmq.LINGER, 2000)
    sock.setsockopt(zmq.SNDTIMEO, 2000)
    try:
        sock.connect(graph["control"])
        sock.send(msgpack.packb(event))
    except (KeyError, zmq.ZMQError) as exc:
        raise ConfigError(f"cannot reach the launcher ({exc}); is the graph still running?") from None
    finally:
        sock.close()


def _wait_for(condition: Any, deadline: float) -> bool:
    while not condition():
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.05)
    return True
