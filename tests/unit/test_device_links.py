"""Back-ends against their emulators through real ptys and loopback UDP.

The back-ends' clock is simulated (integer ns advanced one sample period per
tick), so staleness and back-off are checked exactly; bytes still move through the
kernel, so each tick waits (select, ≤ 20 ms) for the back-end's descriptor.
"""

from __future__ import annotations

import select
import socket
from typing import Callable

import numpy as np
import pytest

from slipstack.lib.protocols.framed import FramedFormat
from slipstack.nodes.devices import LinkStatus
from slipstack.lib.samples import FtSample, TactileSample
from slipstack.nodes.devices.backends import Backend, backend_from_url
from slipstack.nodes.devices.emulators import (
    BotaEmulator, Dsacon32Emulator, FramedEmulator, M1616Emulator, RdtUdpServer, RobotiqEmulator,
)

MS = 1_000_000


class Rig:
    """An emulator, a back-end and a simulated clock ticking once per sample period."""

    def __init__(self, emulator, backend: Backend, emit: Callable[[object, int], object], period_ms: float) -> None:
        self.emulator, self.backend, self.emit = emulator, backend, emit
        self.period_ns = int(period_ms * MS)
        self.now = 1_000 * MS
        self.k = 0  # value index of the next emitted sample
        self.samples: list = []
        backend.open(self.now)

    def tick(self, emit: bool = True, wait_s: float = 0.02) -> list:
        self.now += self.period_ns
        if emit:
            self.emit(self.emulator, self.k)
            self.k += 1
        fd = self.backend.fileno()
        if fd is not None:
            select.select([fd], [], [], wait_s)
        got = self.backend.poll(self.now)
        self.samples += got
        return got

    def run_until(self, cond: Callable[[], bool], max_ticks: int = 200, **kw) -> None:
        for _ in range(max_ticks):
            self.tick(**kw)
            if cond():
                return
        raise AssertionError(f"condition not met in {max_ticks} ticks; counters {self.backend.counters}")

    def close(self) -> None:
        self.backend.close()
        self.emulator.close()


def ft_values(k: int) -> tuple[list[float], list[float]]:
    return [k / 100, -k / 100, 1.0], [k / 1000, 0.0, -0.5]


def tactile_values(k: int, rows: int = 16, cols: int = 16) -> np.ndarray:
    return ((np.arange(rows * cols).reshape(rows, cols) * 7 + k) % 4096).astype(np.uint16)


def emit_ft(emu, k):
    emu.send_ft(*ft_values(k))


def emit_tactile(emu, k):
    emu.send_tactile(tactile_values(k))


FRAMED = FramedFormat(header=b"\xa5\x5a", rows=16, cols=16, dtype="u12", endian="le", checksum="crc16")

SERIAL_CASES = {
    "robotiq": (lambda: RobotiqEmulator(), "robotiq://{}?stop_ms=20", emit_ft, 10.0),
    "bota": (lambda: BotaEmulator(), "bota://{}", emit_ft, 5.0),
    "dsacon32": (lambda: Dsacon32Emulator(), "dsacon32://{}?fps=100", emit_tactile, 10.0),
    "dsacon32-rle": (lambda: Dsacon32Emulator(), "dsacon32://{}?fps=100&rle=1", emit_tactile, 10.0),
    "m1616": (lambda: M1616Emulator(), "m1616://{}?rate_hz=100", emit_tactile, 10.0),
    "framed": (lambda: FramedEmulator(FRAMED),
               "framed://{}?header=a55a&dtype=u12&checksum=crc16&rate_hz=100", emit_tactile, 10.0),
}


def make_rig(name: str) -> Rig:
    make_emu, url, emit, period_ms = SERIAL_CASES[name]
    emu = make_emu()
    return Rig(emu, backend_from_url(url.format(emu.path)), emit, period_ms)


def value_index(sample) -> int:
    """Recover k from a sample built by ft_values / tactile_values."""
    if isinstance(sample, FtSample):
        return round(sample.force_n[0] * 100)
    return int(sample.counts[0, 0])


