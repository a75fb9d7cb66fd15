"""``slipstack launch``: its arguments, their shell completion, and the start of a run.

The launcher and the lock-step run are imported only when a graph is launched, so that
``launch --help`` and the completion of ``name:=value`` start without the node stack.
"""

from __future__ import annotations

import argparse
import os
import re
from pathlib import Path
from typing import Any

from slipstack.launch.launch_file import PORT_ARGS, SIM_ARG

__all__ = ["add_parser", "main_launch", "complete_arguments"]

_CHOICES = re.compile(r"[\w-]+(?:\s*\|\s*[\w-]+)+")
"""An argument's comment lists its values as ``a | b | c`` (launch/files/stack.toml)."""
_BUILTIN_ARGS = ("run_dir", *PORT_ARGS, "stamp", SIM_ARG)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "launch", help="run a graph (default: the simulated rig and the full stack)",
        description="Run a graph of nodes from a TOML launch file; name:=value sets launch arguments "
                    "(--show-args lists them; the shell completes them, see `slipstack completion`).",
    )
    p.add_argument("file", nargs="?", help="launch file (path or shipped name); default: the default graph"
                   ).completer = _complete_file  # type: ignore[attr-defined]
    p.add_argument("assignments", nargs="*", metavar="name:=value", help="launch argument overrides"
                   ).completer = complete_arguments  # type: ignore[attr-defined]
    p.add_argument("--show-args", action="store_true",
                   help="print the launch arguments with their values and comments, and exit")
    p.add_argument("--lockstep", action="store_true",
                   help="run every node in this process on the simulated clock, the rig in lock-step with the "
                        "stack: faster than real time and repeatable bit for bit (simulated devices only; "
                        "a graph over machines runs every machine's nodes here)")
    p.add_argument("--machine", metavar="NAME",
                   help="run the share of machine NAME of a graph with [machines.NAME] tables (run the "
                        "same file and arguments on every machine, each with its own NAME)")
    p.add_argument("--log-level", metavar="LEVEL[,NODE=LEVEL]", default="",
                   help="least level of the node log lines shown and kept: debug, info (default), warning, "
                        "error; for every node, then per node, e.g. warning,ft_driver=debug")
    p.add_argument("--log-file", metavar="PATH",
                   help="keep every line printed here (default: beside the recording, runs/<stamp>.log; "
                        "none when nothing is recorded)")
    p.set_defaults(func=main_launch)


def _complete_file(prefix: str, parsed_args: argparse.Namespace, **_: object) -> list[str]:
    """The launch file: a shipped one by name (``fig15``), or an argument of the default graph."""
    from slipstack.launch.launch_file import launch_files_dir

    if ":=" in prefix:
        return complete_arguments(prefix, parsed_args)
    files = sorted(p.stem for p in launch_files_dir().glob("*.toml"))
    return [f for f in files if f.startswith(prefix)] + complete_arguments(prefix, parsed_args)


def complete_arguments(prefix: str, parsed_args: argparse.Namespace, **_: object) -> list[str]:
    """``name:=`` for the launch file's arguments; after ``name:=``, its values: the default, true
    and false for a flag, the shipped scenes and materials, the ``a | b`` its comment lists."""
    from slipstack.launch.launch_file import arg_comments, declared_args, default_launch_file
    from slipstack.lib.errors import ConfigError
    from slipstack.lib.toml_file import resolve_path

    file = getattr(parsed_args, "file", None)
    try:
        path = (resolve_path(file, Path.cwd(), "files") if file and ":=" not in file else default_launch_file())
        args = declared_args(path)
    except (ConfigError, OSError):
        return []
    name, sep, typed = prefix.partition(":=")
    if not sep:
        return [f"{n}:=" for n in args if n.startswith(prefix) and n not in _BUILTIN_ARGS]
    if name not in args:
        return []
    values = _values(name, args[name], arg_comments(path).get(name, ""))
    return [f"{name}:={v}" for v in values if v.startswith(typed)]


def _values(name: str, default: Any, comment: str) -> list[str]:
    from slipstack.launch.launch_file import launch_files_dir

    if isinstance(default, bool):
        return ["true", "false"]
    shipped = launch_files_dir().parent
    folder = {"scene": "scenes", "material": "materials", "rig_material": "materials"}.get(name)
    listed = _CHOICES.search(comment)
    values = [str(default)] if default not in ("", None) and not isinstance(default, list) else []
    if folder is not None:
        values += sorted(p.stem for p in (shipped / folder).glob("*.toml"))
    if listed is not None:
        values += [v.strip() for v in listed.group(0).split("|")]
    return list(dict.fromkeys(values))


def main_launch(args: argparse.Namespace) -> int:
    from slipstack.launch.launch_file import arg_comments, load_launch_file
    from slipstack.launch.launcher import Launcher, run_lockstep
    from slipstack.launch.run_log import log_path_for
    from slipstack.launch.run_node import parse_assignments
    from slipstack.lib.errors import ConfigError
    from slipstack.lib.toml_file import toml_value
    from slipstack.nodes.devices.sim_link import SIM_PREFIX
    from slipstack.nodes.runtime.logs import LOG_LEVEL_ENV, parse_log_levels
    from slipstack.nodes.runtime.run_dir import make_run_dir, remove_run_dir

    parse_log_levels(args.log_level)  # a bad level fails before anything starts
    if args.log_level:
        os.environ[LOG_LEVEL_ENV] = args.log_level  # the node processes inherit it
    positional = list(args.assignments)
    file = args.file
    if file is not None and ":=" in file:  # `slipstack launch name:=value` with the default file
        positional.insert(0, file)
        file = None
    run_dir = make_run_dir()
    try:
        builtins = {"run_dir": str(run_dir), SIM_ARG: SIM_PREFIX if args.lockstep else ""}
        launch = load_launch_file(file, parse_assignments(positional), builtins=builtins)
        if args.show_args:
            comments = arg_comments(launch.path)
            for name, value in launch.args.items():
                if name not in _BUILTIN_ARGS:
                    note = f"  # {comments[name]}" if name in comments else ""
                    print(f"{name} := {toml_value(value)}{note}")
            remove_run_dir(run_dir)
            return 0
        log_file = Path(args.log_file) if args.log_file else log_path_for(launch)
        if args.lockstep:
            if args.machine is not None:
                raise ConfigError("--lockstep runs every machine's nodes in this one process; "
                                  "drop --machine (or drop --lockstep to run one machine's share)")
            return run_lockstep(launch, run_dir, log_file=log_file)
        launcher = Launcher(launch, run_dir, log_file=log_file, machine=args.machine)
    except BaseException:  # a bad launch file leaves no run directory behind
        remove_run_dir(run_dir)
        raise
    return launcher.run()
