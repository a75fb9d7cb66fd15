"""The driver nodes in-process against real emulators (pty), on a simulated clock.

A small harness plays the executor: it owns the clock, fires the node's timers at
their deadlines, and hands readable descriptors to ``on_readable`` — so stamps and
stale/timeout behaviour are exact in simulated time while the bytes go through a
real pseudo-terminal and the real back-ends.
"""

from __future__ import annotations

import math
import select
import time

import numpy as np
import pytest

from slipstack.lib.calibration import Calibration, save_calibration
from slipstack.lib.errors import ConfigError
from slipstack.lib.protocols.bota import encode_frame
from slipstack.messages import decode
from slipstack.nodes.devices.emulators import BotaEmulator, Dsacon32Emulator, M1616Emulator, RdtUdpServer
from slipstack.nodes.ft_driver import FtDriver, FtDriverParams
from slipstack.nodes.runtime.host import NodeHost
from slipstack.nodes.tactile_driver import TactileDriver, TactileDriverParams

MS = 1_000_000


class Harness:
    """Executor stand-in: simulated clock, real descriptors (module docstring)."""

    def __init__(self, node, emulator) -> None:
        self.node, self.emulator = node, emulator
        self.now = 10_000 * MS
        self.out: list = []
        self.logs: list[str] = []
        self.host = NodeHost(node, lambda: self.now, self._send, measure_handlers=False, log=self.logs.append)

    def _send(self, topic: str, payload: bytes) -> None:
        self.out.append(decode(payload))

    def start(self) -> None:
        self.host.call("start", self.node.start, self.host)

    def _drain(self, wait_s: float) -> None:
        self.emulator.service()
        sources = self.node.io_sources()
        if sources:
            for src in select.select(sources, [], [], wait_s)[0]:
                self.host.call("on_readable", self.node.on_readable, src, self.host)

    def advance(self, dt_ns: int) -> None:
        """Move simulated time on by dt_ns, calling the node at each of its deadlines."""
        end = self.now + dt_ns
        while (due := self.node.next_deadline_ns()) is not None and due <= end:
            self.now = max(self.now, due)
            self._drain(0)
            self.host.call("on_deadline", self.node.on_deadline, self.host)
        self.now = end
        self._drain(0)

    def wait_for(self, predicate, timeout_s: float = 3.0) -> None:
        """Handle I/O at a fixed simulated time until predicate() holds (wall-clock bound)."""
        deadline = time.monotonic() + timeout_s
        while not predicate():
            assert time.monotonic() < deadline, f"timed out; published: {[getattr(m, 'status', m) for m in self.out]}"
            self._drain(0.01)

    def send(self, fn, *args, dt_ns: int) -> object:
        """One device sample: advance dt_ns, send, wait until the driver published it."""
        self.advance(dt_ns)
        n = len(self.out)
        fn(*args)
        self.wait_for(lambda: len(self.out) > n and self.out[-1].status not in ("stale", "disconnected"))
        return self.out[-1]


@pytest.fixture
def bota():
    emu = BotaEmulator()
    yield emu
    emu.close()


def _ft(emu, **params) -> Harness:
    h = Harness(FtDriver(FtDriverParams(url=f"bota://{emu.path}", **params)), emu)
    h.start()
    return h


def test_samples_of_one_read_are_stamped_back_by_the_period_and_strictly_increase(bota):
    """Samples decoded by one read carry the read's time; the driver steps the earlier ones
    back by the nominal period (Bota: 200 Hz, 5 ms), never to or before the last stamp."""
    h = _ft(bota)
    t_prev = h.send(bota.send_ft, [0.0, 0.0, -1.0], [0.0, 0.0, 0.0], dt_ns=5 * MS).header.stamp_ns

    def one_read(n_samples: int) -> list[int]:
        n = len(h.out)
        frames = []
        for k in range(n_samples):  # one write: the driver's read takes them together, however busy the machine
            frames.append(encode_frame([0.0, 0.0, -1.0 - k], [0.0, 0.0, 0.0], timestamp_us=round(bota.n_sent * bota.period_us)))
            bota.n_sent += 1
        bota.device.write(b"".join(frames))
        h.wait_for(lambda: len(h.out) >= n + n_samples)
        assert [m.status for m in h.out[n:]] == ["ok"] * n_samples
        return [m.header.stamp_ns for m in h.out[n:]]

    h.advance(12 * MS)  # within the 12.5 ms stale limit
    assert one_read(3) == [t_prev + 2 * MS, t_prev + 7 * MS, t_prev + 12 * MS] == [h.now - 10 * MS, h.now - 5 * MS, h.now]
    assert one_read(2) == [h.now + 1, h.now + 2]  # the same instant again: 1 ns apart, after the last
    h.advance(4 * MS)
    assert one_read(3) == [h.now - 4 * MS + 3, h.now - 4 * MS + 4, h.now]


