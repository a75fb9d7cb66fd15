"""Launch files (TOML): which nodes, their parameters, remappings, respawn policy.

Format::

More in docs/modules.md, `launch/launch_file.py`.
"""



from __future__ import annotations

import math
import re
import socket
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from slipstack.lib.config import read_flag, read_number
from slipstack.lib.errors import ConfigError
from slipstack.lib.toml_file import loads as toml_loads, resolve_path

if TYPE_CHECKING:  # the node types are imported when a launch is loaded: `launch --help` and completion start lean
    from slipstack.nodes.runtime.node import Node

__all__ = ["NodeEntry", "LaunchFile", "load_launch_file", "default_launch_file", "launch_files_dir", "free_port",
           "CHECK_ARG", "SIM_ARG", "PORT_ARGS", "arg_comments", "declared_args"]

_SUBST = re.compile(r"\$\((\w+)\)")
_IDENTIFIER = re.compile(r"[A-Za-z0-9_-]+")
_NAMESPACE = re.compile(r"[A-Za-z0-9_-]+(/[A-Za-z0-9_-]+)*")
_TOP_KEYS = {"launch", "args", "node", "machines"}
_MACHINE_KEYS = {"address", "ports", "keys", "nodes"}
DEFAULT_PORTS = (24700, 24799)
"""tcp ports of a machine without ``ports``: the first for its launcher, then one per node; the
last two are its launcher's too: its clock offsets on ``diagnostics``, and the injection of tools
on other machines into its nodes (below Linux's ephemeral ports, 32768-60999, which outgoing connections may hold)."""
_LAUNCH_KEYS = {"description", "duration_s", "extends", "check", "keys", "insecure", "allow_inject"}
_NODE_KEYS = {"name", "type", "params", "remap", "namespace", "respawn", "respawn_delay_s", "respawn_max_retries",
              "respawn_reset_s", "respawn_standby", "required", "transport", "enabled", "after", "nice",
              "realtime_priority", "container", "stop_first", "machine"}
SUBST_MAX_CHARS = 65536
"""Longest value an argument substitution may produce (a guard against self-doubling arguments)."""
SUBST_MAX_DEPTH = 32
"""Longest chain of arguments referring to arguments."""
SIM_ARG = "sim"
"""Built-in argument: ``"sim:"`` in a lock-step launch (``--lockstep``), else ``""``; written before a
device URL or emulator address, it names the simulated device (``nodes/devices/sim_link.py``)."""
PORT_ARGS = {"free_udp_port": socket.SOCK_DGRAM, "free_udp_port_2": socket.SOCK_DGRAM, "free_tcp_port": socket.SOCK_STREAM}
"""Built-in arguments: a port free on 127.0.0.1 when the file is loaded, by kind (the UDP ones differ)."""
CHECK_ARG = "check"
"""``check:=true`` on the command line sets ``[launch] check`` when the file declares no such argument."""


@dataclass
class NodeEntry:
    """One node instance of a launch file, with its parameters resolved."""

    name: str
    type: str
    cls: type[Node]
    params: dict[str, Any] = field(default_factory=dict)
    remap: dict[str, str] = field(default_factory=dict)
    respawn: bool = False
    respawn_delay_s: float = 0.05
    """Wait (s) before the first restart; each further restart waits twice as long as the one before."""
    respawn_max_retries: int = 3
    respawn_reset_s: float = 10.0
    """A process that stayed up this long (s) gets its full restart budget back."""
    respawn_standby: bool = True
    """Keep a warm standby process for this one (a restart then takes about 0.1 s instead of 1-4 s)."""
    required: bool = False
    transport: str = "ipc"
    after: list[str] = field(default_factory=list)
    nice: int = 0
    realtime_priority: int = 0
    """``SCHED_FIFO`` priority (1-99) of its process; 0: normal scheduling (``launch/priority.py``)."""
    container: str = ""
    """Nodes naming the same container run in one process ("": a process of its own)."""
    stop_first: bool = False
    """Stopped before every other node on Ctrl-C/SIGTERM (the simulated world, which must
    not run on without the controller)."""
    machine: str = ""
    """The ``[machines]`` entry that runs it ("" in a graph without machines)."""

    def process_policy(self) -> tuple:
        """The settings that belong to the process, which a container's members must share."""
        return (self.respawn, self.respawn_delay_s, self.respawn_max_retries, self.respawn_reset_s,
                self.respawn_standby, self.required, self.transport, self.nice, self.realtime_priority, self.stop_first,
                self.machine)

    def instance(self, **options: Any) -> Node:
        """Build the node object (validates the parameters); ``options``: the node class's own keywords."""
        from slipstack.nodes.runtime.node import make_params

        return self.cls(make_params(self.cls.Params, self.params, self.name), **options)

    def output_topics(self, node: Node) -> dict[str, str]:
        return {n: self.remap.get(o.topic, o.topic) for n, o in node.outputs.items()}

    def input_topics(self, node: Node) -> dict[str, str]:
        return {n: self.remap.get(i.topic, i.topic) for n, i in node.inputs.items()}


