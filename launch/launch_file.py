"""Launch files (TOML): which nodes, their parameters, remappings, respawn policy.

Format::

    [launch]
    description = "what this graph does"
    duration_s = 0            # stop by itself after this long (0: run until Ctrl-C)
    extends = "stack.toml"    # optional: take the nodes and args of another launch
                              # file; this file's [args] override, its nodes are added

    [args]                    # launch arguments, overridden by `name:=value`
    rate_hz = 1000.0          # built in: $(run_dir), this run's private directory, and
                              # $(free_udp_port), a UDP port free on 127.0.0.1 now,
                              # $(stamp), the date-time the launch started

    [[node]]
    name = "source"           # instance name (unique); topics/logs use it
    type = "wrench_source"    # a node type from `slipstack run --help`
    params = { rate_hz = "$(rate_hz)" }   # "$(arg)" is replaced by a launch argument
    remap = { "ft/wrench" = "ft/raw" }    # default topic -> topic in this graph
    respawn = false           # restart it when it dies
    respawn_delay_s = 0.5
    respawn_max_retries = 3
    required = false          # when it exits, the whole launch stops
    transport = "ipc"         # or "tcp" (binds 127.0.0.1 on a free port)
    enabled = true            # may be "$(arg)": leave a node out of this run
    after = ["rig"]           # start only once these nodes are ready (besides the
                              # topic order: subscribers before publishers)
    nice = -5                 # scheduling priority (needs the privilege to raise it;
                              # without it the node runs at normal priority)

A value that is exactly ``"$(name)"`` takes the argument's type; inside a longer
string it is substituted as text.
"""

from __future__ import annotations

import re
import socket
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from slipstack.lib.errors import ConfigError
from slipstack.nodes.catalog import node_class
from slipstack.nodes.node import Node, make_params

__all__ = ["NodeEntry", "LaunchFile", "load_launch_file", "default_launch_file", "launch_files_dir", "free_port"]

_SUBST = re.compile(r"\$\((\w+)\)")
_NODE_KEYS = {"name", "type", "params", "remap", "respawn", "respawn_delay_s", "respawn_max_retries",
              "required", "transport", "enabled", "after", "nice", "container", "stop_first"}


@dataclass
class NodeEntry:
    """One node instance of a launch file, with its parameters resolved."""

    name: str
    type: str
    cls: type[Node]
    params: dict[str, Any] = field(default_factory=dict)
    remap: dict[str, str] = field(default_factory=dict)
    respawn: bool = False
    respawn_delay_s: float = 0.5
    respawn_max_retries: int = 3
    required: bool = False
    transport: str = "ipc"
    after: list[str] = field(default_factory=list)
    nice: int = 0
    container: str = ""
    """Nodes naming the same container run in one process ("": a process of its own)."""
    stop_first: bool = False
    """Stopped before every other node on Ctrl-C/SIGTERM (the simulated world, which must
    not run on without the controller)."""

    def process_policy(self) -> tuple:
        """The settings that belong to the process, which a container's members must share."""
        return (self.respawn, self.respawn_delay_s, self.respawn_max_retries, self.required, self.transport, self.nice,
                self.stop_first)

    def instance(self) -> Node:
        """Build the node object (validates the parameters)."""
        return self.cls(make_params(self.cls.Params, self.params, self.name))

    def output_topics(self, node: Node) -> dict[str, str]:
        return {n: self.remap.get(o.topic, o.topic) for n, o in node.outputs.items()}

    def input_topics(self, node: Node) -> dict[str, str]:
        return {n: self.remap.get(i.topic, i.topic) for n, i in node.inputs.items()}


@dataclass
class LaunchFile:
    path: Path
    description: str
    duration_s: float
    args: dict[str, Any]
    nodes: list[NodeEntry]


def launch_files_dir() -> Path:
    """The folder of the launch files shipped with slipstack."""
    return Path(__file__).parent / "files"


def default_launch_file() -> Path:
    """The graph ``slipstack launch`` runs with no file."""
    return launch_files_dir() / "default.toml"


def _substitute(value: Any, args: dict[str, Any], where: str) -> Any:
    if isinstance(value, dict):
        return {k: _substitute(v, args, f"{where}.{k}") for k, v in value.items()}
    if isinstance(value, list):
        return [_substitute(v, args, where) for v in value]
    if not isinstance(value, str):
        return value

    def lookup(name: str) -> Any:
        if name not in args:
            raise ConfigError(f"{where}: unknown launch argument $({name}); declared: {', '.join(sorted(args)) or 'none'}")
        return args[name]

    whole = _SUBST.fullmatch(value)
    if whole:
        return lookup(whole.group(1))
    return _SUBST.sub(lambda m: str(lookup(m.group(1))), value)


def _typed_override(default: Any, text: str, name: str) -> Any:
    if isinstance(default, bool):
        if text.lower() in ("true", "1", "yes", "on"):
            return True
        if text.lower() in ("false", "0", "no", "off"):
            return False
        raise ConfigError(f"launch argument {name} is a bool; got {text!r}")
    if isinstance(default, list):  # "[a, b]", "a,b" or "" (empty list)
        items = text.strip().removeprefix("[").removesuffix("]")
        return [item.strip().strip("'\"") for item in items.split(",") if item.strip()]
    if isinstance(default, (int, float)):
        try:
            return type(default)(text)
        except ValueError:
            raise ConfigError(f"launch argument {name} is a {type(default).__name__}; got {text!r}") from None
    return text


