"""Device emulators: the device side of each wire protocol, for the simulated rig.

Each emulator encodes with the same codec the driver decodes with
(``slipstack.lib.protocols``) and reacts to the host's commands. The caller (the
simulated rig) paces them: it calls ``send_ft(force_n, torque_nm)`` or
``send_tactile(counts)`` once per sample period; each call first handles pending
host commands, then sends a frame if the device is streaming. Nothing blocks.

More in docs/modules.md, `nodes/devices/emulators.py`.
"""

from __future__ import annotations

import os
import shutil
import socket
import struct
import tempfile
import tty
from typing import Sequence

import numpy as np

from slipstack.lib.protocols import ati_rdt, bota, dsacon32, m1616, robotiq, wsg
from slipstack.lib.protocols.framed import FramedFormat, encode_frame as encode_framed
from slipstack.lib.protocols.stream import Deframer

from .sim_link import SIM_PREFIX, SimDevice, is_simulated, tcp_address, udp_address

__all__ = [
    "PtyDevice", "SerialEmulator", "RobotiqEmulator", "BotaEmulator", "Dsacon32Emulator",
    "FramedEmulator", "M1616Emulator", "RdtUdpServer", "RdtSimServer", "TcpServerDevice", "WsgEmulator",
]


class PtyDevice:
    """A pseudo-terminal standing in for a serial device, behind a stable symlink.

    ``write`` never blocks: bytes the pty cannot take now are dropped and counted in
    ``dropped_bytes`` (as a UART overrun would lose them).
    """

    def __init__(self, link_path: str | os.PathLike | None = None) -> None:
        self._tmpdir: str | None = None
        if link_path is None:
            self._tmpdir = tempfile.mkdtemp(prefix="slipstack-pty-")
            link_path = os.path.join(self._tmpdir, "tty")
        self.path = str(link_path)
        self.dropped_bytes = 0
        self._master: int | None = None
        self._slave: int | None = None

    @property
    def plugged(self) -> bool:
        return self._master is not None

    def plug(self) -> None:
        """Open a new pty (raw mode) and point the link at its slave."""
        if self._master is not None:
            return
        master, slave = os.openpty()
        tty.setraw(master)
        tty.setraw(slave)
        os.set_blocking(master, False)
        tmp = self.path + ".new"
        if os.path.lexists(tmp):
            os.unlink(tmp)
        os.symlink(os.ttyname(slave), tmp)
        os.replace(tmp, self.path)
        self._master, self._slave = master, slave

    def unplug(self) -> None:
        """Remove the link and close the pty; the host side sees EIO."""
        if os.path.lexists(self.path):
            os.unlink(self.path)
        for fd in (self._master, self._slave):
            if fd is not None:
                os.close(fd)
        self._master = self._slave = None

    def write(self, data: bytes) -> bool:
        """Write to the host; False (bytes counted as dropped) if unplugged or full."""
        if self._master is None:
            return False
        try:
            n = os.write(self._master, data)
        except BlockingIOError:
            n = 0
        self.dropped_bytes += len(data) - n
        return n == len(data)

    def read(self) -> bytes:
        """Bytes the host wrote, b"" if none or unplugged."""
        if self._master is None:
            return b""
        try:
            return os.read(self._master, 1 << 16)
        except (BlockingIOError, OSError):
            return b""

    def fileno(self) -> int | None:
        return self._master

    def close(self) -> None:
        self.unplug()
        if self._tmpdir is not None:
            shutil.rmtree(self._tmpdir, ignore_errors=True)
            self._tmpdir = None


class SerialEmulator:
    """Base of the serial emulators: a plugged :class:`PtyDevice` and command dispatch."""

    def __init__(self, link_path: str | os.PathLike | None = None) -> None:
        simulated = link_path is not None and is_simulated(str(link_path))
        self.device: PtyDevice | SimDevice = SimDevice(str(link_path)) if simulated else PtyDevice(link_path)
        self.replug()

    @property
    def path(self) -> str:
        """Path the driver opens (stable across unplug/replug)."""
        return self.device.path

    def service(self) -> None:
        """Handle every command the host has sent so far."""
        data = self.device.read()
        if data:
            self._on_command(data)

    def unplug(self) -> None:
        self.device.unplug()

    def replug(self) -> None:
        """Plug in again (power-up state)."""
        self.device.plug()
        self._on_power_up()

    def close(self) -> None:
        self.device.close()

    def _on_power_up(self) -> None:
        """Reset protocol state at plug-in."""

    def _on_command(self, data: bytes) -> None:
        """React to host bytes."""