@dataclass(frozen=True)
class Machine:
    """One computer of a graph spread over several (``[machines.NAME]``)."""

    name: str
    address: str
    """IP address or host name its tcp endpoints bind and its peers connect to."""
    ports: tuple[int, int]
    """First and last tcp port it uses: the first for its launcher, then one per node (by name)."""
    keys: Path | None
    """Its key directory: its key pair ``NAME.key_secret`` and the public keys it admits."""

    @property
    def is_loopback(self) -> bool:
        """True if the address is this computer's loopback (127.0.0.0/8, ::1, localhost)."""
        return self.address == "localhost" or self.address == "::1" or self.address.startswith("127.")


@dataclass
class LaunchFile:
    path: Path
    description: str
    duration_s: float
    args: dict[str, Any]
    nodes: list[NodeEntry]
    check: bool = False
    """Exit 1 at the end unless the run passed (``<run_dir>/check.json``, no node died and stayed down)."""
    keys: Path | None = None
    """Key directory of the graph's tcp links (``slipstack keys DIR``; nodes/runtime/curve.py)."""
    insecure: bool = False
    """tcp links without CURVE, explicitly allowed."""
    machines: dict[str, Machine] = field(default_factory=dict)
    """The computers the graph spans (empty: all on this one), in file order."""
    allow_inject: tuple[str, ...] = ()
    """Topics of a type tools may not inject (``INJECTION_REFUSED``) that this launch lets them inject."""


def launch_files_dir() -> Path:
    """The folder of the launch files shipped with slipstack."""
    return Path(__file__).parent / "files"


def default_launch_file() -> Path:
    """The graph ``slipstack launch`` runs with no file."""
    return launch_files_dir() / "default.toml"


def _substitute(value: Any, lookup: Callable[[str], Any], where: str) -> Any:
    """``value`` with every ``$(name)`` replaced by ``lookup(name)`` (in tables and lists too)."""
    if isinstance(value, dict):
        return {k: _substitute(v, lookup, f"{where}.{k}") for k, v in value.items()}
    if isinstance(value, list):
        return [_substitute(v, lookup, where) for v in value]
    if not isinstance(value, str):
        return value
    whole = _SUBST.fullmatch(value)
    if whole:
        return lookup(whole.group(1))
    text = _SUBST.sub(lambda m: str(lookup(m.group(1))), value)
    if len(text) > SUBST_MAX_CHARS:
        raise ConfigError(f"{where}: substituting the launch arguments gives {len(text)} characters "
                          f"(more than {SUBST_MAX_CHARS}); does an argument repeat itself?")
    return text


