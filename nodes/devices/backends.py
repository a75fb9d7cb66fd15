"""Driver back-ends chosen by URL: bytes from a device → decoded samples.

URL grammar (query parameters optional unless marked)::

More in docs/modules.md, `nodes/devices/backends.py`.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from enum import Enum
from typing import ClassVar, Union
from urllib.parse import parse_qs, urlsplit

import numpy as np

from slipstack.lib.config import ConfigTable
from slipstack.lib.errors import ConfigError
from slipstack.lib.protocols import ati_rdt, bota, dsacon32, m1616, robotiq, wsg
from slipstack.lib.protocols.crc import compile_kernels as compile_crc_kernels
from slipstack.lib.protocols.framed import FramedCodec, FramedFormat
from slipstack.lib.protocols.stream import Deframer
from slipstack.lib.samples import MAX_SAMPLE_RATE_HZ, FtSample, GripperSample, TactileSample
from slipstack.lib.sequence import SeqTracker

from . import Freshness, LinkStatus
from .serial_link import SerialLink
from .sim_link import SIM_PREFIX, SimLink, is_simulated, sim_twin
from .tcp_link import TcpLink
from .udp_link import UdpLink

__all__ = [
    "Sample", "Backend", "RdtBackend", "RobotiqBackend", "WsgBackend",
    "BotaBackend", "Dsacon32Backend", "FramedBackend", "backend_from_url", "SCHEMES",
]


Sample = Union[FtSample, TactileSample, GripperSample]

DEFAULT_STALE_PERIODS = 2.5
"""Default stale limit (``stale_ms`` not given), in nominal sample periods, but at least
:data:`MIN_DEFAULT_STALE_MS`."""
MIN_DEFAULT_STALE_MS = 2.5
"""Floor of the default stale limit (ms): a device faster than 1 kHz is read in bursts by
a host that wakes up about once a millisecond (and the rig sends its samples so); 2.5
periods of a 7 kHz sensor (0.36 ms) flagged every gap between two bursts as stale."""


class Backend(ABC):
    """Common state machine: link, staleness, counters (module docstring)."""

    kind: ClassVar[str]  # "ft", "tactile" or "gripper"
    default_rate_hz: ClassVar[float] = 100.0

    def __init__(self, url: str, params: ConfigTable) -> None:
        self.url = url
        self.rate_hz = params.real("rate_hz", float(self.default_rate_hz), lo=0.0, lo_open=True, hi=MAX_SAMPLE_RATE_HZ)
        default_stale_ms = max(DEFAULT_STALE_PERIODS * 1e3 / self.rate_hz, MIN_DEFAULT_STALE_MS)
        self.stale_after_s = params.real("stale_ms", default_stale_ms) / 1e3
        self.backoff_min_s = params.real("backoff_ms", 50.0) / 1e3
        self.backoff_max_s = params.real("backoff_max_ms", 2000.0) / 1e3
        self.status = LinkStatus.DISCONNECTED
        self._silent_since_closed = False  # the link was closed and no data came since
        self._samples = Freshness(self.stale_after_s)
        self._own = dict(frames=0, crc_errors=0, rejected_bytes=0, gaps=0, flushed_bytes=0,
                         handshake_failures=0, ignored_packets=0, bad_frames=0)

    # --- interface used by the node wrapper -------------------------------------
    def open(self, now_ns: int) -> None:
        """Start connecting; never raises for an absent device (status says so)."""
        self._link.open(now_ns)
        self._update_status(now_ns)

    def fileno(self) -> int | None:
        """Descriptor to wait on, None while disconnected; re-read after every poll."""
        return self._link.fileno()

    def close(self) -> None:
        """Stop the device stream if possible and release the port/socket."""
        if self._link.is_open:
            self._goodbye()
        self._link.close()
        self.status = LinkStatus.DISCONNECTED

    def poll(self, now_ns: int) -> list[Sample]:
        """Read what is available, advance the handshake, return decoded samples."""
        samples = self._poll(now_ns)
        if samples:
            self._samples.touch(now_ns)
        self._update_status(now_ns)
        return samples

    def next_deadline_ns(self) -> int | None:
        """Latest time to call poll() again without input (stale, retry or handshake timer)."""
        due = self._link.next_attempt_ns()  # called between every two simulated instants: no temporaries
        if self.status is LinkStatus.OK:
            stale_at = self._samples.deadline_ns()
            if stale_at is not None and (due is None or stale_at < due):
                due = stale_at
        timer = self._timer_ns()
        if timer is not None and (due is None or timer < due):
            due = timer
        return due

    @property
    def last_error(self) -> str:
        """Why the link last failed to open or was lost ("" if it never failed)."""
        return self._link.last_error

    @property
    def counters(self) -> dict[str, int]:
        """Snapshot of the counters (module docstring)."""
        c = dict(self._own)
        c["reconnects"] = self._link.reconnects
        return c

    # --- for subclasses ---------------------------------------------------------
    _link: Union[SerialLink, UdpLink, TcpLink, SimLink]

    @abstractmethod
    def _poll(self, now_ns: int) -> list[Sample]: ...

    def _timer_ns(self) -> int | None:
        return None

    def _goodbye(self) -> None:
        """Last words to the device before close (e.g. stop streaming)."""

    def _update_status(self, now_ns: int) -> None:
        """``disconnected`` while the link is closed and, once it was, until data comes again
        (a UDP socket reopens at once, and stays silent at a wrong address); ``stale``: open
        and silent otherwise; ``ok``."""
        if not self._link.is_open:
            self.status = LinkStatus.DISCONNECTED
            self._silent_since_closed = True
        elif self._samples.is_stale(now_ns):
            self.status = LinkStatus.DISCONNECTED if self._silent_since_closed else LinkStatus.STALE
        else:
            self._silent_since_closed = False
            self.status = LinkStatus.OK


class _SerialBackend(Backend):
    """A back-end on a serial port with a deframer (subclasses add handshakes)."""

    default_baud: ClassVar[int]

    def __init__(self, url: str, path: str, params: ConfigTable) -> None:
        super().__init__(url, params)
        compile_crc_kernels()  # the serial protocols frame CRCs: loaded before the first frame
        baud = params.integer("baud", self.default_baud, lo=1)
        self._link = SerialLink(path, baudrate=baud, stale_after_s=self.stale_after_s,
                                backoff_min_s=self.backoff_min_s, backoff_max_s=self.backoff_max_s,
                                on_open=self._on_open)
        self._deframer: Deframer | None = None

    @property
    def counters(self) -> dict[str, int]:
        c = super().counters
        if self._deframer is not None:
            d = self._deframer.counts
            c["crc_errors"] += d.crc_errors
            c["rejected_bytes"] += d.rejected_bytes
        c["write_shortfall"] = self._link.write_shortfall
        return c

    def _on_open(self, now_ns: int) -> None:
        if self._deframer is not None:
            self._deframer.reset()

    def _write(self, data: bytes, now_ns: int) -> None:
        self._link.write(data, now_ns)


class RobotiqBackend(_SerialBackend):
    """Robotiq FT 300: stop any stream (0xFF burst), request streaming, check the echo."""

    kind = "ft"
    default_rate_hz = robotiq.RATE_HZ
    default_baud = robotiq.BAUDRATE
    _STOPPING, _REQUESTING, _STREAMING = range(3)
    _FF_BURST = bytes([robotiq.STOP_BYTE]) * 16
    _FF_EVERY_NS = 8_000_000  # 16 bytes per 8 ms ≈ the 19200-baud line rate

    def __init__(self, url: str, path: str, params: ConfigTable) -> None:
        super().__init__(url, path, params)
        self.stop_ns = int(params.real("stop_ms", 500.0) * 1e6)
        self.echo_ns = int(params.real("echo_ms", 200.0) * 1e6)
        self._deframer = Deframer(robotiq.StreamCodec())
        self._state = self._STOPPING
        self._timer = 0
        self._next_ff = 0
        self._rx = bytearray()

    def _on_open(self, now_ns: int) -> None:
        super()._on_open(now_ns)
        self._state = self._STOPPING
        self._timer = now_ns + self.stop_ns
        self._next_ff = now_ns

    def _timer_ns(self) -> int | None:
        if not self._link.is_open or self._state == self._STREAMING:
            return None
        return min(self._timer, self._next_ff) if self._state == self._STOPPING else self._timer

    def _poll(self, now_ns: int) -> list[Sample]:
        data = self._link.read(now_ns)
        if not self._link.is_open:
            return []
        if self._state == self._STOPPING:
            self._own["flushed_bytes"] += len(data)
            if now_ns >= self._timer:
                self._rx.clear()
                self._write(robotiq.START_STREAM_REQUEST, now_ns)
                self._state, self._timer = self._REQUESTING, now_ns + self.echo_ns
            elif now_ns >= self._next_ff:
                self._write(self._FF_BURST, now_ns)
                self._next_ff = now_ns + self._FF_EVERY_NS
            return []
        if self._state == self._REQUESTING:
            self._rx += data
            i = self._rx.find(robotiq.START_STREAM_ECHO)
            if i < 0:
                if now_ns >= self._timer:
                    self._own["handshake_failures"] += 1
                    self._own["rejected_bytes"] += len(self._rx)
                    self._on_open(now_ns)
                return []
            self._own["rejected_bytes"] += i
            data = bytes(self._rx[i + len(robotiq.START_STREAM_ECHO):])
            self._state = self._STREAMING
        frames = self._deframer.feed(data)
        self._own["frames"] += len(frames)
        return [FtSample(now_ns, f.force_n, f.torque_nm) for f in frames]


class BotaBackend(_SerialBackend):
    """Bota serial F/T: sends ``R`` (run) on open, then decodes the stream."""

    kind = "ft"
    default_rate_hz = bota.RATE_HZ
    default_baud = bota.BAUDRATE

    def __init__(self, url: str, path: str, params: ConfigTable) -> None:
        super().__init__(url, path, params)
        self._deframer = Deframer(bota.StreamCodec())

    def _on_open(self, now_ns: int) -> None:
        super()._on_open(now_ns)
        self._write(bota.RUN_COMMAND, now_ns)

    def _poll(self, now_ns: int) -> list[Sample]:
        frames = self._deframer.feed(self._link.read(now_ns))
        self._own["frames"] += len(frames)
        return [FtSample(now_ns, f.force_n, f.torque_nm, None, f.timestamp_us * 1e-6, f.status) for f in frames]


class FramedBackend(_SerialBackend):
    """Push-only framed tactile stream (generic format or the M1616 preset)."""

    kind = "tactile"
    default_baud = 115200

    def __init__(self, url: str, path: str, params: ConfigTable, fmt: FramedFormat) -> None:
        super().__init__(url, path, params)
        self.format = fmt
        self._deframer = Deframer(FramedCodec(fmt))

    def _poll(self, now_ns: int) -> list[Sample]:
        frames = self._deframer.feed(self._link.read(now_ns))
        self._own["frames"] += len(frames)
        return [TactileSample(now_ns, counts) for counts in frames]


class _DsaState(Enum):
    STOPPING = "stopping"
    QUERYING = "querying"
    CONFIGURING = "configuring"
    STREAMING = "streaming"


class Dsacon32Backend(_SerialBackend):
    """DSACON32: stop push mode, query matrix info 0..matrix, start push mode."""

    kind = "tactile"
    default_baud = dsacon32.BAUDRATE

    def __init__(self, url: str, path: str, params: ConfigTable) -> None:
        self.fps = params.integer("fps", 30, lo=1, hi=65535)
        self.default_rate_hz = float(self.fps)
        super().__init__(url, path, params)
        self.rle = params.flag("rle", False)
        self.matrix = params.integer("matrix", 0, lo=0)
        self.reply_ns = int(params.real("reply_ms", 500.0) * 1e6)
        self._codec = dsacon32.PacketCodec(allow_empty=False)
        self._deframer = Deframer(self._codec)
        self.matrices: list[dsacon32.MatrixInfo] = []
        # cells before our matrix, cells in a frame, our (rows, cols): set by the handshake
        self._frame_layout = (0, 0, (0, 0))
        self._state = _DsaState.STOPPING
        self._timer = 0

    def _on_open(self, now_ns: int) -> None:
        super()._on_open(now_ns)
        self.matrices = []
        self._send(dsacon32.encode_configure_acquisition(0, 0), _DsaState.STOPPING, now_ns)

    def _send(self, packet: bytes, state: _DsaState, now_ns: int) -> None:
        self._write(packet, now_ns)
        self._state, self._timer = state, now_ns + self.reply_ns

    def _timer_ns(self) -> int | None:
        if not self._link.is_open or self._state is _DsaState.STREAMING:
            return None
        return self._timer

    def _goodbye(self) -> None:
        self._link.write(dsacon32.encode_configure_acquisition(0, 0), 0)

    def _poll(self, now_ns: int) -> list[Sample]:
        packets = self._deframer.feed(self._link.read(now_ns))
        out: list[Sample] = []
        for p in packets:
            sample = self._handle(p, now_ns)
            if sample is not None:
                out.append(sample)
        if self._link.is_open and self._state is not _DsaState.STREAMING and now_ns >= self._timer:
            self._own["handshake_failures"] += 1
            self._on_open(now_ns)
        self._own["frames"] += len(out)
        return out

    def _handle(self, p: dsacon32.Packet, now_ns: int) -> TactileSample | None:
        st = self._state
        if p.id == dsacon32.PacketId.FRAME and st is _DsaState.STREAMING:
            n_before, n_cells, shape = self._frame_layout
            frame = dsacon32.decode_frame_payload(p.payload, n_cells)
            if frame is None:
                self._own["bad_frames"] += 1
                return None
            return TactileSample(now_ns, frame.counts[n_before:].reshape(shape), frame.timestamp_ms * 1e-3)
        if p.id == dsacon32.PacketId.CONFIGURE_ACQUISITION and st in (_DsaState.STOPPING, _DsaState.CONFIGURING):
            if dsacon32.decode_error_reply(p.payload) != 0:
                self._own["handshake_failures"] += 1
                self._on_open(now_ns)
            elif st is _DsaState.STOPPING:
                self._send(dsacon32.encode_query_matrix_info(0), _DsaState.QUERYING, now_ns)
            else:
                self._state = _DsaState.STREAMING
            return None
        if p.id == dsacon32.PacketId.MATRIX_INFO and st is _DsaState.QUERYING:
            info = dsacon32.decode_matrix_info(p.payload)
            if info is None or info.error != 0 or info.cells_x * info.cells_y == 0:
                self._own["handshake_failures"] += 1
                self._on_open(now_ns)
                return None
            self.matrices.append(info)
            if len(self.matrices) <= self.matrix:
                self._send(dsacon32.encode_query_matrix_info(len(self.matrices)), _DsaState.QUERYING, now_ns)
            else:
                n = sum(m.cells_x * m.cells_y for m in self.matrices)
                ours = self.matrices[-1]
                self._frame_layout = (n - ours.cells_x * ours.cells_y, n, (ours.cells_y, ours.cells_x))
                self._codec.max_length = self._codec.header_length + max(64, 5 + 2 * n) + 2
                flags = dsacon32.AcquisitionFlags.ACQUIRE | dsacon32.AcquisitionFlags.INTERNAL_TRIGGER
                if self.rle:
                    flags |= dsacon32.AcquisitionFlags.RLE
                self._send(dsacon32.encode_configure_acquisition(flags, self.fps), _DsaState.CONFIGURING, now_ns)
            return None
        self._own["ignored_packets"] += 1
        return None


class RdtBackend(Backend):
    """ATI RDT over UDP: start request on open, re-request after backoff_ms of silence
    (an ICMP refusal then marks it disconnected), count rdt_sequence gaps.

    Only the sensor's datagrams arrive (the socket is connected to the url's
    host:port, so the kernel drops every other source), and a record whose counters
    do not continue the requested stream is dropped and counted
    (``implausible_records``); with no plausible record for backoff_ms the stream is
    requested again and restarts."""

    kind = "ft"
    default_rate_hz = ati_rdt.RATE_HZ

    def __init__(self, url: str, host: str, port: int, params: ConfigTable) -> None:
        super().__init__(url, params)
        self.counts_per_force = params.real("cpf", 1e6, lo=0.0, lo_open=True)
        self.counts_per_torque = params.real("cpt", 1e6, lo=0.0, lo_open=True)
        self._counts_per_unit = np.array([self.counts_per_force] * 3 + [self.counts_per_torque] * 3)
        self._link = UdpLink(host, port, stale_after_s=self.stale_after_s, backoff_min_s=self.backoff_min_s,
                             backoff_max_s=self.backoff_max_s, on_open=self._request)
        self._own["requests"] = 0
        self._own["implausible_records"] = 0
        self._last: ati_rdt.RdtRecord | None = None
        self._rdt_sequence = SeqTracker()
        self._last_request_ns = 0

    def _request(self, now_ns: int) -> None:
        self._last = None
        self._rdt_sequence.forget()
        self._last_request_ns = now_ns
        self._own["requests"] += 1
        self._link.send(ati_rdt.encode_request(ati_rdt.Command.REALTIME, 0), now_ns)

    def _goodbye(self) -> None:
        self._link.send(ati_rdt.encode_request(ati_rdt.Command.STOP, 0), 0)

    def _timer_ns(self) -> int | None:
        return self._rerequest_at() if self._link.is_open else None

    def _poll(self, now_ns: int) -> list[Sample]:
        out: list[Sample] = []
        per_unit = self._counts_per_unit
        for datagram in self._link.recv(now_ns):
            records = ati_rdt.decode_records(datagram)
            if records is None:
                self._own["rejected_bytes"] += len(datagram)
                continue
            for r in records:
                if not ati_rdt.follows(self._last, r):
                    self._own["implausible_records"] += 1
                    continue
                self._own["gaps"] += self._rdt_sequence.update(r.rdt_sequence)
                self._last = r
                wrench = r.counts / per_unit  # N, N·m: force and torque are views of it
                out.append(FtSample(now_ns, wrench[:3], wrench[3:], r.rdt_sequence, None, r.status))
        self._own["frames"] += len(out)
        if not out and self._link.is_open and now_ns >= self._rerequest_at():
            self._request(now_ns)  # silent for backoff_ms: the sensor may have rebooted
        return out

    def _rerequest_at(self) -> int:
        """Re-request after backoff_ms without samples (and since the last request);
        a short stale spell must not restart the stream (and its sequence)."""
        quiet = self._link.backoff.min_ns
        last = self._samples.last_ns
        return max(self._last_request_ns, last if last is not None else 0) + quiet


class _WsgStep(Enum):
    ACK = "ack"
    STATE = "state"
    FORCE_LIMIT = "force-limit"
    SET_GRASP_FORCE = "set-grasp-force"
    GRASP = "grasp"
    STREAM = "stream"
    READY = "ready"


class WsgBackend(Backend):
    """Weiss WSG 50 over TCP (docs/protocols.md §9): on connect, acknowledge a fast stop, read
    the grasping state, take the force limit it holds (or set ``grasp_n`` and grasp the part
    of ``width_mm``), then ask for the grasping force every sample period; the readings are
    its samples. :meth:`set_force` sends the grasping force limit, one command at a time, the
    newest value waiting for the reply to the one before.

    A reply that does not come within ``reply_ms`` is counted (``reply_timeouts``); three in
    a row, or a handshake that stalls, close the link and reconnect. Replies with a status
    other than success are counted (``command_errors``) and said (``last_error``); malformed
    ones are counted as the deframer's ``crc_errors``, ``bad_frames`` (a reply too short for
    its command) or ``ignored_packets`` (an answer to nothing asked)."""

    kind = "gripper"
    default_rate_hz = 100.0
    _TIMEOUTS_TO_RECONNECT = 3

    def __init__(self, url: str, host: str, port: int, params: ConfigTable) -> None:
        super().__init__(url, params)
        self.reply_ns = int(params.real("reply_ms", 100.0, lo=0.0, lo_open=True) * 1e6)
        self.width_mm = params.real("width_mm", 20.0, lo=0.0)
        self.speed_mm_s = params.real("speed_mm_s", 20.0, lo=0.0, lo_open=True)
        self.grasp_n = params.real("grasp_n", 10.0, lo=wsg.FORCE_RANGE_N[0], hi=wsg.FORCE_RANGE_N[1])
        self.period_ms = max(1, round(1e3 / self.rate_hz))
        self._link = TcpLink(host, port, stale_after_s=self.stale_after_s, backoff_min_s=self.backoff_min_s,
                             backoff_max_s=self.backoff_max_s, on_open=self._on_open)
        self._deframer = Deframer(wsg.MessageCodec())
        for name in ("reply_timeouts", "command_errors", "commands_sent", "commands_acknowledged"):
            self._own[name] = 0
        self.state = "unknown"
        self.force_limit_n = math.nan  # the newest limit the gripper acknowledged (N)
        self._step = _WsgStep.ACK
        self._waiting: tuple[int, int] | None = None  # (command id, reply deadline ns)
        self._sent_force = math.nan
        self._wanted_force: float | None = None
        self._timeouts = 0
        self._polled_ns = 0
        self.command_error = ""

    @property
    def counters(self) -> dict[str, int]:
        c = super().counters
        d = self._deframer.counts
        c["crc_errors"] += d.crc_errors
        c["rejected_bytes"] += d.rejected_bytes
        c["write_shortfall"] = self._link.write_shortfall
        return c

    @property
    def ready(self) -> bool:
        """The handshake is done: force commands go out."""
        return self._step is _WsgStep.READY

    def set_force(self, force_n: float, now_ns: int) -> None:
        """Ask for grasping force limit ``force_n`` (N; the caller bounds it to
        :data:`~slipstack.lib.protocols.wsg.FORCE_RANGE_N`); sent once the link is ready and
        no command waits for its reply, the newest value winning."""
        self._wanted_force = force_n
        self._send_wanted(now_ns)

    def _on_open(self, now_ns: int) -> None:
        self._deframer.reset()
        self._waiting, self._timeouts = None, 0
        self.state = "unknown"
        self._ask(wsg.ack_fast_stop(), _WsgStep.ACK, now_ns)

    def _ask(self, message: bytes, step: _WsgStep, now_ns: int) -> None:
        self._step = step
        self._send(message, now_ns)

    def _send(self, message: bytes, now_ns: int) -> None:
        self._link.write(message, now_ns)
        self._waiting = (message[3], now_ns + self.reply_ns)

    def _send_wanted(self, now_ns: int) -> None:
        force = self._wanted_force
        if self._step is not _WsgStep.READY or self._waiting is not None or force is None or force == self._sent_force:
            return
        self._send(wsg.set_force_limit(force), now_ns)
        self._sent_force = force
        self._own["commands_sent"] += 1

    def _timer_ns(self) -> int | None:
        if not self._link.is_open:
            return None
        if not getattr(self._link, "connected", True):  # a TCP connect under way: look again in a millisecond
            return self._polled_ns + 1_000_000
        return None if self._waiting is None else self._waiting[1]

    def _goodbye(self) -> None:
        self._link.write(wsg.encode_message(wsg.Command.DISCONNECT), 0)

    def _poll(self, now_ns: int) -> list[Sample]:
        self._polled_ns = now_ns
        out: list[Sample] = []
        for message in self._deframer.feed(self._link.read(now_ns)):
            sample = self._handle(message, now_ns)
            if sample is not None:
                out.append(sample)
        if self._waiting is not None and now_ns >= self._waiting[1] and self._link.is_open:
            self._waiting = None
            self._own["reply_timeouts"] += 1
            self._timeouts += 1
            if self._step is not _WsgStep.READY or self._timeouts >= self._TIMEOUTS_TO_RECONNECT:
                self._own["handshake_failures"] += self._step is not _WsgStep.READY
                self._link.drop(now_ns, f"the gripper did not answer within {self.reply_ns / 1e6:g} ms "
                                        f"({self._timeouts} time(s) in a row)")
            else:
                self._sent_force = math.nan  # unanswered: send it again
        self._send_wanted(now_ns)
        self._own["frames"] += len(out)
        return out

    def _handle(self, message: wsg.Message, now_ns: int) -> GripperSample | None:
        reply = wsg.reply_status(message.payload)
        if reply is None:
            self._own["bad_frames"] += 1
            return None
        status, values = reply
        if message.id == wsg.Command.GET_FORCE and self._step in (_WsgStep.STREAM, _WsgStep.READY):
            force = wsg.f32(values) if status == wsg.Status.E_SUCCESS else None
            if force is None or not math.isfinite(force):
                self._own["bad_frames"] += 1
                return None
            if self._step is _WsgStep.STREAM:
                self._answered()
                self._step = _WsgStep.READY
            return GripperSample(now_ns, force, self.force_limit_n, self.state)
        if self._waiting is None or message.id != self._waiting[0]:
            self._own["ignored_packets"] += 1
            return None
        if status == wsg.Status.E_CMD_PENDING:
            self._waiting = (message.id, now_ns + 10 * self.reply_ns)  # a grasp takes its time
            return None
        self._answered()
        if status != wsg.Status.E_SUCCESS and message.id != wsg.Command.ACK_FAST_STOP:
            self._own["command_errors"] += 1
            self.command_error = f"{wsg.Command(message.id).name}: {_status_name(status)}"
            if self._step is not _WsgStep.READY:
                self._own["handshake_failures"] += 1
                self._link.drop(now_ns, f"the gripper refused the start: {self.command_error}")
            return None
        self._advance(message.id, values, now_ns)
        return None

    def _answered(self) -> None:
        self._waiting, self._timeouts = None, 0

    def _advance(self, command: int, values: bytes, now_ns: int) -> None:
        """The handshake's next step after a successful reply to ``command``."""
        step = self._step
        if step is _WsgStep.READY:
            if command == wsg.Command.SET_FORCE_LIMIT:
                self.force_limit_n = self._sent_force
                self._own["commands_acknowledged"] += 1
        elif step is _WsgStep.ACK:
            self._ask(wsg.get_grasping_state(), _WsgStep.STATE, now_ns)
        elif step is _WsgStep.STATE:
            state = values[0] if len(values) == 1 else None
            self.state = wsg.GraspingState(state).name.lower() if state in iter(wsg.GraspingState) else "unknown"
            if state == wsg.GraspingState.HOLDING:
                self._ask(wsg.get_force_limit(), _WsgStep.FORCE_LIMIT, now_ns)
            else:
                force = self._wanted_force if self._wanted_force is not None else self.grasp_n
                self._sent_force = force
                self._ask(wsg.set_force_limit(force), _WsgStep.SET_GRASP_FORCE, now_ns)
        elif step is _WsgStep.FORCE_LIMIT:
            limit = wsg.f32(values)
            self.force_limit_n = self._sent_force = limit if limit is not None else math.nan
            self._ask(wsg.get_force(self.period_ms), _WsgStep.STREAM, now_ns)
        elif step is _WsgStep.SET_GRASP_FORCE:
            self.force_limit_n = self._sent_force
            self._ask(wsg.grasp(self.width_mm, self.speed_mm_s), _WsgStep.GRASP, now_ns)
        elif step is _WsgStep.GRASP:
            self.state = "holding"
            self._ask(wsg.get_force(self.period_ms), _WsgStep.STREAM, now_ns)


