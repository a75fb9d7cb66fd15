"""Node log lines through stdlib :mod:`logging`, with levels set per node.

A node writes ``ctx.log(text)``; the line's level follows its prefix, the convention the
nodes already use: ``error: …`` (what :meth:`Context.report_error` writes) is ERROR,
``warning: …`` WARNING, ``debug: …`` DEBUG, anything else INFO. Each node logs to the
logger ``slipstack.node.<name>``; one handler writes the bare line to stderr, where the
launcher prefixes it with ``[<name>]`` and keeps it in the run's log file.

More in docs/modules.md, `nodes/runtime/logs.py`.
"""

from __future__ import annotations

import logging
import os
import sys
from typing import Callable

from slipstack.lib.errors import ConfigError

__all__ = ["LOG_LEVEL_ENV", "DETAIL_PREFIX", "LEVELS", "parse_log_levels", "configure_logging", "node_log", "level_of"]

LOG_LEVEL_ENV = "SLIPSTACK_LOG_LEVEL"
DETAIL_PREFIX = "detail: "
"""A line kept in the run's log file but not shown on the terminal (the summary's long form)."""
LEVELS = ("debug", "info", "warning", "error", "critical")
_PREFIXES = (("error:", logging.ERROR), ("warning:", logging.WARNING), ("debug:", logging.DEBUG))
_ROOT = "slipstack.node"


def parse_log_levels(spec: str) -> tuple[int, dict[str, int]]:
    """``"warning,ft_driver=debug"`` → (the level for every node, {node: its own level}).

    Raises:
        ConfigError: an unknown level name, naming the known ones.
    """
    default, per_node = logging.INFO, {}
    for item in (s.strip() for s in spec.split(",")):
        if not item:
            continue
        node, _, name = item.rpartition("=")
        if name.lower() not in LEVELS:
            raise ConfigError(f"--log-level: unknown level {name!r} in {spec!r}; use one of {', '.join(LEVELS)}, "
                              "for every node or as NODE=LEVEL (e.g. warning,ft_driver=debug)")
        level = logging.getLevelName(name.upper())
        if node:
            per_node[node] = level
        else:
            default = level
    return default, per_node


def configure_logging(spec: str | None = None) -> None:
    """Set up the node loggers of this process from ``spec`` (default: :data:`LOG_LEVEL_ENV`)."""
    default, per_node = parse_log_levels(spec if spec is not None else os.environ.get(LOG_LEVEL_ENV, ""))
    root = logging.getLogger(_ROOT)
    root.setLevel(default)
    root.propagate = False
    if not root.handlers:
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("%(message)s"))
        root.addHandler(handler)
    for node, level in per_node.items():
        logging.getLogger(f"{_ROOT}.{node}").setLevel(level)


def level_of(text: str) -> int:
    """The level of a log line by its prefix (module docstring)."""
    for prefix, level in _PREFIXES:
        if text.startswith(prefix):
            return level
    return logging.INFO


def node_log(name: str, prefix: str = "") -> Callable[[str], None]:
    """The log function of node ``name``: each line at :func:`level_of` its text, with
    ``prefix`` in front (a container's members name themselves). In a process that has
    not configured logging (a tool running a node: ``bag record``, ``bag play``) the
    levels come from :data:`LOG_LEVEL_ENV`, so its info lines are not lost."""
    if not logging.getLogger(_ROOT).handlers:
        configure_logging()
    logger = logging.getLogger(f"{_ROOT}.{name}")

    def log(text: str) -> None:
        level = level_of(text)
        if logger.isEnabledFor(level):
            logger.log(level, prefix + text)

    return log
