"""The ``slipstack`` command: launch graphs, run nodes, inspect topics, record and play."""

from __future__ import annotations

import argparse
import sys
from typing import Callable

from slipstack.lib.errors import SlipstackError

__all__ = ["main", "build_parser", "run_guarded"]


def build_parser() -> argparse.ArgumentParser:
    from slipstack.analysis import reproduce
    from slipstack.launch import keys_cli, launcher, run_node
    from slipstack.nodes import bag_tools, identify_cli, report, topic_tools

    parser = argparse.ArgumentParser(
        prog="slipstack",
        description="Slip detection and control as a ZeroMQ node graph (after Melchiorri 2000).",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in (launcher, run_node, topic_tools, bag_tools, report, identify_cli, reproduce, keys_cli):
        module.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    # `name:=value` may follow options (`run rig --pub X a:=1`): argparse leaves those over
    assignments = [e for e in extra if ":=" in e and not e.startswith("-")]
    if len(assignments) != len(extra) or (assignments and not hasattr(args, "assignments")):
        parser.error(f"unrecognized arguments: {' '.join(e for e in extra if e not in assignments) or ' '.join(extra)}")
    if assignments:
        args.assignments.extend(assignments)
    return run_guarded(args.command, lambda: args.func(args))


def run_guarded(command: str, func: Callable[[], int | None]) -> int:
    """The exit code of ``func()``; a SlipstackError becomes one line on stderr and exit 2."""
    try:
        return int(func() or 0)
    except SlipstackError as exc:
        print(f"slipstack {command}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # output piped into `head` and closed: not an error
        sys.stderr.close()
        return 0


if __name__ == "__main__":
    sys.exit(main())
