"""The ``slipstack`` command: launch graphs, run nodes, inspect topics, record and play."""

from __future__ import annotations

import argparse
import sys

from slipstack.lib.errors import SlipstackError

__all__ = ["main", "build_parser"]


def build_parser() -> argparse.ArgumentParser:
    from slipstack.launch import launcher, run_node

    parser = argparse.ArgumentParser(
        prog="slipstack",
        description="Slip detection and control as a ZeroMQ node graph (after Melchiorri 2000).",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    launcher.add_parser(sub)
    run_node.add_parser(sub)
    for module in ("slipstack.nodes.topic_tools", "slipstack.nodes.bag_tools"):
        try:
            mod = __import__(module, fromlist=["add_parser"])
        except ImportError:
            continue
        mod.add_parser(sub)
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


if __name__ == "__main__":
    sys.exit(main())
