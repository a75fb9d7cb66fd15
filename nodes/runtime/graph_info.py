"""The running graph's description, written by the launcher for tools on the bus.

``<run_dir>/graph.json``::

More in docs/modules.md, `nodes/runtime/graph_info.py`.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Callable

from slipstack.lib.errors import ConfigError
from slipstack.nodes.runtime.run_dir import CURRENT_LINK, point_current, run_root, write_private_file
from slipstack.nodes.runtime.time_base import shifted_clock

__all__ = ["GRAPH_FILE", "INJECTION_REFUSED", "RUN_DIR_HELP", "write_graph", "read_graph", "find_run_dir", "topic_endpoints", "process_start_ticks",
           "register_tool", "time_base_clock"]

GRAPH_FILE = "graph.json"
INJECTION_REFUSED = ("slipstack/GripCommand", "slipstack/Slip", "slipstack/GripState")
"""Message types only the graph's own nodes publish: the grip commands, the slip verdicts and the
finger's report. A node gets no injection endpoint for an input of these types unless the launch
file names its topic in ``[launch] allow_inject`` (docs/safety.md)."""

PARAM_REPLY = "param-reply-"
"""``<run_dir>/param-reply-<tool pid>.json``: the launcher's answer to ``slipstack param set``,
``{"ok": bool, "message": str}``."""
_TOOL_GLOB = "tool-*.json"
MAX_TOOLS = 32  # live registered tools listed at most (by name)
RUN_DIR_ENV = "SLIPSTACK_RUN_DIR"
RUN_DIR_HELP = (f"run directory of the graph (default: ${RUN_DIR_ENV} if set, else the newest run, "
                f"$SLIPSTACK_RUN_ROOT/current; the run root defaults to /tmp/slipstack-<uid>)")
"""The ``--run-dir`` help of every tool: one wording for the two variables."""


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
        from slipstack.nodes.runtime.curve import use_keys  # zmq: only for a graph with keys

        machine = graph.get("machine") or {}
        use_keys(graph["keys"], machine.get("name"), machine.get("hosts"))
    for name, tool in _live_tools(run_dir):
        graph["nodes"].setdefault(name, tool)
    return graph


def _live_tools(run_dir: Path) -> list[tuple[str, dict[str, Any]]]:
    """``(name, node entry)`` of the registered tools whose process still runs."""
    out: list[tuple[str, dict[str, Any]]] = []
    for path in sorted(run_dir.glob(_TOOL_GLOB)):
        if len(out) >= MAX_TOOLS:
            break
        try:
            tool = json.loads(path.read_text())
            alive = process_start_ticks(int(tool["pid"])) == tool["start_ticks"]
            entry = {"type": str(tool["type"]), "pid": tool["pid"], "pub": str(tool["pub"]), "tool": True,
                     "inputs": {}, "outputs": {str(k): str(v) for k, v in dict(tool["outputs"]).items()},
                     "inject": {}, "restarts": 0}
        except (OSError, ValueError, KeyError, TypeError):
            continue  # removed meanwhile, or not one of ours
        if alive:
            out.append((path.stem.removeprefix("tool-"), entry))
    return out


def register_tool(run_dir: Path, name: str, pub: str, outputs: dict[str, str]) -> Path:
    """List a bus tool's publish endpoint ``pub`` (topics ``outputs``: topic → message type)
    in ``run_dir`` for the other tools and the recorder; returns the file to remove at exit
    (a file left by a killed tool is ignored: its process is gone)."""
    pid = os.getpid()
    doc = {"type": name.split("-")[0], "pid": pid, "start_ticks": process_start_ticks(pid), "pub": pub,
           "outputs": outputs}
    return write_private_file(run_dir, f"tool-{name}.json", json.dumps(doc))


def topic_endpoints(graph: dict[str, Any]) -> dict[str, list[str]]:
    """Topic → endpoints of the nodes publishing it (``diagnostics``: every node)."""
    out: dict[str, list[str]] = {}
    for node in graph["nodes"].values():
        if not node.get("pub"):
            continue
        for topic in node["outputs"]:  # includes "diagnostics": every node publishes it
            out.setdefault(topic, []).append(node["pub"])
    return out


def time_base_clock(graph: dict[str, Any]) -> Callable[[], int]:
    """The clock (ns) of the graph's nodes on this machine: its monotonic clock plus the offset
    to the first machine's (``machine.clock_offset_ns``; 0 on one machine), nodes/runtime/time_base.py.
    A tool that stamps or judges ages runs on it (the process executor's ``clock``)."""
    return shifted_clock(int((graph.get("machine") or {}).get("clock_offset_ns", 0)))
