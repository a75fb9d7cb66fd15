"""``slipstack keys DIR [--machine NAME ...]``: key pairs for a graph's tcp links (ZeroMQ CURVE, nodes/runtime/curve.py)."""

from __future__ import annotations

import argparse

from slipstack.nodes.runtime.curve import make_keys, make_machine_keys

__all__ = ["add_parser", "main_keys"]


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "keys", help="make the key pair a graph's tcp links need",
        description="Make DIR (mode 0700) with the graph's CURVE key pair: graph.key (public) and "
                    "graph.key_secret (keep it private). Name DIR in the launch file as [launch] keys = \"DIR\"; "
                    "every tcp link of that graph then admits only holders of these keys. Copy the directory "
                    "to every machine of the graph. With --machine (once per [machines.NAME] of the launch "
                    "file): one directory DIR/NAME per machine, with its own key pair and the public keys of "
                    "the others; copy each machine only its own directory and name it in [machines.NAME] keys.")
    p.add_argument("dir", help="directory to create the key pair(s) in")
    p.add_argument("--machine", action="append", default=[], metavar="NAME",
                   help="a machine of the graph (repeat for each): a key pair per machine in DIR/NAME")
    p.set_defaults(func=main_keys)


def main_keys(args: argparse.Namespace) -> int:
    if args.machine:
        dirs = make_machine_keys(args.dir, args.machine)
        for d, name in zip(dirs, args.machine):
            print(f"wrote {d}: copy it to machine {name} and set [machines.{name}] keys = \"{d}\" (path there)")
        return 0
    public, secret = make_keys(args.dir)
    print(f"wrote {public} and {secret}; set [launch] keys = \"{args.dir}\" in your launch file")
    return 0
