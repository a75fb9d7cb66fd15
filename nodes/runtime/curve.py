"""ZeroMQ CURVE on every tcp link: only holders of the graph's keys publish, receive or inject.

A graph that uses ``transport = "tcp"`` names a key directory (``[launch] keys``,
made by ``slipstack keys DIR``). It holds the graph's key pair (``graph.key``,
``graph.key_secret``) and the public keys (``*.key``) of everyone allowed to connect.
Every socket that *binds* a tcp endpoint is a CURVE server: a ZAP authenticator
(``zmq.auth``) admits only clients whose public key is in the directory. Every socket
that *connects* to one is a CURVE client that checks the server's key, so a process
that grabs a freed port cannot pass itself off as a node. ipc endpoints are guarded by
the run directory's permissions (owner only, 0700) and stay as they are.

The launcher passes the directory to its processes in ``$SLIPSTACK_KEYS``; tools that
attach to a graph read it from ``graph.json``. ``insecure = true`` in the launch file
(``$SLIPSTACK_INSECURE=1`` for the processes) allows tcp without keys, explicitly.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import zmq
import zmq.auth
from zmq.auth.thread import ThreadAuthenticator

from slipstack.lib.errors import ConfigError

__all__ = ["KEYS_ENV", "INSECURE_ENV", "GraphKeys", "make_keys", "use_keys", "secure_bind", "secure_connect"]

KEYS_ENV = "SLIPSTACK_KEYS"
INSECURE_ENV = "SLIPSTACK_INSECURE"
KEY_NAME = "graph"


@dataclass(frozen=True)
class GraphKeys:
    """A graph's CURVE key pair (z85 bytes) and the directory of allowed public keys."""

    directory: Path
    public: bytes
    secret: bytes

    @classmethod
    def load(cls, directory: str | Path) -> GraphKeys:
        """Read ``DIR/graph.key_secret``; a clear error says how to make it."""
        d = Path(directory).expanduser().resolve()
        secret_file = d / f"{KEY_NAME}.key_secret"
        try:
            public, secret = zmq.auth.load_certificate(secret_file)
        except (OSError, ValueError) as exc:
            raise ConfigError(f"no usable key pair in {d} ({exc}); make one with `slipstack keys {d}`") from None
        if secret is None:
            raise ConfigError(f"{secret_file} holds no secret key; make a key pair with `slipstack keys {d}`")
        return cls(d, public, secret)


def make_keys(directory: str | Path) -> tuple[Path, Path]:
    """Create ``DIR`` (mode 0700) with a new key pair; returns (public, secret) file paths.

    Raises:
        ConfigError: a key pair is there already (never overwritten).
    """
    d = Path(directory).expanduser()
    if (d / f"{KEY_NAME}.key_secret").exists():
        raise ConfigError(f"{d} already holds a key pair; remove it first to make a new one")
    d.mkdir(mode=0o700, parents=True, exist_ok=True)
    os.chmod(d, 0o700)
    public, secret = zmq.auth.create_certificates(str(d), KEY_NAME)
    os.chmod(secret, 0o600)
    return Path(public), Path(secret)


_keys: GraphKeys | None = None
_authenticators: dict[int, ThreadAuthenticator] = {}


def use_keys(directory: str | Path | None) -> None:
    """Use the keys in ``directory`` for this process's tcp sockets (None: from the environment)."""
    global _keys
    _keys = GraphKeys.load(directory) if directory else None


def _active() -> GraphKeys | None:
    global _keys
    if _keys is None and os.environ.get(KEYS_ENV):
        _keys = GraphKeys.load(os.environ[KEYS_ENV])
    return _keys


def _tcp_keys(endpoint: str) -> GraphKeys | None:
    """The keys a socket on ``endpoint`` must use; None for ipc or an explicitly insecure graph."""
    if not endpoint.startswith("tcp://"):
        return None
    keys = _active()
    if keys is None and os.environ.get(INSECURE_ENV) != "1":
        raise ConfigError(f"{endpoint}: tcp needs the graph's keys: make them with `slipstack keys DIR` and set "
                          "[launch] keys = \"DIR\" (or insecure = true to allow anyone on the network)")
    return keys


def secure_bind(sock: zmq.Socket, endpoint: str) -> None:
    """Make ``sock`` a CURVE server before it binds ``endpoint`` (tcp only)."""
    keys = _tcp_keys(endpoint)
    if keys is None:
        return
    ctx = sock.context
    if id(ctx) not in _authenticators:
        auth = ThreadAuthenticator(ctx)
        auth.start()
        auth.configure_curve(domain="*", location=str(keys.directory))
        _authenticators[id(ctx)] = auth
    sock.curve_secretkey = keys.secret
    sock.curve_publickey = keys.public
    sock.curve_server = True


def secure_connect(sock: zmq.Socket, endpoint: str) -> None:
    """Make ``sock`` a CURVE client of the graph before it connects to ``endpoint`` (tcp only)."""
    keys = _tcp_keys(endpoint)
    if keys is None:
        return
    sock.curve_secretkey = keys.secret
    sock.curve_publickey = keys.public
    sock.curve_serverkey = keys.public
