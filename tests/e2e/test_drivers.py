"""The driver nodes as real processes (``slipstack run``) against device emulators.

The test process owns the emulator (pty or loopback UDP), paces it at 100 Hz, and
reads the driver's ``ft/wrench`` / ``tactile/frame`` and ``diagnostics`` with a
ZeroMQ SUB socket. Value round trip for every back-end; unplug/replug and a
garbage burst for one serial device (Robotiq) and for RDT.
"""

from __future__ import annotations

import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
import zmq
from progress_deadline import ProgressDeadline

from slipstack.lib.protocols.framed import FramedFormat
from slipstack.messages import decode
from slipstack.nodes.devices.emulators import (
    BotaEmulator, Dsacon32Emulator, FramedEmulator, M1616Emulator, RdtUdpServer, RobotiqEmulator,
)

pytestmark = pytest.mark.e2e

PERIOD_S = 0.01  # the emulators are paced at 100 Hz
FORCE = [1.2341, -2.3468, 10.0049]
TORQUE = [0.01234, -0.04567, 0.00089]


class Driver:
    """``slipstack run NODE url:=URL …`` as a subprocess, with a SUB on its endpoint."""

    def __init__(self, node: str, url: str, run_dir, *params: str) -> None:
        endpoint = f"ipc://{run_dir}/driver.pub"
        self.log_path = run_dir / "driver.log"
        self._log = open(self.log_path, "wb")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "slipstack.launch.cli", "run", node, f"url:={url}", *params, "--pub", endpoint],
            stdout=self._log, stderr=subprocess.STDOUT,
        )
        self.sub = zmq.Context.instance().socket(zmq.SUB)
        self.sub.setsockopt(zmq.SUBSCRIBE, b"")
        self.sub.connect(endpoint)

    def receive(self, timeout_s: float) -> list[tuple[str, object]]:
        """Every frame that arrives within timeout_s (returns early once one arrived)."""
        out = []
        if self.sub.poll(max(0, int(timeout_s * 1000))):
            while True:
                try:
                    topic, payload = self.sub.recv_multipart(zmq.NOBLOCK)
                except zmq.Again:
                    break
                out.append((topic.decode(), decode(payload)))
        if self.proc.poll() is not None:
            raise AssertionError(f"driver exited ({self.proc.returncode}):\n{self.log()}")
        return out

    def log(self) -> str:
        """What the driver process wrote (it writes the file itself: nothing to flush here)."""
        return self.log_path.read_text(errors="replace")

    def stop(self) -> int:
        self.sub.close(linger=0)
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self._log.close()
        return self.proc.returncode


def pace(driver: Driver, send, until, timeout_s: float = 30.0) -> list[tuple[str, object]]:
    """Call send() every PERIOD_S and collect frames until until(frames) holds."""
    frames: list[tuple[str, object]] = []
    deadline = ProgressDeadline(timeout_s, lambda: [driver.proc.pid])
    next_send = time.monotonic()
    while not until(frames):
        now = time.monotonic()
        assert not deadline.expired(), (f"not done after {deadline}; got "
                                        f"{[(t, getattr(m, 'status', '')) for t, m in frames[-5:]]}\n{driver.log()}")
        if now >= next_send:
            send()
            next_send += PERIOD_S
        frames += driver.receive(max(0.0, next_send - time.monotonic()))
    return frames


def data(frames, topic):
    return [m for t, m in frames if t == topic]


def ok_count(topic, n):
    return lambda frames: sum(m.status == "ok" for m in data(frames, topic)) >= n


@pytest.fixture
def run_dir():
    with tempfile.TemporaryDirectory(prefix="ssd-", dir="/tmp") as d:  # short ipc path
        yield Path(d)


FT_CASES = {
    # back-end: (emulator factory, url, expected force, expected torque, tolerance)
    "rdt": (RdtUdpServer, lambda e: e.url + "?rate_hz=100", FORCE, TORQUE, 1e-6),
    # Robotiq wire resolution: 0.01 N and 0.001 N·m
    "robotiq": (RobotiqEmulator, lambda e: f"robotiq://{e.path}", [1.23, -2.35, 10.0], [0.012, -0.046, 0.001], 1e-12),
    "bota": (BotaEmulator, lambda e: f"bota://{e.path}?rate_hz=100", FORCE, TORQUE, 1e-6),  # float32
}


