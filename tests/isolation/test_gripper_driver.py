"""The gripper driver against the emulated WSG 50 over a real TCP socket, on a simulated clock.

A harness plays the executor (as in test_driver_nodes.py): it owns the clock, calls the
node at its deadlines and hands it its socket when readable; the emulator runs on the
same simulated clock. Every command of the protocol the driver uses goes over the wire,
as do malformed replies and a gripper that falls silent.
"""

from __future__ import annotations

import select
import time

import pytest

from slipstack.lib.protocols import wsg
from slipstack.messages import GripCommand, GripperState, decode
from slipstack.nodes.devices.emulators import WsgEmulator
from slipstack.nodes.gripper_driver import GripperDriver, GripperDriverParams
from slipstack.nodes.runtime.host import NodeHost

MS = 1_000_000


class Harness:
    """Executor stand-in: simulated clock, a real socket; the emulator measures ``force_n``."""

    def __init__(self, node: GripperDriver, emulator: WsgEmulator) -> None:
        self.node, self.emulator = node, emulator
        self.now = 10_000 * MS
        self.force_n = 7.0
        self.states: list[GripperState] = []
        self.logs: list[str] = []
        self.host = NodeHost(node, lambda: self.now, self._send, measure_handlers=False, log=self.logs.append)

    def _send(self, topic: str, payload: bytes) -> None:
        msg = decode(payload)
        if isinstance(msg, GripperState):
            self.states.append(msg)

    def start(self) -> None:
        self.host.call("start", self.node.start, self.host)

    def _drain(self, wait_s: float) -> None:
        self.emulator.tick(self.now, self.force_n)
        sources = self.node.io_sources()
        if sources:
            for src in select.select(sources, [], [], wait_s)[0]:
                self.host.call("on_readable", self.node.on_readable, src, self.host)
        self.emulator.tick(self.now, self.force_n)

    def advance(self, dt_ns: int, step_ns: int = MS) -> None:
        """Move simulated time on by ``dt_ns`` in steps, calling the node at each of its deadlines."""
        end = self.now + dt_ns
        while self.now < end:
            target = min(self.now + step_ns, end)
            while (due := self.node.next_deadline_ns()) is not None and due <= target:
                self.now = max(self.now, due)
                self._drain(0)
                self.host.call("on_deadline", self.node.on_deadline, self.host)
            self.now = target
            self._drain(0.002)

    def wait_for(self, predicate, timeout_s: float = 5.0, step_ns: int = MS) -> None:
        deadline = time.monotonic() + timeout_s
        while not predicate():
            assert time.monotonic() < deadline, f"timed out; states: {[s.status for s in self.states[-5:]]}"
            self.advance(step_ns)

    @property
    def counters(self) -> dict[str, int]:
        return self.node.backend.counters


def _driver(emulator: WsgEmulator, **params) -> Harness:
    url = f"wsg://{emulator.path}?rate_hz=100&grasp_n=12&reply_ms=20"
    h = Harness(GripperDriver(GripperDriverParams(url=url, **params)), emulator)
    h.start()
    return h


@pytest.fixture
def emulator():
    em = WsgEmulator("127.0.0.1:0")
    yield em
    em.close()


def test_an_idle_gripper_is_told_the_grasp_force_grasps_and_streams_its_force(emulator):
    h = _driver(emulator)
    h.wait_for(lambda: h.states and h.states[-1].status == "ok")
    assert emulator.holding and emulator.force_limit_n == pytest.approx(12.0)
    assert emulator.stream_period_ns == 10 * MS  # 100 Hz auto-update of the grasping force
    last = h.states[-1]
    assert last.state == "holding" and last.force_n == pytest.approx(7.0) and last.force_limit_n == pytest.approx(12.0)
    h.force_n = 9.5
    h.advance(30 * MS)
    assert h.states[-1].force_n == pytest.approx(9.5)
    assert h.counters["handshake_failures"] == 0 and h.counters["crc_errors"] == 0


def test_a_gripper_holding_a_part_is_taken_over_at_its_own_force_limit(emulator):
    emulator.state, emulator.force_limit_n = wsg.GraspingState.HOLDING, 23.0
    h = _driver(emulator)
    h.wait_for(lambda: h.states and h.states[-1].status == "ok")
    assert emulator.force_limit_n == pytest.approx(23.0)  # neither regrasped nor set to grasp_n
    assert h.states[-1].force_limit_n == pytest.approx(23.0) and h.counters["commands_sent"] == 0