def resolve_path(value: str, base: Path, folder: str) -> Path:
    """Resolve a file named in a launch file: as given, next to it, or a shipped name."""
    for cand in (Path(value), base / value, Path(__file__).parent / folder / value,
                 Path(__file__).parent / folder / f"{value}.toml"):
        if cand.is_file():
            return cand.resolve()
    raise ConfigError(f"cannot find {value!r} (looked next to {base} and in the shipped {folder}/)")


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    """A port free on 127.0.0.1 now (TCP by default, UDP with ``socket.SOCK_DGRAM``)."""
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _read_with_base(p: Path, seen: tuple[Path, ...]) -> dict[str, Any]:
    """The TOML of ``p`` merged over the file it ``extends`` (recursively)."""
    if p in seen:
        raise ConfigError(f"{p.name}: 'extends' loops back to itself")
    try:
        data = tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML ({exc})") from None
    meta = dict(data.get("launch", {}))
    base_name = meta.pop("extends", None)
    if base_name is None:
        return data
    base = _read_with_base(resolve_path(str(base_name), p.parent, "files"), (*seen, p))
    return {
        "launch": {**base.get("launch", {}), **meta},
        "args": {**base.get("args", {}), **data.get("args", {})},
        "node": [*base.get("node", []), *data.get("node", [])],
    }


def _check_containers(file: str, entries: list[NodeEntry]) -> None:
    """A container's members share one process, so they must agree on its settings."""
    names = {e.name for e in entries}
    first: dict[str, NodeEntry] = {}
    for e in entries:
        if not e.container:
            continue
        if e.container in names:
            raise ConfigError(f"{file}: container {e.container!r} has the name of a node; name it differently")
        lead = first.setdefault(e.container, e)
        if e.process_policy() != lead.process_policy():
            raise ConfigError(
                f"{file}: nodes {lead.name} and {e.name} share container {e.container!r} but differ in "
                "respawn, respawn_delay_s, respawn_max_retries, required, transport, nice or stop_first; "
                "make them equal"
            )


def load_launch_file(
    path: str | Path | None, overrides: dict[str, str] | None = None, *, builtins: dict[str, Any] | None = None
) -> LaunchFile:
    """Read and validate a launch file; ``overrides`` are ``name:=value`` arguments.

    ``builtins`` are arguments the launcher provides (``run_dir``: this run's private
    directory, for device links and recordings); a file cannot override them.
    ``free_udp_port`` (a UDP port free now) and ``stamp`` (the local date-time,
    ``YYYYmmdd-HHMMSS``) are always provided.

    Raises:
        ConfigError: naming the file and key that is wrong.
    """
    p = default_launch_file() if path is None else resolve_path(str(path), Path.cwd(), "files")
    data = _read_with_base(p, seen=())
    args = dict(data.get("args", {}))
    for name, text in (overrides or {}).items():
        if name not in args:
            raise ConfigError(f"{p.name}: no launch argument {name!r}; declared: {', '.join(sorted(args)) or 'none'}")
        args[name] = _typed_override(args[name], text, name)
    args.update({"free_udp_port": free_port(socket.SOCK_DGRAM), "stamp": time.strftime("%Y%m%d-%H%M%S"),
                 **(builtins or {})})
    # an argument may refer to others ("rdt://127.0.0.1:$(rdt_port)", "$(run_dir)/ft.tty"),
    # which may refer to others again: resolve until nothing changes
    for _ in range(len(args)):
        resolved = {k: _substitute(v, args, f"{p.name}: args.{k}") for k, v in args.items()}
        if resolved == args:
            break
        args = resolved
    meta = data.get("launch", {})
    entries: list[NodeEntry] = []
    for k, raw in enumerate(data.get("node", [])):
        where = f"{p.name}: node[{k}]"
        unknown = set(raw) - _NODE_KEYS
        if unknown:
            raise ConfigError(f"{where}: unknown key(s) {sorted(unknown)}; allowed: {sorted(_NODE_KEYS)}")
        raw = _substitute(raw, args, where)
        if not raw.get("enabled", True):
            continue
        if "type" not in raw:
            raise ConfigError(f"{where}: missing 'type'")
        name = raw.get("name", raw["type"])
        if raw.get("transport", "ipc") not in ("ipc", "tcp"):
            raise ConfigError(f"{where}: transport must be 'ipc' or 'tcp'")
        entry = NodeEntry(
            name=name, type=raw["type"], cls=node_class(raw["type"]), params=dict(raw.get("params", {})),
            remap=dict(raw.get("remap", {})), respawn=bool(raw.get("respawn", False)),
            respawn_delay_s=float(raw.get("respawn_delay_s", 0.5)),
            respawn_max_retries=int(raw.get("respawn_max_retries", 3)),
            required=bool(raw.get("required", False)), transport=raw.get("transport", "ipc"),
            after=list(raw.get("after", [])), nice=int(raw.get("nice", 0)), container=str(raw.get("container", "")),
            stop_first=bool(raw.get("stop_first", False)),
        )
        entry.instance()  # fail now, naming the node, if a parameter is wrong
        entries.append(entry)
    names = [e.name for e in entries]
    dupes = {n for n in names if names.count(n) > 1}
    if dupes:
        raise ConfigError(f"{p.name}: node names must be unique; repeated: {sorted(dupes)}")
    for e in entries:
        missing = [a for a in e.after if a not in names]
        if missing:
            raise ConfigError(f"{p.name}: node {e.name} starts after {missing}, which this launch does not run")
    _check_containers(p.name, entries)
    return LaunchFile(p, str(meta.get("description", "")), float(_substitute(meta.get("duration_s", 0), args, "launch.duration_s")), args, entries)