def _resolve_args(args: dict[str, Any], file: str) -> dict[str, Any]:
    """Every argument with the ``$(other)`` references in it replaced (each resolved once).

    Raises:
        ConfigError: an argument refers to itself (directly or through others), names an
            undeclared argument, nests deeper than ``SUBST_MAX_DEPTH`` or grows past
            ``SUBST_MAX_CHARS``.
    """
    done: dict[str, Any] = {}

    def resolve(name: str, chain: tuple[str, ...]) -> Any:
        if name in done:
            return done[name]
        if name not in args:
            raise ConfigError(f"{file}: args.{chain[-1]}: unknown launch argument $({name}); "
                              f"declared: {', '.join(sorted(args))}")
        if name in chain:
            raise ConfigError(f"{file}: launch argument {name} refers to itself: "
                              f"{' -> '.join((*chain[chain.index(name):], name))}")
        if len(chain) >= SUBST_MAX_DEPTH:
            raise ConfigError(f"{file}: launch arguments nest deeper than {SUBST_MAX_DEPTH}: {' -> '.join(chain)}")
        done[name] = _substitute(args[name], lambda other: resolve(other, (*chain, name)), f"{file}: args.{name}")
        return done[name]

    return {name: resolve(name, ()) for name in args}


def _typed_override(default: Any, text: str, name: str, endless: bool = False) -> Any:
    """A launch argument given as ``name:=text``, read as the type of its declared ``default``
    (finite, unless ``endless``: the argument is the launch's duration, which may be inf)."""
    where = f"launch argument {name}"
    if isinstance(default, bool):
        return read_flag(text, where)
    if isinstance(default, list):  # "[a, b]", "a,b" or "" (empty list)
        items = text.strip().removeprefix("[").removesuffix("]")
        return [item.strip().strip("'\"") for item in items.split(",") if item.strip()]
    if isinstance(default, (int, float)):
        return read_number(text, where, type(default), finite=not endless)
    return text


def _identifier(value: Any, where: str) -> str:
    """A node or container name: letters, digits, ``_`` and ``-`` (it names files in the run directory)."""
    if not isinstance(value, str) or not _IDENTIFIER.fullmatch(value):
        raise ConfigError(f"{where} must be letters, digits, _ and - only (it names files in the run directory); "
                          f"got {value!r}")
    return value


def _table(value: Any, where: str) -> dict:
    if not isinstance(value, dict):
        raise ConfigError(f"{where} must be a table ({{ key = value, ... }}); got {value!r}")
    return value


def _names(value: Any, where: str) -> list[str]:
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise ConfigError(f"{where} must be a list of node names; got {value!r}")
    return value


_ARG_LINE = re.compile(r"\s*([A-Za-z_][\w-]*)\s*=")


def arg_comments(path: Path) -> dict[str, str]:
    """The comment of each ``[args]`` entry of a launch file and the files it extends
    (the file's own comment wins): the ``# ...`` after the value, else the comment lines
    right above it; indented comment lines right below continue it. For ``--show-args``;
    a file that does not parse gives what it can."""
    text = path.read_text()
    comments: dict[str, str] = {}
    above: list[str] = []
    section, last = "", ""  # last: the argument an indented comment line continues
    for line in text.splitlines():
        stripped = line.strip()
        if stripped.startswith("["):
            section, above, last = stripped, [], ""
            continue
        if stripped.startswith("#"):
            if last and line[0].isspace():
                comments[last] = (comments.get(last, "") + " " + stripped.lstrip("#").strip()).strip()
            else:
                above.append(stripped.lstrip("#").strip())
                last = ""
            continue
        m = _ARG_LINE.match(line)
        last = ""
        if section == "[args]" and m:
            inline = next((line[i + 1:].strip() for i in range(len(line)) if line[i] == "#"
                           and _parses(line[:i])), "")
            if inline or above:
                comments[m.group(1)] = inline or " ".join(above)
            last = m.group(1)
        above = []
    try:
        base_name = toml_loads(text).get("launch", {}).get("extends")
    except tomllib.TOMLDecodeError:
        base_name = None
    if isinstance(base_name, str):
        try:
            return {**arg_comments(resolve_path(base_name, path.parent, "files")), **comments}
        except (ConfigError, OSError):
            pass
    return comments


def _parses(toml_line: str) -> bool:
    """True if ``toml_line`` is a whole ``key = value`` (so a ``#`` after it starts a comment)."""
    try:
        toml_loads(toml_line)
    except tomllib.TOMLDecodeError:
        return False
    return True