class RobotiqEmulator(SerialEmulator):
    """Robotiq FT 300: streams at power-up if ``streaming``; any 0xFF byte stops the
    stream; the start-stream Modbus request is answered with its echo and starts it."""

    def __init__(self, link_path: str | os.PathLike | None = None, *, streaming: bool = True) -> None:
        self.streaming_at_power_up = streaming
        self._requests = Deframer(robotiq.WriteRequestCodec(robotiq.SLAVE_ID))
        super().__init__(link_path)

    def _on_power_up(self) -> None:
        self.streaming = self.streaming_at_power_up
        self._requests.reset()

    def _on_command(self, data: bytes) -> None:
        if self.streaming and robotiq.STOP_BYTE in data:
            self.streaming = False
        for req in self._requests.feed(data):
            if req.register == robotiq.STREAM_REGISTER and req.values == (robotiq.STREAM_START_VALUE,):
                self.device.write(robotiq.encode_write_echo(req.slave, req.register, len(req.values)))
                self.streaming = True

    def send_ft(self, force_n: Sequence[float], torque_nm: Sequence[float]) -> bool:
        """Send one frame (N, N·m, sensor frame) if streaming; True if written."""
        self.service()
        return self.streaming and self.device.write(robotiq.encode_frame(force_n, torque_nm))


class BotaEmulator(SerialEmulator):
    """Bota serial sensor: ``C`` stops streaming, ``R`` starts it (both answered)."""

    def __init__(self, link_path: str | os.PathLike | None = None, *, streaming: bool = True,
                 rate_hz: float = bota.RATE_HZ) -> None:
        self.streaming_at_power_up = streaming
        self.period_us = 1e6 / rate_hz
        super().__init__(link_path)

    def _on_power_up(self) -> None:
        self.streaming = self.streaming_at_power_up
        self.n_sent = 0

    def _on_command(self, data: bytes) -> None:
        for c in data:
            cmd = bytes([c])
            if cmd in (bota.CONFIG_COMMAND, bota.RUN_COMMAND):
                self.streaming = cmd == bota.RUN_COMMAND
                self.device.write(bota.command_reply(cmd))

    def send_ft(self, force_n: Sequence[float], torque_nm: Sequence[float], *, status: int = 0,
                temperature_c: float = 25.0, timestamp_us: int | None = None) -> bool:
        """Send one frame if streaming; the timestamp defaults to frames × period."""
        self.service()
        if not self.streaming:
            return False
        stamp = round(self.n_sent * self.period_us) if timestamp_us is None else timestamp_us
        self.n_sent += 1
        return self.device.write(bota.encode_frame(force_n, torque_nm, timestamp_us=stamp,
                                                   status=status, temperature_c=temperature_c))


