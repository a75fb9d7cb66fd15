"""ZeroMQ CURVE on every tcp link: only holders of the graph's keys publish, receive or inject.

More in docs/modules.md, `nodes/runtime/curve.py`.
"""

from __future__ import annotations

import json
import os
import shutil
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator

import zmq
import zmq.auth

from slipstack.lib.errors import ConfigError

__all__ = ["KEYS_ENV", "INSECURE_ENV", "MACHINE_ENV", "GraphKeys", "make_keys", "make_machine_keys", "use_keys",
           "machine_env", "endpoint_host", "secure_bind", "secure_connect"]

KEYS_ENV = "SLIPSTACK_KEYS"
INSECURE_ENV = "SLIPSTACK_INSECURE"
MACHINE_ENV = "SLIPSTACK_MACHINE"
KEY_NAME = "graph"


@dataclass(frozen=True)
class GraphKeys:
    """A graph's (or one machine's) CURVE key pair (z85 bytes) and the directory of allowed public keys."""

    directory: Path
    public: bytes
    secret: bytes
    servers: dict[str, bytes] = field(default_factory=dict)
    """Address → public key of the machine serving there; other addresses serve with ``public``."""

    @classmethod
    def load(cls, directory: str | Path, machine: str | None = None, hosts: dict[str, str] | None = None) -> GraphKeys:
        """Read ``DIR/graph.key_secret``, or ``DIR/MACHINE.key_secret`` and the public key of
        every machine in ``hosts`` (address → machine name); a clear error says how to make them."""
        d = Path(directory).expanduser().resolve()
        name = machine or KEY_NAME
        how = f"slipstack keys DIR --machine {machine} ..." if machine else f"slipstack keys {d}"
        secret_file = d / f"{name}.key_secret"
        try:
            public, secret = zmq.auth.load_certificate(secret_file)
        except (OSError, ValueError) as exc:
            raise ConfigError(f"no usable key pair in {d} ({exc}); make one with `{how}`") from None
        if secret is None:
            raise ConfigError(f"{secret_file} holds no secret key; make a key pair with `{how}`")
        servers: dict[str, bytes] = {}
        for host, peer in (hosts or {}).items():
            try:
                servers[host] = zmq.auth.load_certificate(d / f"{peer}.key")[0]
            except (OSError, ValueError):
                raise ConfigError(f"{d} has no public key of machine {peer} ({peer}.key): copy it there from "
                                  f"that machine's key directory") from None
        return cls(d, public, secret, servers)

    def server_key(self, endpoint: str) -> bytes:
        """The public key the socket serving ``endpoint`` must prove it holds."""
        return self.servers.get(endpoint_host(endpoint), self.public)


def make_keys(directory: str | Path) -> tuple[Path, Path]:
    """Create ``DIR`` (mode 0700) with a new key pair; returns (public, secret) file paths.

    Raises:
        ConfigError: a key pair is there already (never overwritten).
    """
    d = Path(directory).expanduser()
    if (d / f"{KEY_NAME}.key_secret").exists():
        raise ConfigError(f"{d} already holds a key pair; remove it first to make a new one")
    with _keys_written(d):
        _private_dir(d)
        public, secret = zmq.auth.create_certificates(str(d), KEY_NAME)
        os.chmod(secret, 0o600)
    return Path(public), Path(secret)


@contextmanager
def _keys_written(directory: Path) -> Iterator[None]:
    """Key files written into ``directory``: a folder that cannot take them is a ConfigError."""
    try:
        yield
    except OSError as exc:
        raise ConfigError(f"cannot make keys in {directory} ({exc.strerror}); give a new directory of yours, "
                          "e.g. `slipstack keys ~/.slipstack/keys`") from None


def _private_dir(d: Path) -> None:
    """``d`` made with mode 0700 (its parents too); an existing one must be an empty directory of
    this user's (never a folder of other files, whose mode this would change)."""
    if d.is_dir() and not d.is_symlink() and d.stat().st_uid == os.getuid() and not any(d.iterdir()):
        os.chmod(d, 0o700)
        return
    if os.path.lexists(d):
        raise ConfigError(f"{d} exists and is not an empty directory of yours; keys go into a directory of their "
                          "own: give a new one")
    d.mkdir(mode=0o700, parents=True)


