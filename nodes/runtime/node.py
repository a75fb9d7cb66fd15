"""The node model: named inputs and outputs, one handler per input, parameters.

A node is executor-agnostic: the same object runs in the process executor
(ZeroMQ, wall clock) and the in-process executor (no sockets, simulated clock).
Handlers read time only from ``ctx.now_ns()``.

Declaring a node::

More in docs/modules.md, `nodes/runtime/node.py`.
"""

from __future__ import annotations

import dataclasses
import typing
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol

from slipstack.lib.config import read_typed
from slipstack.lib.errors import ConfigError
from slipstack.lib.toml_file import toml_value
from slipstack.messages import Message

__all__ = ["INPUT_POLICIES", "Input", "Output", "Node", "Context", "IoSource", "NoParams", "make_params", "param_help"]

INPUT_POLICIES = ("latest", "queue", "batch")
"""How an input hands its messages to the handler (:class:`Input`)."""


@dataclass(frozen=True)
class Input:
    """A subscription.

    topic: default topic name (a launch file may remap it).
    type: message type expected; other types are rejected and counted.
    policy: ``latest`` (drain to the newest, count the skipped ones as dropped — for
        control data), ``queue`` (handle every message, one call each, bounded by
        ``depth``) or ``batch`` (one call per wake-up with every valid message queued
        since the last one, oldest first, as a tuple: ``on_<input>(self, msgs, ctx)``;
        at most ``depth`` of them, the older overflow counted as dropped — for a fast
        sensor stream whose every sample matters at the wake-up rate).
    """

    topic: str
    type: type[Message]
    policy: str = "latest"
    depth: int = 100

    def __post_init__(self) -> None:
        if self.policy not in INPUT_POLICIES:
            raise ConfigError(f"input policy must be one of {', '.join(INPUT_POLICIES)}, got {self.policy!r}")
        if self.depth < 1:
            raise ConfigError(f"input depth must be >= 1, got {self.depth!r}")


@dataclass(frozen=True)
class Output:
    """A publication: default topic name and message type."""

    topic: str
    type: type[Message]


class Context(Protocol):
    """What an executor gives a handler."""

    sender: str
    """Who sent the message being handled: "" for the graph's own nodes, else the name the tool
    that injected it gave (``topic_pub-1234``; "inject" if it gave none)."""

    def now_ns(self) -> int:
        """Executor time in integer nanoseconds (monotonic or simulated)."""

    def input_topic(self, input_name: str) -> str:
        """The topic the named input listens to in this graph (its default name unless remapped)."""

    def publish(self, output: str, msg: Message, *, stamp_ns: int, sources: dict[str, int] | None = None) -> None:
        """Publish ``msg`` on the named output; the executor fills the header."""

    def publish_raw(self, topic: str, payload: bytes) -> None:
        """Send an encoded frame as is (header included); for bus tools such as the player."""

    def count(self, name: str, increment: int = 1) -> None:
        """Add to a node-specific counter reported on ``diagnostics``."""

    def set_status(self, status: str, detail: str = "") -> None:
        """Set the node's status string reported on ``diagnostics``."""

    def log(self, text: str) -> None:
        """Write one log line (the launcher prefixes it with the node name)."""

    def report_error(self, text: str) -> None:
        """Say what went wrong: ``last_error`` on ``diagnostics`` and one log line."""

    def shutdown(self) -> None:
        """Ask the executor to stop this node after the current handler (e.g. a scene ended)."""


class IoSource(Protocol):
    """A file descriptor a node wants watched (serial port, UDP socket)."""

    def fileno(self) -> int: ...


@dataclass(frozen=True)
class NoParams:
    """A node without parameters."""


class Node:
    """Base class of all nodes; subclasses declare the class attributes below."""

    name: ClassVar[str] = "node"
    inputs: ClassVar[dict[str, Input]] = {}
    outputs: ClassVar[dict[str, Output]] = {}
    timers: ClassVar[dict[str, float]] = {}
    precise_timers: ClassVar[bool] = False
    """True for a timer-paced source (the rig): sleep to the exact tick, deaf to input
    for under a millisecond; otherwise the executor rounds timer wake-ups up to the
    next millisecond and never stops listening."""
    outlives_graph: ClassVar[bool] = False
    """True for a node that records or sums up the others (recorder, monitor): a launch stops
    it after every other process, and gives it time to finish (launch/launcher.py)."""
    Params: ClassVar[type] = NoParams

    def __init__(self, params: Any = None) -> None:
        self.params = params if params is not None else self.Params()

    def start(self, ctx: Context) -> None:
        """Called once before the first message (open devices here)."""

    def stop(self, ctx: Context) -> None:
        """Called once on shutdown (close devices here)."""

    def io_sources(self) -> list[IoSource]:
        """Descriptors to watch now; ``on_readable(source, ctx)`` is called when one is readable.

        Asked again on every loop turn, so a device that reconnects on a new descriptor
        is picked up; keep it cheap.
        """
        return []

    def on_readable(self, source: IoSource, ctx: Context) -> None:
        """Handle a readable descriptor returned by :meth:`io_sources`."""

    def next_deadline_ns(self) -> int | None:
        """Executor time (ns) at which :meth:`on_deadline` must run, or ``None``.

        Asked after every callback: a one-shot wake-up (a stale limit, a watchdog,
        a reconnect back-off) without a periodic timer waking the process for nothing.
        """
        return None

    def on_deadline(self, ctx: Context) -> None:
        """Called once the time from :meth:`next_deadline_ns` has come; must move or
        clear that deadline (the executor asks again right after)."""


def make_params(params_cls: type, values: dict[str, Any], node_name: str = "node") -> Any:
    """Build a params dataclass from loose values (launch file, ``name:=value``).

    Raises:
        ConfigError: an unknown name (listing the known ones), a missing required one
            (with its help text) or an unreadable value.
    """
    hints = typing.get_type_hints(params_cls)
    known = {f.name for f in dataclasses.fields(params_cls)}
    unknown = sorted(set(values) - known)
    if unknown:
        raise ConfigError(
            f"{node_name}: unknown parameter(s) {', '.join(unknown)}; known: {', '.join(sorted(known)) or 'none'}"
        )
    missing = [f for f in dataclasses.fields(params_cls) if f.name not in values
               and f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
    if missing:
        f = missing[0]
        about = f" ({f.metadata['help']})" if f.metadata.get("help") else ""
        raise ConfigError(f"{node_name}: missing parameter {f.name}{about}; give it as {f.name}:=VALUE "
                          "(or in the node's params in the launch file)")
    coerced = {k: read_typed(v, hints[k], f"{node_name}.{k}") for k, v in values.items()}
    try:
        return params_cls(**coerced)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{node_name}: {exc}") from None


def param_help(params_cls: type) -> list[tuple[str, str, str, str]]:
    """Rows ``(name, type, default, help)`` for ``--help`` output (the default as TOML writes it)."""
    hints = typing.get_type_hints(params_cls)
    rows = []
    for f in dataclasses.fields(params_cls):
        default = toml_value(f.default) if f.default is not dataclasses.MISSING else (
            toml_value(f.default_factory()) if f.default_factory is not dataclasses.MISSING else "(required)"
        )
        hint = hints[f.name]
        type_name = getattr(hint, "__name__", str(hint).replace("typing.", ""))
        rows.append((f.name, type_name, default, f.metadata.get("help", "")))
    return rows