class Dsacon32Emulator(SerialEmulator):
    """DSACON32 with one matrix of ``rows`` × ``cols`` taxels: answers matrix info
    (index 0; other indices get error 1) and configure acquisition; in push mode
    ``send_tactile`` sends a frame (RLE if the host asked for it). At plug-in it sends
    the power-up banner ``1B 5B 35 6E`` three times (it accepts commands at once)."""

    BANNER = b"\x1b\x5b\x35\x6e" * 3

    def __init__(self, link_path: str | os.PathLike | None = None, *, rows: int = 16, cols: int = 16,
                 texel_size_m: float = 1.25e-3) -> None:
        self.info = dsacon32.MatrixInfo(0, texel_size_m, texel_size_m, cols, rows)
        self._commands = Deframer(dsacon32.PacketCodec())
        super().__init__(link_path)

    def _on_power_up(self) -> None:
        self.acquiring = False
        self.rle = False
        self.fps = 0
        self.n_sent = 0
        self._commands.reset()
        self.device.write(self.BANNER)

    def _on_command(self, data: bytes) -> None:
        for p in self._commands.feed(data):
            if p.id == dsacon32.PacketId.MATRIX_INFO and len(p.payload) == 1:
                if p.payload[0] == 0:
                    self.device.write(dsacon32.encode_matrix_info(self.info))
                else:
                    self.device.write(dsacon32.encode_matrix_info(dsacon32.MatrixInfo(1, 0.0, 0.0, 0, 0)))
            elif p.id == dsacon32.PacketId.CONFIGURE_ACQUISITION:
                cfg = dsacon32.decode_configure_acquisition(p.payload)
                if cfg is None:
                    self.device.write(dsacon32.encode_error_reply(p.id, 1))
                    continue
                flags, self.fps = cfg
                self.acquiring = bool(flags & dsacon32.AcquisitionFlags.ACQUIRE) and self.fps > 0
                self.rle = bool(flags & dsacon32.AcquisitionFlags.RLE)
                self.device.write(dsacon32.encode_error_reply(p.id, 0))

    def send_tactile(self, counts: np.ndarray, *, timestamp_ms: int | None = None) -> bool:
        """Push one frame of *counts* (rows, cols), 0..4095, if acquiring; the
        timestamp defaults to frames × 1000/fps ms."""
        self.service()
        if not self.acquiring:
            return False
        stamp = round(self.n_sent * 1000.0 / self.fps) if timestamp_ms is None else timestamp_ms
        self.n_sent += 1
        payload = dsacon32.encode_frame_payload(stamp, counts, rle=self.rle)
        return self.device.write(dsacon32.encode_packet(dsacon32.PacketId.FRAME, payload))


class FramedEmulator(SerialEmulator):
    """A push-only framed tactile board (no commands)."""

    def __init__(self, fmt: FramedFormat, link_path: str | os.PathLike | None = None) -> None:
        self.format = fmt
        super().__init__(link_path)

    def send_tactile(self, counts: np.ndarray) -> bool:
        """Send one frame of *counts* (rows, cols); True if written."""
        return self.device.write(encode_framed(self.format, counts))


class M1616Emulator(FramedEmulator):
    """The M1616 16×16 module (header AA AB AC, u16 big-endian, 4 zero trailer bytes)."""

    def __init__(self, link_path: str | os.PathLike | None = None) -> None:
        super().__init__(m1616.FORMAT, link_path)


