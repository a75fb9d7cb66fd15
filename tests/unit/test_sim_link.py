"""Simulated devices (``sim:`` URLs): the real back-ends decode the real emulators' bytes
through the in-process device table, handshakes, unplugging and bounds included."""

from __future__ import annotations

import numpy as np
import pytest

from slipstack.lib.protocols import dsacon32
from slipstack.lib.protocols.stream import Deframer
from slipstack.nodes.devices import LinkStatus
from slipstack.nodes.devices.backends import FtSample, TactileSample, backend_from_url
from slipstack.nodes.devices.emulators import Dsacon32Emulator, RdtSimServer, RobotiqEmulator
from slipstack.nodes.devices.sim_link import PORT_MAX_BYTES, SimDevice, SimLink, plugged_ports

MS = 1_000_000


def _pump(emulator, backend, send, ticks: int, now: int = 1_000 * MS) -> tuple[list, int]:
    """``ticks`` sample periods of 1 ms: the emulator sends, the back-end polls when due."""
    out = []
    for k in range(ticks):
        now += MS
        send(emulator, k)
        due = backend.next_deadline_ns()
        if due is not None and due <= now:
            out += backend.poll(now)
    return out, now


def test_rdt_over_a_simulated_port_streams_decoded_samples(tmp_path) -> None:
    server = RdtSimServer("127.0.0.1", 40001)
    backend = backend_from_url("sim:rdt://127.0.0.1:40001?rate_hz=1000")
    try:
        backend.open(1_000 * MS)
        samples, _ = _pump(server, backend, lambda e, k: e.send_ft([0.1 * k, 0.0, -2.0], [0.0, 0.0, 0.001]), 20)
        assert backend.status is LinkStatus.OK and backend.url.startswith("sim:rdt://")
        assert len(samples) >= 18 and all(isinstance(s, FtSample) for s in samples)
        assert samples[-1].force_n == pytest.approx([1.9, 0.0, -2.0])
        assert [s.device_seq for s in samples] == list(range(1, len(samples) + 1))
        assert backend.counters["gaps"] == 0 and backend.counters["requests"] == 1
    finally:
        backend.close()
        server.close()
    assert "udp:127.0.0.1:40001" not in plugged_ports()


def test_dsacon32_handshake_and_frames_over_a_simulated_port() -> None:
    emulator = Dsacon32Emulator("sim:/run/x/tactile.tty", rows=4, cols=3)
    backend = backend_from_url("sim:dsacon32:///run/x/tactile.tty?fps=500")
    counts = np.arange(12, dtype=np.uint16).reshape(4, 3) * 100
    try:
        backend.open(1_000 * MS)
        samples, _ = _pump(emulator, backend, lambda e, k: e.send_tactile(counts), 30)
        assert emulator.acquiring and backend.status is LinkStatus.OK
        assert samples and all(isinstance(s, TactileSample) for s in samples)
        np.testing.assert_array_equal(samples[-1].counts, counts)
    finally:
        backend.close()
        emulator.close()


def test_a_missing_or_unplugged_device_reads_disconnected_and_comes_back() -> None:
    backend = backend_from_url("sim:robotiq:///run/y/ft.tty?stop_ms=2&echo_ms=5")
    now = 1_000 * MS
    backend.open(now)
    assert backend.status is LinkStatus.DISCONNECTED and "no simulated device at /run/y/ft.tty" in backend.last_error
    emulator = RobotiqEmulator("sim:/run/y/ft.tty", streaming=False)
    send = lambda e, k: e.send_ft([0.0, 0.0, -1.0], [0.0, 0.0, 0.0])  # noqa: E731
    try:
        samples, now = _pump(emulator, backend, send, 200, now)
        assert backend.status is LinkStatus.OK and samples  # reopened on its back-off, handshake done
        emulator.unplug()
        backend.poll(now + MS)
        assert backend.status is LinkStatus.DISCONNECTED and "unplugged" in backend.last_error
        emulator.replug()
        samples, now = _pump(emulator, backend, send, 300, now + MS)
        assert backend.status is LinkStatus.OK and samples and backend.counters["reconnects"] == 1
    finally:
        backend.close()
        emulator.close()


def test_a_port_is_bounded_and_counts_what_it_drops() -> None:
    device = SimDevice("sim:/run/z/tty")
    device.plug()
    link = SimLink("/run/z/tty", stale_after_s=1.0)
    try:
        assert link.open(0)
        chunk = b"x" * 4096
        written = sum(device.write(chunk) for _ in range(PORT_MAX_BYTES // len(chunk) + 10))
        assert written == PORT_MAX_BYTES // len(chunk)
        assert device.dropped_bytes == 10 * len(chunk)
        assert link.next_attempt_ns() == 0  # bytes wait: the back-end is due at once
        assert len(link.read(1)) == PORT_MAX_BYTES
        assert link.next_attempt_ns() is None
    finally:
        link.close()
        device.close()


def test_dsacon32_reads_its_own_matrix_out_of_a_frame_of_two() -> None:
    """``matrix=1``: the frame carries matrix 0 (2 x 3) then matrix 1 (4 x 2); the sample is
    matrix 1's taxels only, rows x cols as its matrix info says, from every frame."""
    device = SimDevice("sim:/run/x/two_matrices.tty")
    device.plug()
    backend = backend_from_url("sim:dsacon32:///run/x/two_matrices.tty?fps=500&matrix=1")
    infos = [dsacon32.MatrixInfo(0, 1e-3, 1e-3, 3, 2), dsacon32.MatrixInfo(0, 1e-3, 1e-3, 2, 4)]
    commands = Deframer(dsacon32.PacketCodec())
    now = 1_000 * MS

    def answer() -> None:
        for p in commands.feed(device.read()):
            if p.id == dsacon32.PacketId.MATRIX_INFO:
                device.write(dsacon32.encode_matrix_info(infos[p.payload[0]]))
            else:
                device.write(dsacon32.encode_error_reply(p.id, 0))

    try:
        backend.open(now)
        for _ in range(4):  # stop, matrix info 0 and 1, start push mode
            answer()
            now += MS
            assert backend.poll(now) == []
        samples = []
        for k in range(3):
            first = np.full(6, 4000 + k, dtype=np.uint16)
            ours = np.arange(8, dtype=np.uint16) * 10 + k
            device.write(dsacon32.encode_packet(dsacon32.PacketId.FRAME,
                                                dsacon32.encode_frame_payload(k, np.concatenate([first, ours]))))
            now += MS
            samples += backend.poll(now)
        assert [s.counts.shape for s in samples] == [(4, 2)] * 3
        for k, s in enumerate(samples):
            np.testing.assert_array_equal(s.counts, (np.arange(8) * 10 + k).reshape(4, 2))
        assert backend.counters["bad_frames"] == 0 and backend.status is LinkStatus.OK
    finally:
        backend.close()
        device.close()