def _free_ports() -> dict[str, int]:
    """:data:`PORT_ARGS`, each a port free now; the UDP ones are held open together so they differ."""
    socks = []
    try:
        for kind in PORT_ARGS.values():
            s = socket.socket(socket.AF_INET, kind)
            socks.append(s)
            s.bind(("127.0.0.1", 0))
        return {name: s.getsockname()[1] for name, s in zip(PORT_ARGS, socks)}
    finally:
        for s in socks:
            s.close()


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    """A port free on 127.0.0.1 now (TCP by default, UDP with ``socket.SOCK_DGRAM``)."""
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _parse_toml(p: Path) -> dict[str, Any]:
    """The TOML of ``p``; ConfigError ``FILE:LINE: what is wrong`` if it is not valid TOML."""
    try:
        text = p.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{p}: cannot read it ({exc})") from None
    try:
        return toml_loads(text)
    except tomllib.TOMLDecodeError as exc:
        message = str(exc)
        at = re.search(r" \(at line (\d+), column (\d+)\)$", message)
        place = f"{p}:{at.group(1)}:{at.group(2)}" if at else str(p)
        raise ConfigError(f"{place}: not valid TOML: {message[:at.start()] if at else message}") from None


def _read_with_base(p: Path, seen: tuple[Path, ...]) -> dict[str, Any]:
    """The TOML of ``p`` merged over the file it ``extends`` (recursively)."""
    if p in seen:
        raise ConfigError(f"{p.name}: 'extends' loops back to itself: {' -> '.join(s.name for s in (*seen, p))}")
    data = _parse_toml(p)
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise ConfigError(f"{p}: unknown section(s) {sorted(unknown)}; allowed: [launch], [args], [[node]], "
                          "[machines.NAME]")
    meta = dict(_table(data.get("launch", {}), f"{p}: [launch]"))
    unknown = set(meta) - _LAUNCH_KEYS
    if unknown:
        raise ConfigError(f"{p}: [launch]: unknown key(s) {sorted(unknown)}; allowed: {sorted(_LAUNCH_KEYS)}")
    _table(data.get("args", {}), f"{p}: [args]")
    for name, machine in _table(data.get("machines", {}), f"{p}: [machines]").items():
        unknown = set(_table(machine, f"{p}: [machines.{name}]")) - _MACHINE_KEYS
        if unknown:
            raise ConfigError(f"{p}: [machines.{name}]: unknown key(s) {sorted(unknown)}; "
                              f"allowed: {sorted(_MACHINE_KEYS)}")
    nodes = data.get("node", [])
    if not isinstance(nodes, list) or not all(isinstance(n, dict) for n in nodes):
        raise ConfigError(f"{p}: 'node' must be an array of tables ([[node]] sections)")
    base_name = meta.pop("extends", None)
    if base_name is None:
        return data
    if not isinstance(base_name, str):
        raise ConfigError(f"{p}: [launch] extends must be a file name; got {base_name!r}")
    base = _read_with_base(resolve_path(base_name, p.parent, "files"), (*seen, p))
    return {
        "launch": {**base.get("launch", {}), **meta},
        "args": {**base.get("args", {}), **data.get("args", {})},
        "node": [*base.get("node", []), *nodes],
        "machines": {**base.get("machines", {}), **data.get("machines", {})},
    }


def declared_args(path: Path) -> dict[str, Any]:
    """The ``[args]`` of a launch file and the files it extends, as written (not substituted)."""
    return dict(_read_with_base(path, seen=()).get("args", {}))


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
                "respawn, respawn_delay_s, respawn_max_retries, respawn_reset_s, respawn_standby, required, "
                "transport, nice, realtime_priority, stop_first or machine; make them equal"
            )


def _declared_topics(cls: type[Node]) -> set[str]:
    """The default topics of a node type's inputs and outputs (what a namespace prefixes)."""
    return {i.topic for i in cls.inputs.values()} | {o.topic for o in cls.outputs.values()}


