"""Ports for tests that bind tcp or udp: chosen free at run time, never fixed, so two suites
(or two tests) on one host do not collide."""

from __future__ import annotations

import random
import socket

__all__ = ["free_port", "free_port_block"]

_BELOW_EPHEMERAL = (20000, 32000)
"""Where blocks are taken from: below Linux's ephemeral range (32768-60999), which the
outgoing side of every tcp connection draws from, so a node's own connects cannot take a
port of the block before the node that binds it starts."""


def free_port(kind: int = socket.SOCK_STREAM, host: str = "127.0.0.1") -> int:
    """A port the kernel says is free on ``host`` right now (tcp, or udp with SOCK_DGRAM)."""
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind((host, 0))
        return s.getsockname()[1]


def _free(port: int, hosts: tuple[str, ...]) -> bool:
    for host in hosts:
        for kind in (socket.SOCK_STREAM, socket.SOCK_DGRAM):
            with socket.socket(socket.AF_INET, kind) as s:
                try:
                    s.bind((host, port))
                except OSError:
                    return False
    return True


def free_port_block(n: int, hosts: tuple[str, ...] = ("127.0.0.1",)) -> int:
    """The first of ``n`` consecutive ports free on every one of ``hosts`` (tcp and udp), for a
    launch file's ``ports = [first, first + n - 1]``."""
    for _ in range(200):
        first = random.randrange(_BELOW_EPHEMERAL[0], _BELOW_EPHEMERAL[1] - n)
        if all(_free(p, hosts) for p in range(first, first + n)):
            return first
    raise RuntimeError(f"no {n} consecutive free ports in {_BELOW_EPHEMERAL} on {hosts}")