def make_machine_keys(directory: str | Path, machines: list[str]) -> list[Path]:
    """``DIR/NAME/`` (mode 0700) for each machine: its key pair and every machine's public key.

    Raises:
        ConfigError: one of the directories holds a key pair already (never overwritten).
    """
    bad = [n for n in machines if not n or not all(c.isalnum() or c in "_-" for c in n)]
    if bad or len(set(machines)) != len(machines):
        raise ConfigError(f"machine names must be distinct letters, digits, _ and - (as in [machines.NAME]); "
                          f"got {machines}")
    d = Path(directory).expanduser()
    dirs = [d / name for name in machines]
    for sub, name in zip(dirs, machines):
        if (sub / f"{name}.key_secret").exists():
            raise ConfigError(f"{sub} already holds a key pair; remove it first to make new ones")
    with _keys_written(d):
        if not d.is_dir() or d.is_symlink():
            _private_dir(d)
        for sub, name in zip(dirs, machines):
            _private_dir(sub)
            _, secret = zmq.auth.create_certificates(str(sub), name)
            os.chmod(secret, 0o600)
        for sub in dirs:
            for other, name in zip(dirs, machines):
                if other != sub:
                    shutil.copyfile(other / f"{name}.key", sub / f"{name}.key")
    return dirs


def machine_env(name: str, hosts: dict[str, str]) -> str:
    """The value of ``$SLIPSTACK_MACHINE``: this machine's name and address → machine name."""
    return json.dumps({"name": name, "hosts": hosts})


def endpoint_host(endpoint: str) -> str:
    """The address part of a ``tcp://`` endpoint ("" for another transport)."""
    if not endpoint.startswith("tcp://"):
        return ""
    return endpoint[len("tcp://"):].rsplit(":", 1)[0].strip("[]")


_keys: GraphKeys | None = None
_insecure = False
_authenticators: dict[int, "zmq.auth.thread.ThreadAuthenticator"] = {}


def use_keys(directory: str | Path | None, machine: str | None = None, hosts: dict[str, str] | None = None, *,
             insecure: bool = False) -> None:
    """Use the keys in ``directory`` for this process's tcp sockets (None: from the environment);
    ``machine`` and ``hosts`` for a graph over several machines (:meth:`GraphKeys.load`);
    ``insecure``: tcp without keys allowed (the launch file's ``insecure = true``)."""
    global _keys, _insecure
    _keys = GraphKeys.load(directory, machine, hosts) if directory else None
    _insecure = insecure


def _active() -> GraphKeys | None:
    global _keys
    if _keys is None and os.environ.get(KEYS_ENV):
        machine = json.loads(os.environ.get(MACHINE_ENV) or "{}")
        _keys = GraphKeys.load(os.environ[KEYS_ENV], machine.get("name"), machine.get("hosts"))
    return _keys


def _tcp_keys(endpoint: str) -> GraphKeys | None:
    """The keys a socket on ``endpoint`` must use; None for ipc or an explicitly insecure graph."""
    if not endpoint.startswith("tcp://"):
        return None
    keys = _active()
    if keys is None and not _insecure and os.environ.get(INSECURE_ENV) != "1":
        raise ConfigError(f"{endpoint}: tcp needs the graph's keys: make them with `slipstack keys DIR` and set "
                          "[launch] keys = \"DIR\" (or insecure = true to allow anyone on the network)")
    return keys


def secure_bind(sock: zmq.Socket, endpoint: str) -> None:
    """Make ``sock`` a CURVE server before it binds ``endpoint`` (tcp only; plain for ipc)."""
    keys = _tcp_keys(endpoint)
    if keys is None:
        _plain(sock)
        return
    ctx = sock.context
    if id(ctx) not in _authenticators:
        from zmq.auth.thread import ThreadAuthenticator  # here, not at the top: it imports asyncio (~15 ms)

        auth = ThreadAuthenticator(ctx)
        auth.start()
        auth.configure_curve(domain="*", location=str(keys.directory))
        _authenticators[id(ctx)] = auth
    sock.curve_secretkey = keys.secret
    sock.curve_publickey = keys.public
    sock.curve_server = True


def secure_connect(sock: zmq.Socket, endpoint: str) -> None:
    """Make ``sock`` a CURVE client of the graph before it connects to ``endpoint`` (tcp only; plain for ipc)."""
    keys = _tcp_keys(endpoint)
    if keys is None:
        _plain(sock)
        return
    sock.curve_secretkey = keys.secret
    sock.curve_publickey = keys.public
    sock.curve_serverkey = keys.server_key(endpoint)


def _plain(sock: zmq.Socket) -> None:
    """No security mechanism for the socket's next bind or connect. ZeroMQ reads the mechanism
    at each bind and connect from the socket's options, so one socket that reached a tcp peer
    with CURVE (a recorder tapping two machines) would otherwise offer CURVE to an ipc peer too,
    which never answers the handshake; setting ``curve_server`` to 0 resets it to NULL."""
    if sock.get(zmq.MECHANISM) != zmq.NULL:
        sock.curve_server = False
