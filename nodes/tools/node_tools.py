"""``slipstack node list | info NAME``: the running graph's nodes (ros2's ``node`` verbs).

``list`` reads ``graph.json`` (nodes and registered tools). ``info`` adds the node's
launch parameters (from its process's run spec, ``<run_dir>/<process>.spec.json``)
and its newest ``diagnostics`` frame (status, last error, counters), waiting up to
``--timeout`` for one.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from slipstack.lib.errors import ConfigError
from slipstack.nodes.runtime.graph_info import RUN_DIR_HELP, find_run_dir, process_start_ticks, read_graph

__all__ = ["add_parser", "node_params", "newest_diagnostics"]

_SPEC_GLOB = "*.spec.json"


def add_parser(sub: argparse._SubParsersAction) -> None:
    node = sub.add_parser("node", help="list the running graph's nodes, or one node's state",
                          description="The nodes of a running graph: names, types, processes; one node's "
                                      "endpoints, parameters, status and counters.")
    verbs = node.add_subparsers(dest="verb", required=True, metavar="VERB")
    p = verbs.add_parser("list", help="the nodes: name, type, pid, restarts",
                         description="List the nodes (and publishing tools) of the running graph.")
    p.add_argument("--run-dir", metavar="DIR", help=RUN_DIR_HELP)
    p.set_defaults(func=main_list)
    p = verbs.add_parser("info", help="one node: endpoints, parameters, status, counters",
                         description="Print a node's type, pid, topics, launch parameters and its newest "
                                     "diagnostics (status, last error, counters).")
    p.add_argument("name", help="node name (see `slipstack node list`)")
    p.add_argument("--timeout", type=float, default=3.0, metavar="S",
                   help="how long to wait for the node's diagnostics (default 3 s)")
    p.add_argument("--run-dir", metavar="DIR", help=RUN_DIR_HELP)
    p.set_defaults(func=main_info)


def _alive(entry: dict[str, Any], graph_state: str = "running") -> str:
    pid = entry.get("pid")
    if pid is None:
        return "not started yet" if graph_state == "starting" else "down"
    return "running" if process_start_ticks(int(pid)) is not None else "down"


def main_list(args: argparse.Namespace) -> int:
    graph = read_graph(find_run_dir(args.run_dir))
    machine = graph.get("machine") or {}
    here = machine.get("name")
    if here:
        print(f"machine {here}; its nodes' clock is {machine.get('clock_offset_ns', 0) / 1e6:+.3f} ms from this "
              "machine's monotonic clock (the first machine's time base)")
        for name, peer in machine.get("peers", {}).items():
            clock = (f", clock {peer['offset_ns'] / 1e6:+.3f} ms ± {peer['uncertainty_ns'] / 1e6:.3f} ms from ours"
                     if "offset_ns" in peer else "")
            print(f"machine {name}: {peer['state']}{' (quiet)' if peer.get('quiet') else ''}{clock}")
    state = graph.get("state", "running")
    if state != "running":
        print(f"graph {state}")
    for name, entry in sorted(graph["nodes"].items()):
        kind = "tool" if entry.get("tool") else entry.get("type", "?")
        if entry.get("machine", here) != here:  # run by another machine's launcher: no pid here
            print(f"{name}  [{kind}] on machine {entry['machine']} ({entry['pub']})")
            continue
        pid = entry.get("pid")
        print(f"{name}  [{kind}] pid {'-' if pid is None else pid} {_alive(entry, state)}, "
              f"restarts {entry.get('restarts', 0)}")
    return 0


def node_params(run_dir: Path, name: str) -> dict[str, Any] | None:
    """The launch parameters of node ``name`` from the run specs (``None``: no spec names it)."""
    for path in sorted(run_dir.glob(_SPEC_GLOB)):
        try:
            doc = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        for member in doc.get("members", [doc]):
            if isinstance(member, dict) and member.get("name") == name:
                return dict(member.get("params", {}))
    return None


def newest_diagnostics(endpoint: str, name: str, timeout_s: float) -> Any:
    import zmq

    from slipstack.lib.errors import DecodeError
    from slipstack.messages import Diagnostics, decode
    from slipstack.nodes.runtime.transport import make_sub

    sock = make_sub(zmq.Context.instance(), [endpoint], "diagnostics", rcvhwm=100)
    deadline = time.monotonic() + timeout_s
    try:
        while (left := deadline - time.monotonic()) > 0:
            if not sock.poll(max(1, round(left * 1000))):
                break
            parts = sock.recv_multipart()
            if len(parts) != 2 or parts[0] != b"diagnostics":
                continue
            try:
                msg = decode(parts[1], Diagnostics)
            except DecodeError:
                continue
            if msg.node == name:
                return msg
    finally:
        sock.close(linger=0)
    return None


def main_info(args: argparse.Namespace) -> int:
    run_dir = find_run_dir(args.run_dir)
    graph = read_graph(run_dir)
    entry = graph["nodes"].get(args.name)
    if entry is None:
        raise ConfigError(f"no node {args.name!r} in the running graph; nodes: {', '.join(sorted(graph['nodes']))}")
    print(f"{args.name}")
    print(f"  type: {entry.get('type')}  pid: {entry.get('pid')} ({_alive(entry)})  restarts: {entry.get('restarts', 0)}")
    print(f"  publishes on {entry.get('pub') or 'nothing'}:")
    for topic, type_name in sorted(entry.get("outputs", {}).items()):
        print(f"    {topic} [{type_name}]")
    print("  subscribes:")
    for topic, type_name in sorted(entry.get("inputs", {}).items()):
        print(f"    {topic} [{type_name}] (inject: {entry.get('inject', {}).get(topic, 'none')})")
    params = node_params(run_dir, args.name)
    print("  parameters:" + ("" if params else " (defaults)"))
    for key, value in sorted((params or {}).items()):
        print(f"    {key}: {value!r}")
    diag = newest_diagnostics(entry["pub"], args.name, args.timeout) if entry.get("pub") else None
    if diag is None:
        print(f"  diagnostics: none within {args.timeout:g} s")
        return 0
    print(f"  status: {diag.status}")
    if diag.last_error:
        print(f"  last error: {diag.last_error}")
    print("  counters:")
    for key, value in sorted(diag.counters.items()):
        print(f"    {key}: {value:g}")
    return 0