def _node_entry(raw: dict[str, Any], where: str) -> NodeEntry | None:
    """The entry of one substituted ``[[node]]`` table; None if it is not enabled."""
    from slipstack.nodes.catalog import node_class

    if not read_flag(raw.get("enabled", True), f"{where}.enabled"):
        return None
    if "type" not in raw:
        raise ConfigError(f"{where}: missing 'type' (a node type from `slipstack run --help`)")
    if not isinstance(raw["type"], str):
        raise ConfigError(f"{where}.type must be a node type name; got {raw['type']!r}")
    name = _identifier(raw.get("name", raw["type"]), f"{where}.name")
    where = f"{where} ({name})"
    transport = raw.get("transport", "ipc")
    if transport not in ("ipc", "tcp"):
        raise ConfigError(f"{where}.transport must be 'ipc' or 'tcp'; got {transport!r}")
    container = raw.get("container", "")
    remap = _table(raw.get("remap", {}), f"{where}.remap")
    if not all(isinstance(v, str) for v in remap.values()):
        raise ConfigError(f"{where}.remap maps topic names to topic names; got {remap!r}")
    namespace = raw.get("namespace", "")
    if namespace:
        if not isinstance(namespace, str) or not _NAMESPACE.fullmatch(namespace):
            raise ConfigError(f"{where}.namespace must be words of letters, digits, _ and - joined by /, "
                              f"e.g. \"finger0\"; got {namespace!r}")
        cls = node_class(raw["type"])
        remap = {**{t: f"{namespace}/{t}" for t in _declared_topics(cls)}, **remap}
    params = _table(raw.get("params", {}), f"{where}.params")
    return NodeEntry(
        name=name, type=raw["type"], cls=node_class(raw["type"]), params=dict(params), remap=dict(remap), respawn=read_flag(raw.get("respawn", False), f"{where}.respawn"),
        respawn_delay_s=read_number(raw.get("respawn_delay_s", NodeEntry.respawn_delay_s), f"{where}.respawn_delay_s", lo=0),
        respawn_max_retries=read_number(raw.get("respawn_max_retries", NodeEntry.respawn_max_retries),
                                        f"{where}.respawn_max_retries", int, lo=0),
        respawn_reset_s=read_number(raw.get("respawn_reset_s", NodeEntry.respawn_reset_s), f"{where}.respawn_reset_s", lo=0),
        respawn_standby=read_flag(raw.get("respawn_standby", True), f"{where}.respawn_standby"),
        required=read_flag(raw.get("required", False), f"{where}.required"), transport=transport,
        after=list(_names(raw.get("after", []), f"{where}.after")),
        nice=read_number(raw.get("nice", 0), f"{where}.nice", int, lo=-20),
        realtime_priority=read_number(raw.get("realtime_priority", 0), f"{where}.realtime_priority", int, lo=0, hi=99),
        container=_identifier(container, f"{where}.container") if container else "",
        stop_first=read_flag(raw.get("stop_first", False), f"{where}.stop_first"),
        machine=_identifier(raw["machine"], f"{where}.machine") if raw.get("machine") else "",
    )