class RdtUdpServer:
    """ATI Net F/T RDT server on loopback: answers start (real-time / buffered → one
    record per datagram) and stop requests from any client, streams records to the
    latest requester; software bias (0x0042) subtracts the current reading.

    ``send_ft`` advances the internal ft_sequence every call (the sensor's 7 kHz
    clock) and sends a record while streaming; ``lose(n)`` skips sending the next n
    records while still numbering them (simulated packet loss).
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 0, *, counts_per_force: float = 1e6,
                 counts_per_torque: float = 1e6) -> None:
        self.host = host
        self.port = port
        self.scale = np.array([counts_per_force] * 3 + [counts_per_torque] * 3)
        self.sent = 0
        self._sock: socket.socket | None = None
        self._to_lose = 0
        self.replug()

    @property
    def address(self) -> tuple[str, int]:
        return (self.host, self.port)

    @property
    def url(self) -> str:
        return f"rdt://{self.host}:{self.port}"

    @property
    def plugged(self) -> bool:
        return self._sock is not None

    def replug(self) -> None:
        """Bind (again) at the same address; power-up state (not streaming)."""
        if self._sock is not None:
            return
        self._sock = self._bind()
        self.client: tuple[str, int] | None = None
        self.streaming = False
        self.remaining = 0
        self.rdt_sequence = 0
        self.ft_sequence = 0
        self.bias = np.zeros(6)
        self._last = np.zeros(6)

    def _bind(self) -> socket.socket:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((self.host, self.port))
        sock.setblocking(False)
        self.port = sock.getsockname()[1]
        return sock

    def _receive(self) -> tuple[bytes, object] | None:
        """The next request datagram and its sender, None if there is none."""
        try:
            return self._sock.recvfrom(64)
        except (BlockingIOError, ConnectionRefusedError):
            return None

    def _send_to_client(self, record: bytes) -> bool:
        try:
            self._sock.sendto(record, self.client)
        except (BlockingIOError, ConnectionRefusedError):
            return False
        return True

    def unplug(self) -> None:
        if self._sock is not None:
            self._sock.close()
            self._sock = None

    def close(self) -> None:
        self.unplug()

    def lose(self, n: int) -> None:
        self._to_lose += n

    def service(self) -> None:
        """Handle every pending request."""
        while self._sock is not None:
            received = self._receive()
            if received is None:
                return
            data, addr = received
            req = ati_rdt.decode_request(data)
            if req is None:
                continue
            command, count = req
            if command in (ati_rdt.Command.REALTIME, ati_rdt.Command.BUFFERED):
                self.client, self.streaming, self.remaining, self.rdt_sequence = addr, True, count, 0
            elif command == ati_rdt.Command.STOP:
                self.streaming = False
            elif command == ati_rdt.Command.BIAS:
                self.bias = self._last.copy()

    def send_ft(self, force_n: Sequence[float], torque_nm: Sequence[float], *, status: int = 0) -> bool:
        """One sensor tick: (N, N·m, sensor frame); True if a record was sent."""
        self.service()
        self.ft_sequence += 1
        self._last = np.concatenate([force_n, torque_nm]) * self.scale
        if self._sock is None or not self.streaming or self.client is None:
            return False
        self.rdt_sequence += 1
        if self.remaining:
            self.remaining -= 1
            self.streaming = self.remaining > 0
        if self._to_lose:
            self._to_lose -= 1
            return False
        record = ati_rdt.encode_record(self.rdt_sequence, self.ft_sequence, status, self._last - self.bias)
        if not self._send_to_client(record):
            return False
        self.sent += 1
        return True


class RdtSimServer(RdtUdpServer):
    """:class:`RdtUdpServer` in the simulated device table, at ``udp_address(host, port)``
    (``sim_link.py``): the driver's ``sim:rdt://HOST:PORT`` reaches it. One client, the host side of the port."""

    def _bind(self) -> SimDevice:  # type: ignore[override]
        device = SimDevice(udp_address(self.host, self.port))
        device.plug()
        return device

    def _receive(self) -> tuple[bytes, object] | None:
        if not self._pending:
            self._pending.extend(self._sock.read_chunks())
        return (self._pending.pop(0), "host") if self._pending else None

    def _send_to_client(self, record: bytes) -> bool:
        return self._sock.write(record)

    def replug(self) -> None:
        self._pending: list[bytes] = []
        super().replug()

    def unplug(self) -> None:
        if self._sock is not None:
            self._sock.unplug()
            self._sock = None

    @property
    def url(self) -> str:
        return f"sim:rdt://{self.host}:{self.port}"