def test_rdt_at_7khz_in_bursts_of_a_millisecond_is_never_stale_by_default():
    """The rig (and a host that reads the socket once per millisecond) delivers 7 kHz RDT
    records in bursts of seven every 1 ms. With the default stale limit (2.5 periods =
    0.36 ms at 7 kHz) every gap between bursts flagged the sensor stale and the grip held
    (fail-safe) on good data; the default has a floor of 2.5 ms."""
    server = RdtUdpServer()
    try:
        h = Harness(FtDriver(FtDriverParams(url=server.url + "?rate_hz=7000")), server)
        h.start()
        h.send(server.send_ft, [0.0, 0.0, -1.0], [0.0, 0.0, 0.0], dt_ns=MS)
        streaming = len(h.out)
        for _ in range(20):
            h.advance(MS)
            n = len(h.out)
            for _ in range(7):
                server.send_ft([0.0, 0.0, -1.0], [0.0, 0.0, 0.0])
            h.wait_for(lambda: sum(m.status == "ok" for m in h.out[n:]) == 7)
        statuses = [m.status for m in h.out[streaming:]]
        assert statuses == ["ok"] * 140, [s for s in statuses if s != "ok"][:3]
        h.advance(3 * MS)  # a real silence is still said within the floor
        assert h.out[-1].status == "stale"
    finally:
        server.close()


def test_bias_from_tare_then_sensor_to_pad_transform(bota):
    h = _ft(bota, tare_on_start=True, tare_samples=4, pad_offset_m=(0.01, 0.0, 0.02), pad_rpy_deg=(0.0, 0.0, 90.0))
    bias_f, bias_t = [0.5, -0.25, 0.125], [0.0, 0.0, 0.0]
    taring = [h.send(bota.send_ft, bias_f, bias_t, dt_ns=5 * MS) for _ in range(4)]
    assert [m.status for m in taring] == ["taring"] * 4
    msg = h.send(bota.send_ft, np.add(bias_f, [1.0, 0.0, -5.0]), [0.0, 0.0, 0.02], dt_ns=5 * MS)
    # Rz(90°) takes x_S to y_F; τ_F = R τ_S + p × f_F with p = (0.01, 0, 0.02), f_F = (0, 1, −5):
    # p × f_F = (0·(−5) − 0.02·1, 0.02·0 − 0.01·(−5), 0.01·1 − 0) = (−0.02, 0.05, 0.01).
    assert msg.status == "ok" and msg.frame == "pad" and msg.device_seq == -1
    np.testing.assert_allclose(msg.force, [0.0, 1.0, -5.0], atol=1e-6)
    np.testing.assert_allclose(msg.torque, [-0.02, 0.05, 0.03], atol=1e-6)
    assert msg.header.stamp_ns == h.now  # receive time on the executor clock
    h.node.tare()  # on command: the next 4 samples become the new bias
    for _ in range(4):
        assert h.send(bota.send_ft, [2.0, 2.0, 2.0], [0.0, 0.0, 0.0], dt_ns=5 * MS).status == "taring"
    np.testing.assert_allclose(h.send(bota.send_ft, [2.0, 2.0, 2.0], [0, 0, 0], dt_ns=5 * MS).force, 0.0, atol=1e-6)
    h.node.stop(h.host)
    assert h.host.counters["ft.tares"] == 2 and h.host.counters["device.frames"] == 10