def load_launch_file(
    path: str | Path | None, overrides: dict[str, str] | None = None, *, builtins: dict[str, Any] | None = None
) -> LaunchFile:
    """Read and validate a launch file; ``overrides`` are ``name:=value`` arguments.

    ``builtins`` are arguments the launcher provides (``run_dir``: this run's private
    directory, for device links and recordings); a file cannot override them.
    ``free_udp_port``, ``free_udp_port_2``, ``free_tcp_port`` (ports free now), ``stamp`` (the local date-time,
    ``YYYYmmdd-HHMMSS``) and ``sim`` (:data:`SIM_ARG`, ``""`` unless given) are always provided.

    Raises:
        ConfigError: naming the file and key that is wrong.
    """
    p = default_launch_file() if path is None else resolve_path(str(path), Path.cwd(), "files")
    data = _read_with_base(p, seen=())
    args = dict(data.get("args", {}))
    overrides = dict(overrides or {})
    check_override = overrides.pop(CHECK_ARG) if CHECK_ARG in overrides and CHECK_ARG not in args else None
    duration = _SUBST.fullmatch(str(data.get("launch", {}).get("duration_s", "")))
    for name, text in overrides.items():
        if name not in args:
            raise ConfigError(f"{p.name}: no launch argument {name!r}; declared: {', '.join(sorted(args)) or 'none'}")
        args[name] = _typed_override(args[name], text, name, endless=duration is not None and duration[1] == name)
    args.update({**_free_ports(), "stamp": time.strftime("%Y%m%d-%H%M%S"), SIM_ARG: "", **(builtins or {})})
    # an argument may refer to others ("rdt://127.0.0.1:$(rdt_port)", "$(run_dir)/ft.tty"),
    # which may refer to others again
    args = _resolve_args(args, p.name)

    def lookup(name: str) -> Any:
        if name not in args:
            raise ConfigError(f"{p.name}: unknown launch argument $({name}); declared: {', '.join(sorted(args))}")
        return args[name]

    meta = _substitute(data.get("launch", {}), lookup, f"{p.name}: [launch]")
    entries: list[NodeEntry] = []
    for k, raw in enumerate(data.get("node", [])):
        where = f"{p.name}: node[{k}]"
        unknown = set(raw) - _NODE_KEYS
        if unknown:
            raise ConfigError(f"{where}: unknown key(s) {sorted(unknown)}; allowed: {sorted(_NODE_KEYS)}")
        entry = _node_entry(_substitute(raw, lookup, where), where)
        if entry is not None:
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
    machines = _machines(p, _substitute(data.get("machines", {}), lookup, f"{p.name}: [machines]"), meta, entries)
    _check_containers(p.name, entries)
    check = meta.get("check", False) if check_override is None else _typed_override(False, check_override, CHECK_ARG)
    keys, insecure = _tcp_security(p, meta, entries, machines)
    duration_s = read_number(meta.get("duration_s", 0), f"{p.name}: duration_s", lo=0, finite=False)
    if math.isnan(duration_s):
        raise ConfigError(f"{p.name}: duration_s must be a number of seconds >= 0 or inf, got nan")
    return LaunchFile(p, str(meta.get("description", "")), duration_s,
                      args, entries, read_flag(check, f"{p.name}: [launch] check"), keys, insecure, machines,
                      _allow_inject(p.name, meta.get("allow_inject", []), entries))


def _allow_inject(file: str, value: Any, entries: list[NodeEntry]) -> tuple[str, ...]:
    """``[launch] allow_inject``: topics a node of the launch subscribes to."""
    subscribed = {t for e in entries for t in e.input_topics(e.instance()).values()}
    if not (isinstance(value, list) and all(isinstance(t, str) for t in value)):
        raise ConfigError(f"{file}: [launch] allow_inject must be a list of topic names, got {value!r}")
    unknown = sorted(set(value) - subscribed)
    if unknown:
        raise ConfigError(f"{file}: [launch] allow_inject names {unknown}, which no node of this launch subscribes "
                          f"to; subscribed: {', '.join(sorted(subscribed))}")
    return tuple(sorted(set(value)))


def _port_range(value: Any, where: str) -> tuple[int, int]:
    """``[first, last]`` tcp ports, 1024 < first <= last < 65536."""
    if (not isinstance(value, list) or len(value) != 2
            or not all(isinstance(v, int) and not isinstance(v, bool) for v in value)
            or not 1024 < value[0] <= value[1] < 65536):
        raise ConfigError(f"{where} must be [first, last] tcp ports with 1024 < first <= last < 65536; got {value!r}")
    return value[0], value[1]


