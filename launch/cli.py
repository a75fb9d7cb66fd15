"""The ``slipstack`` command: launch graphs, run nodes, inspect topics, record and play."""

from __future__ import annotations

import argparse
import atexit
import gc
import importlib
import sys

from slipstack.lib.errors import run_guarded

__all__ = ["main", "build_parser"]


# command → (module with ``add_parser(sub)``, one-line help). Only the module of the command
# being run is imported: ``slipstack --help`` and ``slipstack topic list`` start without
# numpy, scipy or the node types.
COMMANDS = {
    "launch": ("slipstack.launch.launch_command", "run a graph (default: the simulated rig and the full stack)"),
    "run": ("slipstack.launch.run_node", "run one node as a process"),
    "topic": ("slipstack.nodes.tools.topic_tools", "inspect and poke the running graph's topics"),
    "node": ("slipstack.nodes.tools.node_tools", "list the running graph's nodes, or one node's state"),
    "param": ("slipstack.nodes.tools.param_tools", "a running node's parameters: list, get, set (restarts its process)"),
    "bag": ("slipstack.nodes.tools.bag_tools", "record, play, inspect and export recordings (MCAP)"),
    "report": ("slipstack.analysis.report", "paper-style figure or friction identification of a recording"),
    "identify": ("slipstack.analysis.identify_cli", "a material file (friction and thresholds) from friction ramps"),
    "reproduce": ("slipstack.analysis.reproduce", "run the paper's experiments in lock-step and draw its figures"),
    "keys": ("slipstack.launch.keys_cli", "make the key pair a graph's tcp links need"),
    "completion": ("slipstack.launch.completion", "print the shell completion script (bash, zsh, fish)"),
}


class _Version(argparse.Action):
    """``--version``: the installed package's version, looked up only when asked."""

    def __init__(self, option_strings: list[str], dest: str = argparse.SUPPRESS, help: str | None = None) -> None:
        super().__init__(option_strings, dest=dest, default=argparse.SUPPRESS, nargs=0, help=help)

    def __call__(self, parser: argparse.ArgumentParser, namespace: argparse.Namespace, values: object,
                 option_string: str | None = None) -> None:
        from importlib.metadata import PackageNotFoundError, version

        try:
            text = version("slipstack")
        except PackageNotFoundError:  # a source tree that was never installed
            text = "(not installed)"
        print(f"slipstack {text}")
        parser.exit()


def build_parser(argv: list[str] | None = None) -> argparse.ArgumentParser:
    """The ``slipstack`` parser; the command named in ``argv`` gets its full parser, the
    others only their name and help (``argv`` ``None``: every command in full)."""
    parser = argparse.ArgumentParser(
        prog="slipstack",
        description="Slip detection and control as a ZeroMQ node graph (after Melchiorri 2000).",
    )
    parser.add_argument("--version", action=_Version, help="print the installed version and exit")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    words = [a for a in (argv or []) if not a.startswith("-")]
    chosen = set(COMMANDS) if argv is None else {w for w in words[:1] if w in COMMANDS}
    for name, (module, help_text) in COMMANDS.items():
        if name in chosen:
            importlib.import_module(module).add_parser(sub)
        else:
            sub.add_parser(name, help=help_text)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command in ``argv`` (default: the process's arguments); its exit code."""
    from slipstack.launch.completion import complete
    from slipstack.nodes.runtime.stop_signal import stop_on_signals

    if argv is None:
        # Ctrl-C and SIGTERM stop the command from its first line: a tool started in the background
        # by a script inherits SIGINT ignored, and lost it until its own handling was in place
        # (0.2-0.8 s of imports). The launcher and the node executor take the signals over later.
        stop_on_signals()
        # The command is the whole process: when it ends, its objects die with it. Freezing them
        # spares the interpreter's last garbage collection over every one of them (0.08 s after
        # a lock-step run, of 0.11 s of exit). Files are closed by the code that opened them.
        atexit.register(gc.freeze)
    try:
        complete(build_parser)  # the shell asking for completions: answered, then exits
        argv = sys.argv[1:] if argv is None else argv
        parser = build_parser(argv)  # imports the command's module
        args, extra = parser.parse_known_args(argv)
    except KeyboardInterrupt:  # a stop before the command runs: nothing was done
        return 130
    # `name:=value` may follow options (`run rig --pub X a:=1`): argparse leaves those over
    assignments = [e for e in extra if ":=" in e and not e.startswith("-")]
    if len(assignments) != len(extra) or (assignments and not hasattr(args, "assignments")):
        parser.error(f"unrecognized arguments: {' '.join(e for e in extra if e not in assignments) or ' '.join(extra)}")
    if assignments:
        args.assignments.extend(assignments)
    return run_guarded(args.command, lambda: args.func(args))



if __name__ == "__main__":
    sys.exit(main())
