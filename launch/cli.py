"""The ``slipstack`` command: launch graphs, run nodes, inspect topics, record and play."""

from __future__ import annotations

import argparse
import sys

from slipstack.lib.errors import SlipstackError

__all__ = ["main", "build_parser"]


def build_parser() -> argparse.ArgumentParser:
    from slipstack.launch import launcher, run_node
    from slipstack.nodes import bag_tools, topic_tools

    parser = argparse.ArgumentParser(
        prog="slipstack",
        description="Slip detection and control as a ZeroMQ node graph (after Melchiorri 2000).",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for module in (launcher, run_node, topic_tools, bag_tools):
        module.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except SlipstackError as exc:
        print(f"slipstack {args.command}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:  # output piped into `head` and closed: not an error
        sys.stderr.close()
        return 0


if __name__ == "__main__":
    sys.exit(main())