def test_lowpass_step_response_matches_the_exact_discretisation(bota):
    h = _ft(bota, lowpass_hz=10.0, to_pad=False)
    first = h.send(bota.send_ft, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], dt_ns=5 * MS)
    assert first.frame == "sensor"
    alpha = 1.0 - math.exp(-2.0 * math.pi * 10.0 / 200.0)  # Bota nominal 200 Hz: dt = 5 ms
    for k in range(1, 6):
        msg = h.send(bota.send_ft, [1.0, 0.0, 0.0], [0.0, 0.0, -2.0], dt_ns=5 * MS)
        assert msg.force[0] == pytest.approx(1.0 - (1.0 - alpha) ** k, abs=1e-9)
        assert msg.torque[2] == pytest.approx(-2.0 * (1.0 - (1.0 - alpha) ** k), abs=1e-9)


def test_a_driver_started_at_time_zero_reports_its_link_at_once(bota):
    h = Harness(FtDriver(FtDriverParams(url=f"bota://{bota.path}")), bota)
    h.now = 0  # a clock that starts at 0, as the in-process executor's does by default
    h.start()
    h.advance(1 * MS)
    assert [(m.header.stamp_ns, m.status) for m in h.out] == [(0, "stale")]  # no sample yet: flagged at once


def test_device_counters_reach_diagnostics_every_50_ms_while_running(bota):
    h = _ft(bota)
    for _ in range(10):  # one sample every 5 ms from the start t0
        h.send(bota.send_ft, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], dt_ns=5 * MS)
    # mirrored at t0 and at t0 + 50 ms, just before the 10th sample came
    assert h.host.counters.get("device.frames") == 9


def test_stale_within_three_periods_then_disconnected_then_recovers(bota):
    h = _ft(bota, to_pad=False)  # the default stale_status_period_ms: 10 ms, inside the grip's 20 ms timeout
    for _ in range(5):
        last = h.send(bota.send_ft, [1.0, 2.0, 3.0], [0.1, 0.2, 0.3], dt_ns=5 * MS)
    n = len(h.out)
    h.advance(60 * MS)  # the device goes silent
    held = h.out[n:]
    assert held and {m.status for m in held} == {"stale"}
    assert h.host.status == "stale" and h.host.detail == f"bota://{bota.path}"  # diagnostics says so too
    assert held[0].header.stamp_ns - last.header.stamp_ns <= 3 * 5 * MS  # 3 sample periods at 200 Hz
    gaps = np.diff([m.header.stamp_ns for m in held])
    assert np.all(gaps <= 10 * MS) and np.all(gaps >= 9 * MS)  # repeated every 10 ms (the default)
    np.testing.assert_allclose(held[-1].force, [1.0, 2.0, 3.0], atol=1e-6)  # the last good values, held

    bota.unplug()
    n = len(h.out)
    h.wait_for(lambda: any(m.status == "disconnected" for m in h.out[n:]))
    assert h.host.status == "disconnected"
    bota.replug()
    h.advance(200 * MS)  # past the reconnect back-off (50 ms, doubling)
    h.wait_for(lambda: h.node.backend.fileno() is not None)
    msg = h.send(bota.send_ft, [-4.0, 0.5, 0.25], [0.0, 0.0, 0.0], dt_ns=5 * MS)
    assert msg.status == "ok" and h.host.status == "ok"
    np.testing.assert_allclose(msg.force, [-4.0, 0.5, 0.25], atol=1e-6)
    h.node.stop(h.host)
    assert h.host.counters["device.reconnects"] == 1


def _counts(rows: int, cols: int, top: int) -> np.ndarray:
    return (np.arange(rows * cols, dtype=np.int64) * 97 % (top + 1)).reshape(rows, cols).astype(np.uint16)


def test_m1616_default_linear_calibration_saturation_and_dead_mask():
    emu = M1616Emulator()
    try:
        h = Harness(TactileDriver(TactileDriverParams(url=f"m1616://{emu.path}", dead_taxels=(3, 200))), emu)
        h.start()
        counts = _counts(16, 16, 60000)
        counts[5, 7] = 65535
        msg = h.send(emu.send_tactile, counts, dt_ns=10 * MS)
        expected = 10.0 * counts.ravel().astype(float)  # default 10 Pa/count
        expected[[3, 200]] = 0.0
        assert msg.pressure_pa.dtype == np.float32 and msg.status == "ok"
        np.testing.assert_allclose(msg.pressure_pa, expected, rtol=1e-7)
        assert np.flatnonzero(msg.saturated).tolist() == [5 * 16 + 7]  # u16 full scale
        assert np.flatnonzero(msg.dead).tolist() == [3, 200]
        assert (msg.rows, msg.cols, msg.pitch_m, msg.device_stamp) == (16, 16, 1.25e-3, -1)
    finally:
        emu.close()