@pytest.mark.parametrize("backend", sorted(FT_CASES))
def test_ft_values_round_trip(backend, run_dir):
    make, url, force, torque, tol = FT_CASES[backend]
    emu = make()
    driver = Driver("ft_driver", url(emu), run_dir)
    try:
        frames = pace(driver, lambda: emu.send_ft(FORCE, TORQUE), ok_count("ft/wrench", 3))
        msg = [m for m in data(frames, "ft/wrench") if m.status == "ok"][-1]
        np.testing.assert_allclose(msg.force, force, rtol=0, atol=tol)
        np.testing.assert_allclose(msg.torque, torque, rtol=0, atol=tol)
        assert msg.frame == "pad"
        assert (msg.device_seq > 0) == (backend == "rdt")  # only RDT has a device sequence
    finally:
        assert driver.stop() == 0, driver.log()
        emu.close()


def _counts(rows, cols, top):
    return (np.arange(rows * cols, dtype=np.int64) * 97 % (top + 1)).reshape(rows, cols).astype(np.uint16)


_FRAMED = FramedFormat(header=b"\xa5\x5a", rows=4, cols=8, dtype="u8", checksum="sum8")
TACTILE_CASES = {
    "m1616": (M1616Emulator, lambda e: f"m1616://{e.path}?rate_hz=100", 16, 16, 65535),
    "dsacon32": (lambda: Dsacon32Emulator(rows=6, cols=14), lambda e: f"dsacon32://{e.path}?fps=100", 6, 14, 4095),
    "framed": (lambda: FramedEmulator(_FRAMED), lambda e: f"framed://{e.path}?header=a55a&rows=4&cols=8&dtype=u8"
               "&checksum=sum8&rate_hz=100", 4, 8, 255),
}


@pytest.mark.parametrize("backend", sorted(TACTILE_CASES))
def test_tactile_values_round_trip(backend, run_dir):
    make, url, rows, cols, top = TACTILE_CASES[backend]
    emu = make()
    counts = _counts(rows, cols, top - 1)
    counts[0, 1] = top
    driver = Driver("tactile_driver", url(emu), run_dir, f"rows:={rows}", f"cols:={cols}", "dead_taxels:=2")
    try:
        frames = pace(driver, lambda: emu.send_tactile(counts), ok_count("tactile/frame", 3))
        msg = [m for m in data(frames, "tactile/frame") if m.status == "ok"][-1]
        expected = 10.0 * counts.ravel()  # default calibration: 10 Pa/count
        expected[2] = 0.0
        np.testing.assert_allclose(msg.pressure_pa, expected, rtol=1e-7)
        assert np.flatnonzero(msg.saturated).tolist() == [1]  # the device's full scale
        assert np.flatnonzero(msg.dead).tolist() == [2]
        assert (msg.rows, msg.cols) == (rows, cols)
    finally:
        assert driver.stop() == 0, driver.log()
        emu.close()


def _garbage_rdt(emu: RdtUdpServer, data_: bytes) -> None:
    # The driver's socket is connected to the sensor, so the datagram must come from the
    # sensor's address: a second socket bound to it (the emulator sets SO_REUSEADDR too).
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind(emu.address)
        s.sendto(data_, emu.client)  # no multiple of 36 bytes: not an RDT record


UNPLUG_CASES = {
    "robotiq": (RobotiqEmulator, lambda e: f"robotiq://{e.path}", lambda e, g: e.device.write(g)),
    # stale_ms=20: 2 periods, leaving one period for the driver's timer and scheduling
    "rdt": (RdtUdpServer, lambda e: e.url + "?rate_hz=100&stale_ms=20", _garbage_rdt),
}


