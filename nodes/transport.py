"""ZeroMQ transport details: endpoints and socket options (run directories: ``nodes/run_dir``).

Frames are multipart ``[topic, msgpack payload]``. Each publishing node binds one
XPUB socket (verbose, so it sees every subscription and can wait for its
subscribers: the readiness handshake against slow joiners); each input connects
one SUB socket to every endpoint that publishes its topic.
"""

from __future__ import annotations

from pathlib import Path

import zmq

from slipstack.lib.errors import ConfigError
from slipstack.nodes.run_dir import RUN_ROOT_ENV, make_run_dir, run_root

__all__ = ["make_run_dir", "ipc_endpoint", "make_pub", "make_sub", "RUN_ROOT_ENV", "run_root"]

IPC_PATH_MAX = 107  # Linux sun_path limit (libzmq zmq_ipc)


def ipc_endpoint(run_dir: Path, name: str) -> str:
    """The ``ipc://`` endpoint of node ``name`` inside ``run_dir``.

    Raises:
        ConfigError: if the path exceeds the 107-character limit of Linux.
    """
    path = str(run_dir / f"{name}.pub")
    if len(path) > IPC_PATH_MAX:
        raise ConfigError(
            f"ipc path {path} is {len(path)} characters; Linux allows {IPC_PATH_MAX}. "
            f"Set {RUN_ROOT_ENV} to a shorter directory."
        )
    return f"ipc://{path}"


def make_pub(ctx: zmq.Context, endpoint: str, *, sndhwm: int = 1000) -> zmq.Socket:
    """Bind a verbose XPUB socket (subscriptions are visible for the handshake)."""
    sock = ctx.socket(zmq.XPUB)
    sock.setsockopt(zmq.LINGER, 0)
    sock.setsockopt(zmq.SNDHWM, sndhwm)
    sock.setsockopt(zmq.XPUB_VERBOSE, 1)
    sock.bind(endpoint)
    return sock


def make_sub(ctx: zmq.Context, endpoints: list[str], topic: str | None, *, rcvhwm: int = 1000) -> zmq.Socket:
    """Connect a SUB socket to ``endpoints``, subscribed to ``topic`` (all if ``None``)."""
    sock = ctx.socket(zmq.SUB)
    sock.setsockopt(zmq.LINGER, 0)
    sock.setsockopt(zmq.RCVHWM, rcvhwm)
    sock.setsockopt(zmq.RECONNECT_IVL, 20)
    sock.setsockopt(zmq.RECONNECT_IVL_MAX, 200)
    sock.setsockopt(zmq.SUBSCRIBE, b"" if topic is None else topic.encode())
    for ep in endpoints:
        sock.connect(ep)
    return sock