@pytest.mark.parametrize("name", sorted(SERIAL_CASES))
def test_serial_backend_streams_from_its_emulator(name: str) -> None:
    rig = make_rig(name)
    try:
        rig.run_until(lambda: len(rig.samples) >= 12)
        ks = [value_index(s) for s in rig.samples]
        assert ks == list(range(ks[0], ks[0] + len(ks)))  # consecutive: nothing lost
        for s, k in zip(rig.samples, ks):
            if isinstance(s, FtSample):
                f, t = ft_values(k)
                np.testing.assert_allclose(s.force_n, f, atol=1e-6)
                np.testing.assert_allclose(s.torque_nm, t, atol=1e-6)
            else:
                assert isinstance(s, TactileSample) and s.counts.dtype == np.uint16
                np.testing.assert_array_equal(s.counts, tactile_values(k))
        c = rig.backend.counters
        assert rig.backend.status is LinkStatus.OK
        assert (c["crc_errors"], c["handshake_failures"], c["reconnects"]) == (0, 0, 0)
        assert c["frames"] == len(rig.samples)
    finally:
        rig.close()


def test_robotiq_handshake_stops_power_up_stream_and_checks_echo() -> None:
    rig = make_rig("robotiq")
    try:
        assert rig.emulator.streaming  # streaming at power-up
        rig.run_until(lambda: len(rig.samples) >= 1)
        c = rig.backend.counters
        assert c["flushed_bytes"] >= 16  # power-up frames discarded while stopping
        assert c["rejected_bytes"] == 0  # echo found, every later byte in a frame
        assert rig.emulator.streaming
    finally:
        rig.close()


def test_dsacon32_handshake_and_stop_on_close() -> None:
    rig = make_rig("dsacon32-rle")
    try:
        rig.run_until(lambda: len(rig.samples) >= 2)
        (info,) = rig.backend.matrices
        assert (info.cells_x, info.cells_y) == (16, 16) and info.texel_width_m == pytest.approx(1.25e-3)
        assert rig.emulator.acquiring and rig.emulator.rle and rig.emulator.fps == 100
        # the power-up banner went before the port was opened (pyserial flushes input
        # at open); frame timestamps are 10 ms apart (fps 100)
        assert rig.backend.counters["rejected_bytes"] == 0
        assert rig.samples[1].device_time_s - rig.samples[0].device_time_s == pytest.approx(0.01)
        rig.backend.close()
        for _ in range(50):
            select.select([rig.emulator.device.fileno()], [], [], 0.01)
            rig.emulator.service()
            if not rig.emulator.acquiring:
                break
        assert not rig.emulator.acquiring
    finally:
        rig.emulator.close()


def test_silent_device_is_stale_within_three_periods() -> None:
    rig = make_rig("bota")
    try:
        rig.run_until(lambda: len(rig.samples) >= 3)
        last = rig.now
        states = []
        for _ in range(6):  # the device stays plugged but goes silent
            rig.now += rig.period_ns // 2
            rig.backend.poll(rig.now)
            states.append((rig.now - last, rig.backend.status))
        stale_at = min(dt for dt, s in states if s is LinkStatus.STALE)
        assert stale_at <= 3 * rig.period_ns
        assert all(s is LinkStatus.OK for dt, s in states if dt <= 2.5 * rig.period_ns)
        assert rig.backend.next_deadline_ns() is None  # nothing to wake up for but input
        rig.run_until(lambda: rig.backend.status is LinkStatus.OK)
    finally:
        rig.close()


@pytest.mark.parametrize("name", ["robotiq", "dsacon32", "m1616"])
def test_serial_unplug_replug(name: str) -> None:
    rig = make_rig(name)
    try:
        rig.run_until(lambda: len(rig.samples) >= 3)
        last_sample = rig.now
        rig.emulator.unplug()
        rig.run_until(lambda: rig.backend.status is LinkStatus.DISCONNECTED, max_ticks=3)
        lost_at = rig.now  # a pty read fails at once (EIO): disconnected, not just stale
        assert lost_at - last_sample <= 3 * rig.period_ns
        assert rig.backend.fileno() is None
        assert rig.backend.next_deadline_ns() == lost_at + 50 * MS  # first retry after backoff_ms
        rig.run_until(lambda: rig.now >= lost_at + 120 * MS)  # retry at +50 ms fails
        assert rig.backend.next_deadline_ns() == lost_at + 150 * MS  # then 100 ms more
        assert rig.backend.counters["reconnects"] == 0
        rig.emulator.replug()
        n = len(rig.samples)
        rig.run_until(lambda: len(rig.samples) >= n + 3)
        assert rig.backend.counters["reconnects"] == 1
        assert rig.backend.status is LinkStatus.OK
    finally:
        rig.close()


