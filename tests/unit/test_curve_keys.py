"""CURVE key files (nodes/runtime/curve.py): the paths and modes written, the address of a
tcp endpoint whose machine key a socket must prove."""

from __future__ import annotations

import stat
from pathlib import Path

import pytest
import zmq.auth

from slipstack.nodes.runtime import curve


def _mode(path: Path) -> int:
    return stat.S_IMODE(path.stat().st_mode)


def test_make_keys_returns_the_pair_it_wrote_and_only_the_owner_reads_the_secret(tmp_path):
    d = tmp_path / "keys"
    public, secret = curve.make_keys(d)
    assert (public, secret) == (d / "graph.key", d / "graph.key_secret")
    assert _mode(d) == 0o700 and _mode(secret) == 0o600
    pair = zmq.auth.load_certificate(secret)
    assert pair[1] is not None and zmq.auth.load_certificate(public)[0] == pair[0]


def test_each_machine_gets_a_private_secret_and_every_machines_public_key(tmp_path):
    dirs = curve.make_machine_keys(tmp_path / "keys", ["a", "b"])
    assert dirs == [tmp_path / "keys" / "a", tmp_path / "keys" / "b"]
    for d, name in zip(dirs, ["a", "b"]):
        assert _mode(d) == 0o700 and _mode(d / f"{name}.key_secret") == 0o600
        assert sorted(p.name for p in d.iterdir()) == sorted(["a.key", "b.key", f"{name}.key_secret"])


@pytest.mark.parametrize("endpoint, host", [
    ("tcp://10.0.0.2:5555", "10.0.0.2"),
    ("tcp://robot-pc:40000", "robot-pc"),
    ("tcp://[fe80::1]:5555", "fe80::1"),  # IPv6: the colons of the address stay
    ("ipc:///tmp/slipstack/ft", ""),
])
def test_endpoint_host_is_the_address_without_port_or_brackets(endpoint, host):
    assert curve.endpoint_host(endpoint) == host
