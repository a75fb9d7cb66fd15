"""ZeroMQ transport details: endpoints and socket options (run directories: ``nodes/run_dir``).

Frames are multipart ``[topic, msgpack payload]``. Each publishing node binds one
XPUB socket (verbose, so it sees every subscription and can wait for its
subscribers: the readiness handshake against slow joiners); each input connects
one SUB socket to every endpoint that publishes its topic.

More in docs/modules.md, `nodes/runtime/transport.py`.
"""

from __future__ import annotations

import json
import os
import socket
from pathlib import Path

import zmq

from slipstack.lib.errors import ConfigError
from slipstack.messages.codec import MAX_PAYLOAD_BYTES
from slipstack.nodes.runtime.curve import secure_bind, secure_connect
from slipstack.nodes.runtime.run_dir import RUN_ROOT_ENV, make_run_dir, run_root

__all__ = [
    "make_run_dir", "ipc_endpoint", "make_pub", "make_sub", "bound_socket", "RUN_ROOT_ENV", "run_root",
    "MAX_SUBSCRIPTION_BYTES", "SUBSCRIPTION_HWM", "MAX_ORIGIN_BYTES", "tcp_endpoint",
    "machine_ports", "listening_socket", "LISTEN_FDS_ENV", "HANDSHAKE_MS",
]

IPC_PATH_MAX = 107  # Linux sun_path limit (libzmq zmq_ipc)

MAX_ORIGIN_BYTES = 64
"""Longest sender name an injected ``[topic, payload, origin]`` frame may carry (bytes, UTF-8);
longer ones are cut."""


def ipc_endpoint(run_dir: Path, name: str, *, bound: bool = True) -> str:
    """The ``ipc://`` endpoint of node ``name`` inside ``run_dir``.

    Raises:
        ConfigError: if the path exceeds the 107-character limit of Linux and a socket will be
            ``bound`` to it (a lock-step plan binds none).
    """
    path = str(run_dir / f"{name}.pub")
    if bound and len(path) > IPC_PATH_MAX:
        raise ConfigError(
            f"ipc path {path} is {len(path)} characters; Linux allows {IPC_PATH_MAX}. "
            f"Set {RUN_ROOT_ENV} to a shorter directory."
        )
    return f"ipc://{path}"


def tcp_endpoint(address: str, port: int) -> str:
    """``tcp://ADDRESS:PORT`` (an IPv6 address in brackets)."""
    return f"tcp://[{address}]:{port}" if ":" in address else f"tcp://{address}:{port}"


def machine_ports(first: int, node_names: list[str]) -> dict[str, int]:
    """The tcp port of each node of one machine of a graph: ``first`` is its launcher's,
    then one per node in order of name. Every launcher of the graph computes the same
    ports from the same launch file, so none has to ask another where a node listens."""
    return {name: first + 1 + k for k, name in enumerate(sorted(node_names))}


MAX_SUBSCRIPTION_BYTES = 1024
"""Longest frame an XPUB accepts from a peer: a subscription (one byte and a topic prefix)."""
SUBSCRIPTION_HWM = 1000
"""Queued (un)subscriptions, each direction."""
HANDSHAKE_MS = 10_000
"""A connection whose handshake (ZMTP, CURVE) is not done within this is closed (ZeroMQ's default,
30 s, let silent connections pile up: 5000 held for 35 s took 2900 descriptors; 3 s was too
short for a CURVE handshake with a launcher at nice 5 on a machine at load 13)."""
LISTEN_FDS_ENV = "SLIPSTACK_LISTEN_FDS"
"""JSON ``{endpoint: descriptor}``: listening tcp sockets a node process inherits from its launcher."""
LISTEN_BACKLOG = 100  # ZeroMQ's own default