def test_grip_commands_set_the_force_limit_bounded_to_the_range_the_newest_winning(emulator):
    h = _driver(emulator)
    h.wait_for(lambda: h.node.backend.ready)
    h.node.on_grip(GripCommand(f_n_desired=14.0), h.host)
    h.wait_for(lambda: emulator.force_limit_n == pytest.approx(14.0))
    for f in (30.0, 31.0, 32.0):  # within one command period (2 ms at 500 Hz): only the newest goes out
        h.node.on_grip(GripCommand(f_n_desired=f), h.host)
    h.wait_for(lambda: emulator.force_limit_n == pytest.approx(32.0))
    assert h.counters["commands_sent"] == 2
    h.advance(5 * MS)
    h.node.on_grip(GripCommand(f_n_desired=200.0), h.host)
    h.wait_for(lambda: emulator.force_limit_n == pytest.approx(80.0))  # the WSG 50's largest
    h.advance(5 * MS)
    h.node.on_grip(GripCommand(f_n_desired=0.5), h.host)
    h.wait_for(lambda: emulator.force_limit_n == pytest.approx(5.0))  # its least
    assert h.counters["commands_acknowledged"] == h.counters["commands_sent"] == 4
    h.advance(20 * MS)  # the next force reading carries the acknowledged limit
    assert h.states[-1].force_limit_n == pytest.approx(5.0)


def test_a_reply_with_a_broken_crc_is_counted_and_the_command_sent_again(emulator):
    h = _driver(emulator)
    h.wait_for(lambda: h.node.backend.ready)
    emulator.stream_period_ns = 0  # only the command's reply on the wire
    emulator.corrupt(1)
    h.node.on_grip(GripCommand(f_n_desired=17.0), h.host)
    h.wait_for(lambda: h.counters["commands_acknowledged"] == 1, step_ns=5 * MS)
    assert h.counters["crc_errors"] >= 1 and h.counters["reply_timeouts"] == 1
    assert h.counters["commands_sent"] == 2 and emulator.force_limit_n == pytest.approx(17.0)


def test_a_refused_command_is_counted_and_said(emulator):
    h = _driver(emulator, f_max_n=90.0)  # above the WSG 50's 80 N: the gripper answers E_RANGE_ERROR
    h.wait_for(lambda: h.node.backend.ready)
    h.node.on_grip(GripCommand(f_n_desired=85.0), h.host)
    h.wait_for(lambda: h.counters["command_errors"] == 1)
    assert "E_RANGE_ERROR" in h.node.backend.command_error
    assert emulator.force_limit_n == pytest.approx(12.0)  # unchanged
    h.advance(5 * MS)
    h.node.on_grip(GripCommand(f_n_desired=20.0), h.host)
    h.wait_for(lambda: emulator.force_limit_n == pytest.approx(20.0))


def test_garbage_and_answers_to_nothing_asked_are_skipped(emulator):
    h = _driver(emulator)
    h.wait_for(lambda: h.node.backend.ready)
    emulator.device.write(b"\xaa\xaa\xaa\x99garbage" + wsg.encode_reply(wsg.Command.GRASP, wsg.Status.E_SUCCESS)
                          + wsg.encode_message(wsg.Command.GET_FORCE, b"\x00"))  # a reply without its status
    h.node.on_grip(GripCommand(f_n_desired=15.0), h.host)
    h.wait_for(lambda: emulator.force_limit_n == pytest.approx(15.0))
    c = h.counters
    assert c["ignored_packets"] == 1 and c["bad_frames"] == 1 and c["rejected_bytes"] > 0
    assert h.states[-1].status == "ok"


def test_a_silent_gripper_goes_stale_then_is_reconnected_and_taken_over(emulator):
    h = _driver(emulator)
    h.wait_for(lambda: h.states and h.states[-1].status == "ok")
    emulator.silent = True
    h.advance(40 * MS)
    assert h.states[-1].status in ("stale", "disconnected")
    h.node.on_grip(GripCommand(f_n_desired=18.0), h.host)
    h.wait_for(lambda: h.counters["reply_timeouts"] >= 3, step_ns=5 * MS)
    h.advance(200 * MS, step_ns=5 * MS)
    assert h.states[-1].status == "disconnected" and "did not answer" in h.node.backend.last_error
    emulator.silent = False
    h.wait_for(lambda: h.states and h.states[-1].status == "ok", step_ns=5 * MS)
    assert h.counters["reconnects"] >= 1
    h.wait_for(lambda: emulator.force_limit_n == pytest.approx(18.0), step_ns=5 * MS)  # the wanted squeeze, re-sent


def test_the_watchdog_holds_the_last_squeeze_then_raises_it_when_commands_stop(emulator):
    h = _driver(emulator, command_timeout_ms=100.0, watchdog_grip_n=30.0, watchdog_rise_n_per_s=10.0)
    h.wait_for(lambda: h.node.backend.ready)
    h.node.on_grip(GripCommand(f_n_desired=14.0), h.host)
    h.advance(90 * MS)
    assert emulator.force_limit_n == pytest.approx(14.0) and not h.states[-1].watchdog
    h.advance(510 * MS)  # 0.5 s past the timeout: held, then raised by about 10 N/s × 0.5 s
    assert 18.0 <= emulator.force_limit_n <= 19.5
    assert h.states[-1].watchdog and h.node.commanded_n >= 18.0
    h.advance(3000 * MS)
    assert emulator.force_limit_n == pytest.approx(30.0)  # up to the safe grip, never beyond
    h.node.on_grip(GripCommand(f_n_desired=10.0), h.host)  # a command ends the watchdog's hold
    h.wait_for(lambda: emulator.force_limit_n == pytest.approx(10.0))
    assert not h.node.watchdog.expired
