"""The two sockets of a tool that publishes into a running graph (``topic pub``, ``bag play``).

More in docs/modules.md, `nodes/runtime/tool_pub.py`.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import zmq

from slipstack.nodes.runtime.curve import secure_connect
from slipstack.nodes.runtime.graph_info import register_tool
from slipstack.nodes.runtime.transport import (
    MAX_ORIGIN_BYTES, MAX_SUBSCRIPTION_BYTES, SUBSCRIPTION_HWM, bound_socket, ipc_endpoint, make_pub,
)

__all__ = ["BusPublisher", "InjectionSender", "MAX_ORIGIN_BYTES", "tool_name"]

class BusPublisher:
    """The tool's publish endpoint on the bus (module docstring).

    Args:
        run_dir: the graph's run directory (``None``: bind ``endpoint`` without registering).
        name: the tool's name in the graph, e.g. ``topic_pub-1234``.
        outputs: topic → message type name of what it will send.
        endpoint: where to bind (default ``ipc://<run_dir>/<name>.pub``).
    """

    def __init__(self, run_dir: Path | None, name: str, outputs: dict[str, str], *,
                 endpoint: str | None = None, sndhwm: int = 1000) -> None:
        if endpoint is None and run_dir is None:
            raise ValueError("BusPublisher needs a run directory or an endpoint")
        self.endpoint = endpoint or ipc_endpoint(run_dir, name)
        self.sock = make_pub(zmq.Context.instance(), self.endpoint, sndhwm=sndhwm)
        self._registration = None if run_dir is None else register_tool(run_dir, name, self.endpoint, outputs)

    def wait_for_recorders(self, count: int, timeout_s: float) -> int:
        """Wait until ``count`` all-topic subscribers (the graph's recorders, which re-read the
        registrations every half second) have joined; returns how many did."""
        joined = 0
        deadline = time.monotonic() + timeout_s
        while joined < count:
            left = deadline - time.monotonic()
            if left <= 0 or not self.sock.poll(max(1, round(left * 1000))):
                break
            if self.sock.recv() == b"\x01":
                joined += 1
        return joined

    def send(self, topic: str, payload: bytes) -> None:
        self.sock.send_multipart((topic.encode(), payload), copy=True)

    def close(self, linger_s: float = 1.0) -> None:
        """Send what is queued (up to ``linger_s``), unbind and remove the registration."""
        self.sock.close(linger=round(linger_s * 1000))
        if self._registration is not None:
            try:
                self._registration.unlink()
            except FileNotFoundError:
                pass


class InjectionSender:
    """XPUBs connected to nodes' injection endpoints; frames carry ``origin`` (module docstring).

    The ipc endpoints of this machine's nodes share one socket; each tcp endpoint (another
    machine's launcher) gets one of its own, as CURVE is set per socket and per server."""

    def __init__(self, addresses: list[str], origin: str, *, sndhwm: int = 1000) -> None:
        self.origin = origin.encode()[:MAX_ORIGIN_BYTES]
        groups: dict[str, list[str]] = {}
        for address in sorted(set(addresses)):
            groups.setdefault(address if address.startswith("tcp://") else "", []).append(address)
        self.socks: list[zmq.Socket] = []
        for key, members in sorted(groups.items()):
            sock = bound_socket(zmq.Context.instance(), zmq.XPUB, sndhwm=sndhwm, rcvhwm=SUBSCRIPTION_HWM,
                                max_msg_bytes=MAX_SUBSCRIPTION_BYTES)
            sock.setsockopt(zmq.XPUB_VERBOSE, 1)
            if key:
                secure_connect(sock, key)  # another machine's launcher: tcp with CURVE
            for address in members:
                sock.connect(address)
            self.socks.append(sock)

    def wait_for_subscriptions(self, want: dict[str, int], timeout_s: float) -> dict[str, int]:
        """Wait until ``want[topic]`` subscriptions to each topic arrived; returns the counts seen."""
        seen = {t: 0 for t in want}
        poller = zmq.Poller()
        for sock in self.socks:
            poller.register(sock, zmq.POLLIN)
        deadline = time.monotonic() + timeout_s
        while any(seen[t] < n for t, n in want.items()):
            left = deadline - time.monotonic()
            ready = dict(poller.poll(max(1, round(left * 1000)))) if left > 0 else {}
            if not ready:
                break
            for sock in ready:
                frame = sock.recv()
                topic = frame[1:].decode(errors="replace")
                if frame[:1] == b"\x01" and topic in seen:
                    seen[topic] += 1
        return seen

    def send(self, topic: str, payload: bytes, origin: str | None = None) -> None:
        """One ``[topic, payload, origin]`` frame (``origin``: this sender's, or a sub-origin of it)."""
        tag = self.origin if origin is None else (self.origin + b"/" + origin.encode())[:MAX_ORIGIN_BYTES]
        for sock in self.socks:
            sock.send_multipart((topic.encode(), payload, tag), copy=True)

    def close(self, linger_s: float = 1.0) -> None:
        for sock in self.socks:
            sock.close(linger=round(linger_s * 1000))


def tool_name(kind: str) -> str:
    """``kind-<pid>``: a tool's name in the graph."""
    return f"{kind}-{os.getpid()}"