def listening_socket(endpoint: str) -> socket.socket:
    """A tcp socket bound to ``endpoint`` (``tcp://HOST:PORT``) and listening, inheritable: the
    launcher holds one per tcp port of its nodes for the whole launch, and a node's socket takes
    it over (ZMQ_USE_FD), so after a crash nothing else can take the port before the node is back.

    Raises:
        OSError: the address cannot be bound (EADDRINUSE: another process holds it).
    """
    host, _, port = endpoint[len("tcp://"):].rpartition(":")
    host = host.strip("[]")
    sock = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_STREAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as ZeroMQ's own bind does
        sock.bind((host, int(port)))
        sock.listen(LISTEN_BACKLOG)
    except BaseException:
        sock.close()
        raise
    sock.set_inheritable(True)
    return sock


def _inherited_listen_fd(endpoint: str) -> int | None:
    """The descriptor of the listening socket the launcher holds for ``endpoint``, if any."""
    try:
        fd = json.loads(os.environ.get(LISTEN_FDS_ENV, "{}")).get(endpoint)
    except (ValueError, AttributeError):
        return None
    return fd if isinstance(fd, int) else None


def bound_socket(ctx: zmq.Context, kind: int, *, sndhwm: int, rcvhwm: int, max_msg_bytes: int) -> zmq.Socket:
    """A new socket with both high-water marks (frames), a maximum inbound frame size
    (bytes; a peer sending more is disconnected), a handshake time limit and no linger."""
    sock = ctx.socket(kind)
    sock.setsockopt(zmq.LINGER, 0)
    sock.setsockopt(zmq.HANDSHAKE_IVL, HANDSHAKE_MS)
    sock.setsockopt(zmq.SNDHWM, sndhwm)
    sock.setsockopt(zmq.RCVHWM, rcvhwm)
    sock.setsockopt(zmq.MAXMSGSIZE, max_msg_bytes)
    return sock


def make_pub(ctx: zmq.Context, endpoint: str, *, sndhwm: int = 1000, unsubscriptions: bool = False,
             remote: str | None = None) -> zmq.Socket:
    """Bind a verbose XPUB socket (subscriptions are visible for the handshake); CURVE on tcp.

    ``unsubscriptions``: also pass on every unsubscription, a departing subscriber's
    included (XPUB_VERBOSER), so counting them gives the subscribers present now.
    ``remote``: a tcp endpoint bound as well, for subscribers on other machines; ``endpoint``
    is bound first, so an ipc endpoint stays without CURVE (ZeroMQ takes the security
    options of a socket at each bind).
    """
    sock = bound_socket(ctx, zmq.XPUB, sndhwm=sndhwm, rcvhwm=SUBSCRIPTION_HWM, max_msg_bytes=MAX_SUBSCRIPTION_BYTES)
    sock.setsockopt(zmq.XPUB_VERBOSER if unsubscriptions else zmq.XPUB_VERBOSE, 1)
    for ep in (endpoint, remote) if remote else (endpoint,):
        secure_bind(sock, ep)
        fd = _inherited_listen_fd(ep)
        if fd is not None:
            sock.setsockopt(zmq.USE_FD, fd)
        sock.bind(ep)
        sock.setsockopt(zmq.USE_FD, -1)
    return sock


def make_sub(ctx: zmq.Context, endpoints: list[str], topic: str | None, *, rcvhwm: int = 1000) -> zmq.Socket:
    """Connect a SUB socket to ``endpoints``, subscribed to ``topic`` (all if ``None``); CURVE on tcp."""
    sock = bound_socket(ctx, zmq.SUB, sndhwm=SUBSCRIPTION_HWM, rcvhwm=rcvhwm, max_msg_bytes=MAX_PAYLOAD_BYTES)
    sock.setsockopt(zmq.RECONNECT_IVL, 20)
    sock.setsockopt(zmq.RECONNECT_IVL_MAX, 200)
    sock.setsockopt(zmq.SUBSCRIBE, b"" if topic is None else topic.encode())
    for ep in endpoints:
        secure_connect(sock, ep)
        sock.connect(ep)
    return sock
