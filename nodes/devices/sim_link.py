"""Simulated devices: device links inside one process, for lock-step runs.

A simulated device is the twin of a real one: the same emulator speaks the same wire
protocol, and the same driver back-end decodes it, but the bytes pass through a
:class:`SimPort` in this process's device table instead of a pseudo-terminal or a
UDP socket. Nothing is bound or opened and nothing waits: whoever runs the nodes
(the in-process executor, ``slipstack launch --lockstep``) decides when each side
runs, so a run is deterministic.

More in docs/modules.md, `nodes/devices/sim_link.py`.
"""

from __future__ import annotations

from collections import deque
from typing import Callable

from . import ReconnectingLink
from .serial_link import SerialLink
from .tcp_link import TcpLink
from .udp_link import UdpLink

__all__ = ["SIM_PREFIX", "PORT_MAX_BYTES", "SimPort", "SimDevice", "SimLink", "is_simulated", "udp_address",
           "tcp_address", "sim_twin", "plugged_ports", "host_side_changes"]

SIM_PREFIX = "sim:"
PORT_MAX_BYTES = 1 << 20
"""Bytes one direction of a :class:`SimPort` holds before it drops (1 MiB, ~1 s of a 16×16 tactile stream at 500 Hz)."""

_TABLE: dict[str, "SimPort"] = {}
_host_side_changes = 0  # see host_side_changes()


def is_simulated(address: str) -> bool:
    """True for a ``sim:`` address or URL."""
    return address.startswith(SIM_PREFIX)


def udp_address(host: str, port: int) -> str:
    """The table address of a simulated UDP device."""
    return f"udp:{host}:{port}"


def tcp_address(host: str, port: int) -> str:
    """The table address of a simulated TCP device (its byte stream, like a serial port's)."""
    return f"tcp:{host}:{port}"


def host_side_changes() -> int:
    """A count that moves whenever a device wrote to its host or a port was plugged or
    unplugged: the only things outside a driver's own calls that can move a
    :class:`SimLink`'s :meth:`~SimLink.next_attempt_ns`. A lock-step executor re-reads its
    drivers' deadlines before the clock moves only when this count moved."""
    return _host_side_changes


def _host_side_changed() -> None:
    global _host_side_changes
    _host_side_changes += 1


def plugged_ports() -> list[str]:
    """Addresses of the simulated devices plugged in now (for error messages and tests)."""
    return sorted(_TABLE)


class _Direction:
    """One direction of a port: chunks in order (datagram boundaries kept), bounded in bytes."""

    def __init__(self) -> None:
        self.chunks: deque[bytes] = deque()
        self.size = 0
        self.dropped_bytes = 0

    def put(self, data: bytes) -> bool:
        if self.size + len(data) > PORT_MAX_BYTES:
            self.dropped_bytes += len(data)
            return False
        self.chunks.append(bytes(data))
        self.size += len(data)
        return True

    def take_all(self) -> list[bytes]:
        out = list(self.chunks)
        self.chunks.clear()
        self.size = 0
        return out


class SimPort:
    """A plugged simulated device: bytes to the host and bytes to the device."""

    def __init__(self, address: str) -> None:
        self.address = address
        self.to_host = _Direction()
        self.to_device = _Direction()
        self.host_attached = False


class SimDevice:
    """The device side of a simulated port, with :class:`~.emulators.PtyDevice`'s interface
    (``plug``, ``unplug``, ``write``, ``read``, ``close``), so an emulator runs on either."""

    def __init__(self, address: str) -> None:
        self.path = self.address = address[len(SIM_PREFIX):] if is_simulated(address) else address
        self._port: SimPort | None = None

    @property
    def plugged(self) -> bool:
        return self._port is not None

    @property
    def dropped_bytes(self) -> int:
        return 0 if self._port is None else self._port.to_host.dropped_bytes

    def plug(self) -> None:
        """Put a fresh port in the table at the address (a host still holding the old one reads it lost)."""
        if self._port is None:
            self._port = _TABLE[self.address] = SimPort(self.address)
            _host_side_changed()

    def unplug(self) -> None:
        if self._port is not None and _TABLE.get(self.address) is self._port:
            del _TABLE[self.address]
        self._port = None
        _host_side_changed()

    def write(self, data: bytes) -> bool:
        """To the host; False if unplugged or the port is full (the bytes are dropped and counted)."""
        if self._port is None:
            return False
        _host_side_changed()
        return self._port.to_host.put(data)

    def read(self) -> bytes:
        """Every byte the host wrote since the last read."""
        return b"".join(self.read_chunks())

    def read_chunks(self) -> list[bytes]:
        """What the host wrote since the last read, one item per write (a datagram each)."""
        return [] if self._port is None else self._port.to_device.take_all()

    def fileno(self) -> None:
        return None

    def close(self) -> None:
        self.unplug()