class TcpServerDevice:
    """A TCP server on ``(host, port)`` standing in for a network device, with
    :class:`PtyDevice`'s interface: one client at a time; a newer one replaces it.
    Nothing blocks: ``write`` drops (and counts) what the socket cannot take now."""

    def __init__(self, host: str, port: int) -> None:
        self.host, self.port = host, port
        self.path = f"{host}:{port}"
        self.dropped_bytes = 0
        self._server: socket.socket | None = None
        self._client: socket.socket | None = None

    @property
    def plugged(self) -> bool:
        return self._server is not None

    def plug(self) -> None:
        """Listen (again) at the same address."""
        if self._server is not None:
            return
        server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        server.bind((self.host, self.port))
        server.listen(1)
        server.setblocking(False)
        self.port = server.getsockname()[1]
        self.path = f"{self.host}:{self.port}"
        self._server = server

    def unplug(self) -> None:
        """Close the client and stop listening (the host reads the connection lost)."""
        for sock in (self._client, self._server):
            if sock is not None:
                sock.close()
        self._client = self._server = None

    def _accept(self) -> None:
        try:
            client, _ = self._server.accept()
        except (BlockingIOError, OSError):
            return
        client.setblocking(False)
        client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        if self._client is not None:
            self._client.close()
        self._client = client

    def read(self) -> bytes:
        """Bytes the client sent, b"" if none (accepting a client first if one waits)."""
        if self._server is None:
            return b""
        self._accept()
        if self._client is None:
            return b""
        try:
            data = self._client.recv(1 << 16)
        except BlockingIOError:
            return b""
        except OSError:
            data = b""
        if not data:
            self._client.close()
            self._client = None
        return data

    def write(self, data: bytes) -> bool:
        """To the client; False (bytes counted as dropped) with none, or when it is full."""
        if self._client is None:
            self.dropped_bytes += len(data)
            return False
        try:
            n = self._client.send(data)
        except BlockingIOError:
            n = 0
        except OSError:
            n = 0
        self.dropped_bytes += len(data) - n
        return n == len(data)

    def fileno(self) -> int | None:
        return None if self._server is None else self._server.fileno()

    def close(self) -> None:
        self.unplug()