def test_dsacon32_with_a_calibration_file(tmp_path):
    cal = Calibration(counts=np.array([0.0, 1000.0, 4095.0]), pressure_pa=np.array([0.0, 5000.0, 40000.0]),
                      dead=np.array([0]))
    save_calibration(cal, tmp_path / "cal.toml")
    emu = Dsacon32Emulator(rows=6, cols=14)
    try:
        params = TactileDriverParams(url=f"dsacon32://{emu.path}?fps=100", calibration=str(tmp_path / "cal.toml"),
                                     rows=6, cols=14, pitch_m=3.4e-3)
        h = Harness(TactileDriver(params), emu)
        h.start()
        h.wait_for(lambda: h.node.backend.matrices and emu.acquiring)  # stop, matrix info, start push mode
        counts = _counts(6, 14, 4095)
        counts[0, 3] = 500
        counts[2, 2] = 4095
        msg = h.send(emu.send_tactile, counts, dt_ns=10 * MS)
        c = counts.ravel()
        expected = np.where(c <= 1000, 5.0 * c, 5000.0 + (c - 1000.0) * 35000.0 / 3095.0)
        expected[0] = 0.0
        np.testing.assert_allclose(msg.pressure_pa, expected, rtol=1e-6)
        assert msg.pressure_pa[3] == pytest.approx(2500.0)
        assert msg.saturated[2 * 14 + 2] and msg.saturated.sum() == (c >= 4095).sum()  # 12-bit full scale
        assert msg.dead[0] and msg.dead.sum() == 1
        assert (msg.rows, msg.cols, msg.pitch_m) == (6, 14, 3.4e-3)
        assert msg.device_stamp == 0  # first frame: controller time 0 ms
    finally:
        emu.close()


def test_a_frame_of_the_wrong_size_is_counted_not_published():
    emu = M1616Emulator()
    try:
        h = Harness(TactileDriver(TactileDriverParams(url=f"m1616://{emu.path}", rows=8, cols=32)), emu)
        h.start()
        h.advance(10 * MS)
        emu.send_tactile(_counts(16, 16, 1000))
        h.wait_for(lambda: h.host.counters.get("tactile.size_mismatch", 0) == 1)
        assert all(m.status != "ok" for m in h.out)
        assert h.host.status == "size-mismatch" and "16x16" in h.host.detail and "8x32" in h.host.detail
    finally:
        emu.close()


def test_invalid_configuration_is_a_config_error_naming_the_fix(tmp_path):
    bad = tmp_path / "nan.toml"
    bad.write_text("counts = [0, 100]\npressure_pa = [0.0, nan]\n")
    # the calibration file is read at start (a launch may write it first)
    with pytest.raises(ConfigError, match="nan.toml.*finite"):
        TactileDriver(TactileDriverParams(url="m1616:///dev/null", calibration=str(bad)))._load_calibration()
    gain = tmp_path / "gain.toml"
    gain.write_text("counts = [0, 100]\npressure_pa = [0.0, 1.0]\ngain = [1.0, 1.0]\n")
    with pytest.raises(ConfigError, match="gain has 2 entries.*256"):
        TactileDriver(TactileDriverParams(url="m1616:///dev/null", calibration=str(gain)))._load_calibration()
    with pytest.raises(ConfigError, match="is a ft device"):
        TactileDriver(TactileDriverParams(url="rdt://127.0.0.1"))
    with pytest.raises(ConfigError, match="is a tactile device"):
        FtDriver(FtDriverParams(url="m1616:///dev/null"))
    with pytest.raises(ConfigError, match="3 numbers"):
        FtDriver(FtDriverParams(url="rdt://127.0.0.1", pad_offset_m=(0.0, 0.0)))