def make_rdt_rig() -> Rig:
    server = RdtUdpServer()
    backend = backend_from_url(f"{server.url}?rate_hz=1000")
    return Rig(server, backend, emit_ft, 1.0)


def test_rdt_streams_and_counts_gaps() -> None:
    rig = make_rdt_rig()
    try:
        rig.run_until(lambda: len(rig.samples) >= 5)
        rig.emulator.lose(3)
        rig.run_until(lambda: len(rig.samples) >= 10)
        seqs = [s.device_seq for s in rig.samples]
        assert seqs == list(range(1, 6)) + list(range(9, 9 + len(seqs) - 5))
        assert rig.backend.counters["gaps"] == 3
        ks = [value_index(s) for s in rig.samples]
        assert ks[5] - ks[4] == 4  # three sensor ticks were not delivered
        np.testing.assert_allclose(rig.samples[-1].torque_nm, ft_values(ks[-1])[1], atol=1e-6)
        assert rig.backend.status is LinkStatus.OK
        rig.backend.close()  # sends the RDT stop request
        rig.emulator.service()
        assert not rig.emulator.streaming
    finally:
        rig.close()


def test_rdt_unplug_replug() -> None:
    rig = make_rdt_rig()
    try:
        rig.run_until(lambda: len(rig.samples) >= 3)
        last_sample = rig.now
        rig.emulator.unplug()
        rig.run_until(lambda: rig.backend.status is not LinkStatus.OK, max_ticks=3, wait_s=0.002)
        assert rig.now - last_sample <= 3 * rig.period_ns
        assert rig.backend.status is LinkStatus.STALE  # UDP: silence first
        # a re-request 50 ms later meets an ICMP port-unreachable -> disconnected
        rig.run_until(lambda: rig.backend.status is LinkStatus.DISCONNECTED, max_ticks=100, wait_s=0.002)
        rig.emulator.replug()
        n = len(rig.samples)
        rig.run_until(lambda: len(rig.samples) >= n + 3, max_ticks=400, wait_s=0.002)
        c = rig.backend.counters
        assert c["reconnects"] >= 1 and c["requests"] >= 3
        assert rig.samples[n].device_seq == 1  # a new request restarts rdt_sequence
        assert rig.backend.status is LinkStatus.OK
    finally:
        rig.close()


def test_rdt_that_was_refused_and_then_never_answers_stays_disconnected() -> None:
    """The hardware launch with a wrong RDT address: requests meet a port-unreachable now
    and then, and silence otherwise. A socket reopened after a refusal that stays silent is
    not a device that went quiet: the status stays ``disconnected`` until data comes (was:
    ``stale`` between refusals, so the monitor, which samples the status once a second,
    rarely saw the driver down and did not name it in the summary)."""
    rig = make_rdt_rig()
    silent = None
    try:
        rig.emulator.unplug()
        rig.run_until(lambda: rig.backend.status is LinkStatus.DISCONNECTED, max_ticks=100, wait_s=0.002)
        silent = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # takes the requests, never answers
        silent.bind(rig.emulator.address)
        requests = rig.backend.counters["requests"]
        seen = set()
        for _ in range(300):  # past the back-off: the link reopens and asks again
            rig.tick(wait_s=0.002)
            seen.add(rig.backend.status)
        assert rig.backend.counters["requests"] > requests and seen == {LinkStatus.DISCONNECTED}, seen
        silent.close()
        silent = None
        rig.emulator.replug()
        rig.run_until(lambda: rig.backend.status is LinkStatus.OK, max_ticks=400, wait_s=0.002)
    finally:
        if silent is not None:
            silent.close()
        rig.close()
