"""The running graph's description, written by the launcher for tools on the bus.

``<run_dir>/graph.json``::

    {"run_dir": str, "launcher_pid": int, "started_ns": int, "launch_file": str,
     "state": "starting" (endpoints known, nodes coming up) | "running" (all ready),
     "nodes": {name: {"type": str, "pid": int | null, "pub": endpoint,
                      "inputs": {topic: message type}, "outputs": {topic: message type},
                      "inject": {topic: endpoint the node's SUB binds, for `topic pub`},
                      "restarts": int}}}

``<run root>/current`` is a symlink to the newest run directory; tools use it
unless ``--run-dir`` or ``$SLIPSTACK_RUN_DIR`` names another.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from slipstack.lib.errors import ConfigError
from slipstack.nodes.transport import run_root

__all__ = ["GRAPH_FILE", "write_graph", "read_graph", "find_run_dir", "topic_endpoints"]

GRAPH_FILE = "graph.json"
RUN_DIR_ENV = "SLIPSTACK_RUN_DIR"


def write_graph(run_dir: Path, graph: dict[str, Any]) -> None:
    """Atomically (re)write ``graph.json`` and point ``current`` at ``run_dir``."""
    tmp = run_dir / (GRAPH_FILE + ".tmp")
    tmp.write_text(json.dumps(graph, indent=1))
    os.replace(tmp, run_dir / GRAPH_FILE)
    link = run_root() / "current"
    tmp_link = run_root() / f".current-{os.getpid()}"
    if tmp_link.is_symlink():
        tmp_link.unlink()
    tmp_link.symlink_to(run_dir)
    os.replace(tmp_link, link)


def find_run_dir(explicit: str | None = None) -> Path:
    """The run directory to attach to.

    Raises:
        ConfigError: no running graph found (says how to start one).
    """
    chosen = explicit or os.environ.get(RUN_DIR_ENV)
    path = Path(chosen) if chosen else run_root() / "current"
    if not (path / GRAPH_FILE).exists():
        raise ConfigError(
            f"no running slipstack graph at {path}; start one with `slipstack launch` "
            f"or pass --run-dir (or set ${RUN_DIR_ENV})"
        )
    return path.resolve()


def read_graph(run_dir: Path) -> dict[str, Any]:
    """Load ``graph.json`` from ``run_dir``."""
    return json.loads((run_dir / GRAPH_FILE).read_text())


def topic_endpoints(graph: dict[str, Any]) -> dict[str, list[str]]:
    """Topic → endpoints of the nodes publishing it (``diagnostics``: every node)."""
    out: dict[str, list[str]] = {}
    for node in graph["nodes"].values():
        if not node.get("pub"):
            continue
        for topic in node["outputs"]:  # includes "diagnostics": every node publishes it
            out.setdefault(topic, []).append(node["pub"])
    return out
