"""Shell completion of the ``slipstack`` command (argcomplete).

``slipstack completion bash`` (or ``zsh``, ``fish``) prints the script to load once,
e.g. ``eval "$(slipstack completion bash)"`` in ``~/.bashrc``. The shell then calls
``slipstack`` with argcomplete's environment (``_ARGCOMPLETE``, ``COMP_LINE``); the
command builds only the parser of the command being typed (:func:`complete`), so a
completion costs what ``slipstack --help`` does, and argcomplete is imported only then.
Completed: commands, verbs and options; shipped launch files (``launch/launcher.py``);
the running graph's topics (``nodes/tools/topic_tools.py``).
"""

from __future__ import annotations

import argparse
import os
import shlex
from typing import Callable

__all__ = ["add_parser", "complete", "COMPLETION_ENV", "SHELLS"]

COMPLETION_ENV = "_ARGCOMPLETE"
SHELLS = ("bash", "zsh", "fish")


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("completion", help="print the shell completion script",
                       description='Print the script that makes the shell complete slipstack commands; load it '
                                   'with eval "$(slipstack completion bash)" (e.g. in ~/.bashrc).')
    p.add_argument("shell", nargs="?", default="bash", choices=SHELLS, help="the shell (default bash)")
    p.set_defaults(func=main_completion)


def main_completion(args: argparse.Namespace) -> int:
    import argcomplete

    print(argcomplete.shellcode(["slipstack"], shell=args.shell))
    return 0


def complete(build_parser: Callable[[list[str]], argparse.ArgumentParser]) -> None:
    """Answer the shell's completion request (then exit); return at once if there is none."""
    if COMPLETION_ENV not in os.environ:
        return
    import argcomplete

    line = os.environ.get("COMP_LINE", "")
    typed = line[: int(os.environ.get("COMP_POINT", len(line)))]
    try:
        words = shlex.split(typed)[1:]
    except ValueError:  # an open quote
        words = typed.split()[1:]
    argcomplete.autocomplete(build_parser(words))