def _machines(p: Path, tables: dict[str, Any], meta: dict[str, Any], entries: list[NodeEntry]) -> dict[str, Machine]:
    """The ``[machines.NAME]`` tables, with every node placed on one of them (its ``machine`` key,
    else the machine whose ``nodes`` lists it, else the first machine)."""
    if not tables:
        placed = [e.name for e in entries if e.machine]
        if placed:
            raise ConfigError(f"{p.name}: nodes {placed} name a machine, but the file declares no [machines.NAME]")
        return {}
    default_keys = meta.get("keys", "")
    machines: dict[str, Machine] = {}
    listed: dict[str, str] = {}
    names = {e.name for e in entries}
    for name, t in tables.items():
        where = f"{p.name}: [machines.{_identifier(name, f'{p.name}: [machines] name')}]"
        address = t.get("address")
        if not isinstance(address, str) or not address.strip() or any(c in address for c in "/:[] "):
            raise ConfigError(f"{where}.address must be the machine's IP address or host name, e.g. \"10.0.0.2\"; "
                              f"got {address!r}")
        keys = t.get("keys", f"{default_keys}/{name}" if default_keys else "")
        if not isinstance(keys, str):
            raise ConfigError(f"{where}.keys must be a directory path; got {keys!r}")
        machines[name] = Machine(name, address, _port_range(t.get("ports", list(DEFAULT_PORTS)), f"{where}.ports"),
                                 (p.parent / Path(keys).expanduser()).resolve() if keys else None)
        for node in _names(t.get("nodes", []), f"{where}.nodes"):
            if node not in names:
                continue  # a node the file leaves out of this run (enabled = false)
            if node in listed:
                raise ConfigError(f"{where}.nodes: {node} is also listed by [machines.{listed[node]}]")
            listed[node] = name
    first = next(iter(machines))
    for e in entries:
        if e.machine and e.name in listed and listed[e.name] != e.machine:
            raise ConfigError(f"{p.name}: node {e.name} says machine = {e.machine!r}, "
                              f"[machines.{listed[e.name]}] lists it too; keep one")
        e.machine = e.machine or listed.get(e.name, first)
        if e.machine not in machines:
            raise ConfigError(f"{p.name}: node {e.name}: no [machines.{e.machine}]; machines: {', '.join(machines)}")
    ordered = sorted(machines.values(), key=lambda m: (m.address, m.ports))
    for a, b in zip(ordered, ordered[1:]):
        if a.address == b.address and b.ports[0] <= a.ports[1]:
            raise ConfigError(f"{p.name}: machines {a.name} and {b.name} share address {a.address} and overlap in "
                              "ports; give them disjoint ports = [first, last]")
    for m in machines.values():
        needed = 3 + sum(1 for e in entries if e.machine == m.name)
        if m.ports[1] - m.ports[0] + 1 < needed:
            raise ConfigError(f"{p.name}: [machines.{m.name}].ports {list(m.ports)} holds "
                              f"{m.ports[1] - m.ports[0] + 1} ports; it needs {needed} (its launcher's first and last two, one per node)")
    return machines


def _tcp_security(p: Path, meta: dict[str, Any], entries: list[NodeEntry],
                  machines: dict[str, Machine]) -> tuple[Path | None, bool]:
    """``[launch] keys`` (a key directory, relative to the launch file) and ``insecure``;
    a graph with tcp links (``transport = "tcp"`` or machines) needs one of them, and a
    machine on a non-loopback address needs keys or ``insecure`` (nodes/runtime/curve.py)."""
    insecure = read_flag(meta.get("insecure", False), f"{p.name}: [launch] insecure")
    raw = meta.get("keys", "")
    if not isinstance(raw, str):
        raise ConfigError(f"{p.name}: [launch] keys must be a directory path; got {raw!r}")
    keys = (p.parent / Path(raw).expanduser()).resolve() if raw else None
    if machines:
        unkeyed = [m for m in machines.values() if m.keys is None]
        if unkeyed and not insecure:
            remote = [m.name for m in unkeyed if not m.is_loopback]
            what = (f"machines {remote} are on the network" if remote
                    else f"machines {[m.name for m in unkeyed]} link over tcp")
            names = " ".join(f"--machine {m}" for m in machines)
            raise ConfigError(f"{p.name}: {what} without keys: run `slipstack keys DIR {names}` and set "
                              "[machines.NAME] keys = \"DIR/NAME\" (copy each machine its directory), "
                              "or insecure = true to let anyone who reaches those ports connect")
        return keys, insecure
    if keys is not None:
        from slipstack.nodes.runtime.curve import GraphKeys

        GraphKeys.load(keys)  # fail now with how to make them
    tcp = [e.name for e in entries if e.transport == "tcp"]
    if tcp and keys is None and not insecure:
        raise ConfigError(f"{p.name}: nodes {tcp} use transport tcp, which needs keys: run `slipstack keys DIR` and "
                          "set [launch] keys = \"DIR\" (or insecure = true to let anyone on the network connect)")
    return keys, insecure