class WsgEmulator:
    """A Weiss WSG 50 answering its binary command protocol (docs/protocols.md §9).

    Powers up idle, fingers open, force limit 10 N. Answers: loop (echo), disconnect,
    acknowledge fast stop, grasp (pending, then held: a part of ``part_width_mm`` is found
    within ``travel_mm`` of the width asked, else ``E_CMD_FAILED``), release, set and get
    the force limit (``E_RANGE_ERROR`` outside :data:`~slipstack.lib.protocols.wsg.FORCE_RANGE_N`),
    get the grasping state and the grasping force (once, or every period with the
    auto-update flag); ``E_CMD_UNKNOWN`` for any other command, ``E_CMD_FORMAT_ERROR`` for a
    payload of the wrong size. A message whose CRC fails is dropped unanswered (counted).

    ``squeeze_n``: what the fingers press the part with (the force limit while holding, 0
    otherwise). Faults for tests: ``silent`` (reads and answers nothing), ``corrupt(n)``
    (the next ``n`` messages go out with a broken CRC).
    """

    GRASP_TIME_NS = 50_000_000

    def __init__(self, address: str = "127.0.0.1:0", *, part_width_mm: float = 20.0, travel_mm: float = 10.0) -> None:
        simulated = is_simulated(address)
        host, _, port = address[len(SIM_PREFIX) if simulated else 0:].rpartition(":")
        self.device: TcpServerDevice | SimDevice = (SimDevice(tcp_address(host, int(port))) if simulated
                                                    else TcpServerDevice(host, int(port)))
        self.part_width_mm = part_width_mm
        self.travel_mm = travel_mm
        self.silent = False
        self._corrupt = 0
        self._requests = Deframer(wsg.MessageCodec())
        self.device.plug()
        self._power_up()

    @property
    def path(self) -> str:
        return self.device.path

    @property
    def squeeze_n(self) -> float:
        return self.force_limit_n if self.state == wsg.GraspingState.HOLDING else 0.0

    @property
    def holding(self) -> bool:
        return self.state == wsg.GraspingState.HOLDING

    @property
    def rejected(self) -> int:
        """Messages dropped for a failed CRC (and bytes in none)."""
        return self._requests.counts.crc_errors

    def _power_up(self) -> None:
        self.state = wsg.GraspingState.IDLE
        self.force_limit_n = 10.0
        self.stream_period_ns = 0
        self._next_stream_ns = 0
        self._pending: tuple[int, int, int] | None = None  # (command, done at ns, final state)
        self._requests.reset()

    def corrupt(self, n: int) -> None:
        self._corrupt += n

    def tick(self, now_ns: int, force_n: float) -> None:
        """Handle what the host sent, finish a grasp or release that is due, stream the force."""
        if self.silent:
            self.device.read()
            return
        for message in self._requests.feed(self.device.read()):
            self._answer(message, now_ns, force_n)
        if self._pending is not None and now_ns >= self._pending[1]:
            command, _, final = self._pending
            self._pending = None
            self.state = final
            failed = final == wsg.GraspingState.NO_PART_FOUND
            self._send(wsg.encode_reply(command, wsg.Status.E_CMD_FAILED if failed else wsg.Status.E_SUCCESS))
        if self.stream_period_ns and now_ns >= self._next_stream_ns:
            self._next_stream_ns = now_ns + self.stream_period_ns
            self._send(wsg.encode_reply(wsg.Command.GET_FORCE, wsg.Status.E_SUCCESS, struct.pack("<f", force_n)))

    def _send(self, message: bytes) -> None:
        if self._corrupt:
            self._corrupt -= 1
            message = message[:-1] + bytes([message[-1] ^ 0xFF])
        self.device.write(message)

    def _answer(self, m: wsg.Message, now_ns: int, force_n: float) -> None:
        C, S = wsg.Command, wsg.Status
        sizes = {C.LOOP: None, C.DISCONNECT: 0, C.ACK_FAST_STOP: 3, C.GRASP: 8, C.RELEASE: 8, C.SET_FORCE_LIMIT: 4,
                 C.GET_FORCE_LIMIT: 0, C.GET_GRASPING_STATE: 3, C.GET_FORCE: 3}
        if m.id not in sizes:
            self._send(wsg.encode_reply(m.id, S.E_CMD_UNKNOWN))
            return
        size = sizes[m.id]
        if size is not None and len(m.payload) != size:
            self._send(wsg.encode_reply(m.id, S.E_CMD_FORMAT_ERROR))
            return
        if m.id == C.LOOP:
            self._send(wsg.encode_reply(m.id, S.E_SUCCESS, m.payload))
        elif m.id == C.ACK_FAST_STOP:
            ok = m.payload == wsg.ACK_PAYLOAD
            self._send(wsg.encode_reply(m.id, S.E_SUCCESS if ok else S.E_CMD_FORMAT_ERROR))
        elif m.id in (C.GRASP, C.RELEASE):
            width, _ = struct.unpack("<ff", m.payload)
            if self._pending is not None:
                self._send(wsg.encode_reply(m.id, S.E_ALREADY_RUNNING))
                return
            if m.id == C.GRASP:
                found = abs(width - self.part_width_mm) <= self.travel_mm
                final = wsg.GraspingState.HOLDING if found else wsg.GraspingState.NO_PART_FOUND
                self.state = wsg.GraspingState.GRASPING
            else:
                final, self.state = wsg.GraspingState.IDLE, wsg.GraspingState.RELEASING
            self._pending = (m.id, now_ns + self.GRASP_TIME_NS, final)
            self._send(wsg.encode_reply(m.id, S.E_CMD_PENDING))
        elif m.id == C.SET_FORCE_LIMIT:
            (force,) = struct.unpack("<f", m.payload)
            lo, hi = wsg.FORCE_RANGE_N
            if not lo <= force <= hi:
                self._send(wsg.encode_reply(m.id, S.E_RANGE_ERROR))
                return
            self.force_limit_n = force
            self._send(wsg.encode_reply(m.id, S.E_SUCCESS))
        elif m.id == C.GET_FORCE_LIMIT:
            self._send(wsg.encode_reply(m.id, S.E_SUCCESS, struct.pack("<f", self.force_limit_n)))
        elif m.id == C.GET_GRASPING_STATE:
            self._send(wsg.encode_reply(m.id, S.E_SUCCESS, bytes([self.state])))
        elif m.id == C.GET_FORCE:
            flags, period_ms = struct.unpack("<BH", m.payload)
            self.stream_period_ns = period_ms * 1_000_000 if flags & wsg.AUTO_UPDATE and period_ms else 0
            self._next_stream_ns = now_ns + self.stream_period_ns
            self._send(wsg.encode_reply(m.id, S.E_SUCCESS, struct.pack("<f", force_n)))
        else:  # disconnect: the host leaves; a new one starts afresh
            self._send(wsg.encode_reply(m.id, S.E_SUCCESS))
            self.stream_period_ns = 0

    def close(self) -> None:
        self.device.close()