@pytest.mark.parametrize("backend", sorted(UNPLUG_CASES))
def test_garbage_unplug_and_replug(backend, run_dir):
    make, url, inject = UNPLUG_CASES[backend]
    emu = make()
    driver = Driver("ft_driver", url(emu), run_dir, "to_pad:=false")
    try:
        pace(driver, lambda: emu.send_ft([1.0, 2.0, 3.0], [0.0, 0.0, 0.0]), ok_count("ft/wrench", 5))

        garbage = b"\x01\x02garbage\x99\x00" * 4  # no Robotiq sync 0x20 0x4E; no 36-byte multiple
        inject(emu, garbage)

        def rejected_seen(frames):
            diag = [m for m in data(frames, "diagnostics") if m.counters.get("device.rejected_bytes", 0) >= len(garbage)]
            after = [m for m in data(frames, "ft/wrench") if m.status == "ok" and m.force[0] == 4.0]
            return bool(diag) and len(after) >= 5

        before = pace(driver, lambda: emu.send_ft([4.0, 0.0, 0.0], [0.0, 0.0, 0.0]), rejected_seen)

        emu.unplug()
        after = pace(driver, lambda: None, lambda f: any(m.status != "ok" for m in data(f, "ft/wrench")))
        wrenches = data(before + after, "ft/wrench")
        first_bad = next(i for i, m in enumerate(wrenches) if m.status != "ok")
        bad, last_ok = wrenches[first_bad], wrenches[first_bad - 1]
        assert bad.status in ("stale", "disconnected") and last_ok.status == "ok"
        np.testing.assert_allclose(bad.force, [4.0, 0.0, 0.0], atol=1e-9)  # the last good value, held
        # disconnected as soon as the port hangs up, stale once no sample came for the stale
        # limit (2 or 2.5 sample periods, never sooner); either later by the driver's
        # wake-up delay, which a busy machine stretches (3 periods on an idle one)
        gap_ns = bad.header.stamp_ns - last_ok.header.stamp_ns
        assert (2 * PERIOD_S * 1e9 if bad.status == "stale" else 0) <= gap_ns <= 1e9, (bad.status, gap_ns)

        emu.replug()
        frames = pace(driver, lambda: emu.send_ft([-5.0, 0.0, 1.0], [0.0, 0.0, 0.0]),
                      lambda f: any(m.status == "ok" and m.force[0] == -5.0 for m in data(f, "ft/wrench")))
        assert data(frames, "ft/wrench")[-1].status == "ok"
    finally:
        assert driver.stop() == 0, driver.log()
        emu.close()


@pytest.mark.parametrize("node,url", [("ft_driver", "robotiq:///dev/ttyNOPE"),
                                      ("tactile_driver", "dsacon32:///dev/ttyNOPE?fps=100")])
def test_wrong_device_path_is_said_and_retried_without_spinning(node, url, run_dir):
    """``slipstack run ft_driver url:=robotiq:///dev/ttyNOPE``: an error line
    on the terminal, ``disconnected`` with the open error on diagnostics, and a back-off that
    sleeps (loop wake-ups per second of diagnostics stamps stay far below a busy loop's)."""
    driver = Driver(node, url, run_dir)
    try:
        diags = []
        deadline = ProgressDeadline(20, lambda: [driver.proc.pid])
        while len(diags) < 3:
            assert not deadline.expired(), f"not done after {deadline}; diagnostics: {diags}\n{driver.log()}"
            diags += [m for t, m in driver.receive(1.0) if t == "diagnostics"]
        last = diags[-1]
        assert last.status.startswith("disconnected"), last.status
        assert "/dev/ttyNOPE" in last.status and "No such file" in last.last_error, last
        first, last = diags[0], diags[-1]
        span_s = (last.header.stamp_ns - first.header.stamp_ns) / 1e9
        wakeups_per_s = (last.counters["loop.wakeups"] - first.counters["loop.wakeups"]) / span_s
        assert wakeups_per_s < 2000, f"{wakeups_per_s:.0f} loop wake-ups per second: a busy loop"
        errors = [line for line in driver.log().splitlines() if "error" in line and "/dev/ttyNOPE" in line]
        assert len(errors) == 1, driver.log()  # said once, not once per retry
        assert "docs/drivers.md" in errors[0]
    finally:
        assert driver.stop() == 0, driver.log()