def _status_name(status: int) -> str:
    try:
        return wsg.Status(status).name
    except ValueError:
        return f"status {status}"


def _serial_path(url: str, netloc: str, path: str) -> str:
    if netloc or not path.startswith("/"):
        raise ConfigError(f"{url}: a serial back-end needs an absolute path, e.g. robotiq:///dev/ttyUSB0")
    return path


def _hex_bytes(params: ConfigTable, name: str) -> bytes:
    """Bytes given as hex digits (``a5 5a``); empty if absent."""
    text = params.text(name, "")
    try:
        return bytes.fromhex(text)
    except ValueError:
        raise params.error(name, f"must be hex digits such as 'a5 5a', got {text!r}") from None


def backend_from_url(url: str) -> Backend:
    """Construct (not open) the back-end a URL names; ConfigError if the URL is invalid.

    ``sim:`` before a URL names the device's simulated twin (``nodes/devices/sim_link.py``):
    the same back-end, on an in-process link."""
    if is_simulated(url):
        backend = backend_from_url(url[len(SIM_PREFIX):])
        backend.url = url
        backend._link = sim_twin(backend._link)
        return backend
    parts = urlsplit(url)
    scheme = parts.scheme.lower()
    query = {k: v[-1] for k, v in parse_qs(parts.query, keep_blank_values=True).items()}
    params = ConfigTable(query, "", url, from_text=True)
    if scheme == "rdt":
        if not parts.hostname:
            raise ConfigError(f"{url}: rdt needs a host, e.g. rdt://192.168.1.1:49152")
        try:
            port = parts.port or ati_rdt.PORT
        except ValueError as e:
            raise ConfigError(f"{url}: bad port") from e
        backend: Backend = RdtBackend(url, parts.hostname, port, params)
    elif scheme == "wsg":
        if not parts.hostname:
            raise ConfigError(f"{url}: wsg needs a host, e.g. wsg://192.168.1.20:1000")
        try:
            port = parts.port or wsg.DEFAULT_PORT
        except ValueError as e:
            raise ConfigError(f"{url}: bad port") from e
        backend = WsgBackend(url, parts.hostname, port, params)
    elif scheme in ("robotiq", "bota", "dsacon32"):
        cls = {"robotiq": RobotiqBackend, "bota": BotaBackend, "dsacon32": Dsacon32Backend}[scheme]
        backend = cls(url, _serial_path(url, parts.netloc, parts.path), params)
    elif scheme in ("m1616", "framed"):
        path = _serial_path(url, parts.netloc, parts.path)
        if scheme == "m1616":
            fmt = m1616.FORMAT
        else:
            fmt = FramedFormat(
                header=_hex_bytes(params, "header"), rows=params.integer("rows", 16), cols=params.integer("cols", 16),
                dtype=params.text("dtype", "u16"), endian=params.text("endian", "le"),  # type: ignore[arg-type]
                order=params.text("order", "row"), trailer=params.integer("trailer", 0),  # type: ignore[arg-type]
                checksum=params.text("checksum", "none"),  # type: ignore[arg-type]
            )
        backend = FramedBackend(url, path, params, fmt)
    else:
        raise ConfigError(f"{url}: unknown scheme {parts.scheme!r}; known: {sorted(SCHEMES)}")
    params.finish()
    return backend


#: URL schemes and the kind of sample each yields.
SCHEMES = {"rdt": "ft", "robotiq": "ft", "bota": "ft", "dsacon32": "tactile", "m1616": "tactile", "framed": "tactile",
           "wsg": "gripper"}
