"""Injection from other machines: tools elsewhere reach this machine's nodes through its launcher.

More in docs/modules.md, `launch/inject_relay.py`.
"""

from __future__ import annotations

import threading

import zmq

from slipstack.messages.codec import MAX_PAYLOAD_BYTES
from slipstack.nodes.runtime.curve import secure_bind
from slipstack.nodes.runtime.transport import MAX_ORIGIN_BYTES, SUBSCRIPTION_HWM, bound_socket

__all__ = ["InjectionRelay", "READ_LIMIT"]

READ_LIMIT = 256
"""Frames forwarded per wake-up in each direction."""
_HWM = 200  # injected frames queued each way (the nodes' injection sockets hold as many)
_POLL_MS = 100  # how often the thread looks at its stop flag


class InjectionRelay:
    """Forwards injection from ``endpoint`` (tcp, bound) to the nodes' injection endpoints ``targets``."""

    def __init__(self, zctx: zmq.Context, endpoint: str, targets: list[str]) -> None:
        self.endpoint = endpoint
        self.forwarded = 0
        self.rejected = 0
        self._stop = threading.Event()
        self.tools = bound_socket(zctx, zmq.XSUB, sndhwm=SUBSCRIPTION_HWM, rcvhwm=_HWM, max_msg_bytes=MAX_PAYLOAD_BYTES)
        secure_bind(self.tools, endpoint)
        self.tools.bind(endpoint)
        self.nodes = bound_socket(zctx, zmq.XPUB, sndhwm=_HWM, rcvhwm=SUBSCRIPTION_HWM, max_msg_bytes=MAX_PAYLOAD_BYTES)
        for target in sorted(set(targets)):
            self.nodes.connect(target)
        self._thread = threading.Thread(target=self._run, name="inject-relay", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        poller = zmq.Poller()
        poller.register(self.tools, zmq.POLLIN)
        poller.register(self.nodes, zmq.POLLIN)
        while not self._stop.is_set():
            events = dict(poller.poll(_POLL_MS))
            if self.nodes in events:  # (un)subscriptions of the nodes: up to the tools
                for _ in range(READ_LIMIT):
                    try:
                        self.tools.send(self.nodes.recv(zmq.NOBLOCK), zmq.NOBLOCK)
                    except zmq.Again:
                        break
            if self.tools in events:
                for _ in range(READ_LIMIT):
                    try:
                        parts = self.tools.recv_multipart(zmq.NOBLOCK)
                    except zmq.Again:
                        break
                    self._forward(parts)

    def _forward(self, parts: list[bytes]) -> None:
        if len(parts) not in (2, 3) or (len(parts) == 3 and len(parts[2]) > MAX_ORIGIN_BYTES):
            self.rejected += 1  # the node would reject it too: it is not an injection frame
            return
        try:
            self.nodes.send_multipart(parts, zmq.NOBLOCK)
            self.forwarded += 1
        except zmq.Again:  # a node's queue is full: dropped, as its own socket would
            pass

    def close(self) -> None:
        """Stop the thread and close both sockets."""
        self._stop.set()
        self._thread.join()
        self.tools.close(linger=0)
        self.nodes.close(linger=0)