class SimLink(ReconnectingLink[SimPort]):
    """The host side: a serial-style (``read``/``write``) and datagram-style
    (``recv``/``send``) link to the port at ``address``, with the reconnect, back-off
    and staleness of the real links."""

    def __init__(self, address: str, *, stale_after_s: float, backoff_min_s: float = 0.05,
                 backoff_max_s: float = 2.0, on_open: Callable[[int], None] | None = None) -> None:
        super().__init__(stale_after_s=stale_after_s, backoff_min_s=backoff_min_s,
                         backoff_max_s=backoff_max_s, on_open=on_open)
        self.address = address
        self.write_shortfall = 0

    def _connect(self) -> SimPort:
        port = _TABLE.get(self.address)
        if port is None:
            raise OSError(f"no simulated device at {self.address} (plugged in: {', '.join(plugged_ports()) or 'none'}); "
                          "a sim: URL needs the simulated rig in the same lock-step run")
        port.to_host.take_all()  # like pyserial, start from an empty input buffer
        port.host_attached = True
        return port

    def _disconnect(self, handle: SimPort) -> None:
        handle.host_attached = False

    def _fileno(self, handle: SimPort) -> None:
        return None

    def _live(self, now_ns: int) -> SimPort | None:
        """The open port, or None; a port unplugged under us is lost (the driver reads disconnected)."""
        port = self._ensure_open(now_ns)
        if port is not None and _TABLE.get(self.address) is not port:
            self._lost(now_ns, OSError(f"simulated device {self.address} unplugged"))
            return None
        return port

    def next_attempt_ns(self) -> int | None:
        """When the back-end must poll again without a timer of its own: at once (0) while bytes
        wait, else the retry of a lost link (None while open and idle)."""
        port = self._handle
        if port is None:
            return super().next_attempt_ns()
        # open: no retry pending (the base class's answer, without its call: read at every simulated instant)
        return 0 if port.to_host.chunks and _TABLE.get(self.address) is port else None

    def read(self, now_ns: int) -> bytes:
        """Every byte the device sent (b"" if none or closed)."""
        return b"".join(self.recv(now_ns))

    def recv(self, now_ns: int) -> list[bytes]:
        """What the device sent, one item per device write (a datagram each)."""
        port = self._live(now_ns)
        if port is None:
            return []
        chunks = port.to_host.take_all()
        if chunks:
            self.freshness.touch(now_ns)
        return chunks

    def write(self, data: bytes, now_ns: int) -> int:
        """Bytes the port accepted (0 if closed or full)."""
        port = self._live(now_ns)
        if port is None:
            return 0
        if not port.to_device.put(data):
            self.write_shortfall += len(data)
            return 0
        return len(data)

    def send(self, data: bytes, now_ns: int) -> bool:
        """One datagram; False if closed or full."""
        return self.write(data, now_ns) == len(data)


def sim_twin(link: SerialLink | UdpLink | TcpLink) -> SimLink:
    """A :class:`SimLink` at the simulated address of ``link``'s device, with its timings and ``on_open``."""
    if isinstance(link, SerialLink):
        address = link.port
    else:
        address = (tcp_address if isinstance(link, TcpLink) else udp_address)(*link.address)
    return SimLink(address, stale_after_s=link.freshness.stale_after_ns / 1e9,
                   backoff_min_s=link.backoff.min_ns / 1e9, backoff_max_s=link.backoff.max_ns / 1e9,
                   on_open=link.on_open)
