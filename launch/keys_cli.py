"""``slipstack keys DIR``: a key pair for a graph's tcp links (ZeroMQ CURVE, nodes/runtime/curve.py)."""

from __future__ import annotations

import argparse

from slipstack.nodes.runtime.curve import make_keys

__all__ = ["add_parser", "main_keys"]


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "keys", help="make the key pair a graph's tcp links need",
        description="Make DIR (mode 0700) with the graph's CURVE key pair: graph.key (public) and "
                    "graph.key_secret (keep it private). Name DIR in the launch file as [launch] keys = \"DIR\"; "
                    "every tcp link of that graph then admits only holders of these keys. Copy the directory "
                    "to every machine of the graph.")
    p.add_argument("dir", help="directory to create the key pair in")
    p.set_defaults(func=main_keys)


def main_keys(args: argparse.Namespace) -> int:
    public, secret = make_keys(args.dir)
    print(f"wrote {public} and {secret}; set [launch] keys = \"{args.dir}\" in your launch file")
    return 0
