"""The running graph's description, written by the launcher for tools on the bus.

``<run_dir>/graph.json``::

    {"run_dir": str, "launcher_pid": int, "launcher_start_ticks": int (field 22 of
     /proc/PID/stat: with the pid, names the launcher process even if the pid is reused),
     "started_ns": int, "launch_file": str,
     "state": "starting" (endpoints known, nodes coming up) | "running" (all ready),
     "nodes": {name: {"type": str, "pid": int | null, "pub": endpoint,
                      "inputs": {topic: message type}, "outputs": {topic: message type},
                      "inject": {topic: endpoint the node's SUB binds, for `topic pub`},
                      "restarts": int}}}

``<run root>/current`` is a symlink to the newest run directory; tools use it
unless ``--run-dir`` or ``$SLIPSTACK_RUN_DIR`` names another. A run directory whose
launcher is gone (SIGKILLed: nobody removed the directory) is refused as stale.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from slipstack.lib.errors import ConfigError
from slipstack.nodes.curve import use_keys
from slipstack.nodes.run_dir import CURRENT_LINK, point_current, run_root, write_private_file

__all__ = ["GRAPH_FILE", "write_graph", "read_graph", "find_run_dir", "topic_endpoints", "process_start_ticks"]

GRAPH_FILE = "graph.json"
RUN_DIR_ENV = "SLIPSTACK_RUN_DIR"


def process_start_ticks(pid: int) -> int | None:
    """When process ``pid`` started (clock ticks since boot, /proc/PID/stat field 22); None if it is gone."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None
    if fields[0] == "Z":  # a zombie has exited
        return None
    return int(fields[19])


def write_graph(run_dir: Path, graph: dict[str, Any]) -> None:
    """Atomically (re)write ``graph.json`` (never through a symlink) and point ``current`` at ``run_dir``."""
    write_private_file(run_dir, GRAPH_FILE, json.dumps(graph, indent=1))
    point_current(run_dir)


def _check_launcher_alive(path: Path, graph: dict[str, Any]) -> None:
    """Raise ConfigError if the launcher that wrote ``graph`` is gone (a stale run directory)."""
    pid = graph.get("launcher_pid")
    if pid is None:  # a graph not written by a launcher (hand-made): nothing to check
        return
    ticks = process_start_ticks(int(pid))
    if ticks is None or ticks != graph.get("launcher_start_ticks", ticks):
        raise ConfigError(
            f"no running graph (launcher pid {pid} is gone; run directory {path} is stale). "
            f"Start one with `slipstack launch`; remove {path} to clean up"
        )


def find_run_dir(explicit: str | None = None) -> Path:
    """The run directory to attach to.

    Raises:
        ConfigError: no running graph found, or its launcher is gone (says how to start one).
    """
    chosen = explicit or os.environ.get(RUN_DIR_ENV)
    path = Path(chosen) if chosen else run_root() / CURRENT_LINK
    try:
        graph = read_graph(path)
    except (OSError, ValueError):
        raise ConfigError(
            f"no running slipstack graph at {path}; start one with `slipstack launch` "
            f"or pass --run-dir (or set ${RUN_DIR_ENV})"
        ) from None
    _check_launcher_alive(path.resolve(), graph)
    return path.resolve()


def read_graph(run_dir: Path) -> dict[str, Any]:
    """Load ``graph.json`` from ``run_dir``; a graph with tcp keys makes this process use them
    (a tool attaching from outside the launch)."""
    graph = json.loads((run_dir / GRAPH_FILE).read_text())
    if graph.get("keys"):
        use_keys(graph["keys"])
    return graph


def topic_endpoints(graph: dict[str, Any]) -> dict[str, list[str]]:
    """Topic → endpoints of the nodes publishing it (``diagnostics``: every node)."""
    out: dict[str, list[str]] = {}
    for node in graph["nodes"].values():
        if not node.get("pub"):
            continue
        for topic in node["outputs"]:  # includes "diagnostics": every node publishes it
            out.setdefault(topic, []).append(node["pub"])
    return out
