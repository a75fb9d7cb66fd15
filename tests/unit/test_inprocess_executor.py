"""The in-process executor: deterministic, counts drops and rejects like the bus."""

from __future__ import annotations

import numpy as np

from slipstack.messages import Header, Wrench, encode
from slipstack.nodes.demo import Relay, SourceParams, WrenchSource
from slipstack.nodes.devices.sim_link import SimDevice, SimLink, host_side_changes
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from slipstack.nodes.runtime.node import Context, Input, Node, Output


def _wrench(seq: int, t: int) -> Wrench:
    return Wrench(force=np.array([seq, 0.0, 1.0]), torque=np.zeros(3), header=Header(t, seq, t, {}))


def test_source_and_relay_run_on_a_simulated_clock_deterministically():
    def run() -> list:
        ex = InProcessExecutor([WrenchSource(SourceParams(rate_hz=1000)), Relay()])
        ex.run(until_ns=50_000_000)
        return ex.published["ft/relayed"]

    a, b = run(), run()
    assert len(a) == 50
    assert [m.header.stamp_ns for m in a] == [1_000_000 * (k + 1) for k in range(50)]
    assert [m.header.seq for m in a] == list(range(50))
    assert all(np.array_equal(x.force, y.force) and x.header == y.header for x, y in zip(a, b))


def test_rejected_frames_and_sequence_gaps_are_counted_not_raised():
    relay = Relay()
    ex = InProcessExecutor([relay], diagnostics_period_s=1.0)
    ex.feed([(1, "ft/wrench", _wrench(0, 1)), (2, "ft/wrench", b"\x00garbage"), (3, "ft/wrench", _wrench(5, 3))])
    ex.run(until_ns=1_000_000_000)
    host = ex.hosts[0]
    assert host.counters["in.ft/wrench.received"] == 3
    assert host.counters["in.ft/wrench.rejected"] == 1
    assert host.counters["in.ft/wrench.lost"] == 4  # seq 0 then 5
    assert len(ex.published["ft/relayed"]) == 2
    (diag,) = ex.published["diagnostics"]
    assert diag.counters["in.ft/wrench.rejected"] == 1 and "payload" in diag.last_error


class _Faulty(Node):
    name = "faulty"
    inputs = {"wrench": Input("ft/wrench", Wrench)}

    def on_wrench(self, msg: Wrench, ctx: Context) -> None:
        if msg.header.seq == 1:
            raise ZeroDivisionError("bug")
        ctx.count("handled")


def test_a_handler_that_raises_is_counted_and_the_node_goes_on():
    ex = InProcessExecutor([_Faulty()])
    ex.feed([(k, "ft/wrench", encode(_wrench(k, k))) for k in range(3)])
    ex.run()
    host = ex.hosts[0]
    assert host.counters["handler_errors"] == 1 and host.counters["handled"] == 2
    assert host.status == "error" and any("ZeroDivisionError" in line for line in ex.logs)


class _Finisher(Relay):
    """Relays one frame, then asks to shut down."""

    def on_wrench(self, msg: Wrench, ctx: Context) -> None:
        super().on_wrench(msg, ctx)
        ctx.shutdown()


def test_advance_and_inject_drive_named_nodes_and_hand_every_frame_to_on_frame():
    frames: list[tuple[int, str, int]] = []
    ex = InProcessExecutor([Relay(), Relay()], names=["first", "second"], remaps={"second": {"ft/relayed": "x"}},
                           keep_published=False, on_frame=lambda t, topic, payload: frames.append((t, topic, len(payload))))
    ex.inject("ft/wrench", _wrench(0, 5), at_ns=7)
    ex.advance(10)
    assert ex.now_ns == 10
    ex.inject("ft/wrench", encode(_wrench(1, 12)))  # now
    ex.advance(20)
    assert [(t, topic) for t, topic, _ in frames] == [(7, "ft/relayed"), (7, "x"), (10, "ft/relayed"), (10, "x")]
    assert ex.host("second").counters["out.x.published"] == 2 and ex.published == {} and ex.raw == []
    assert ex.finished() == []


def test_advance_stops_at_the_shutdown_of_a_watched_node():
    ex = InProcessExecutor([_Finisher(), Relay()], names=["finisher", "relay"])
    ex.feed([(3, "ft/wrench", _wrench(0, 3)), (8, "ft/wrench", _wrench(1, 8))])
    ex.advance(100, stop_at_shutdown_of=["finisher"])
    assert ex.finished() == ["finisher"] and ex.now_ns == 3  # the instant ran out; the frame at 8 ns did not run
    # the relay still got the finisher's instant, not the next
    assert [m.header.stamp_ns for m in ex.published["ft/relayed"]] == [3, 3]
    assert ex.host("relay").counters["in.ft/wrench.received"] == 1
    stopped: list[str] = []
    for host in ex.hosts:
        host.node.stop = lambda ctx, n=host.name: stopped.append(n)
    ex.stop(["relay", "finisher"])
    assert stopped == ["relay", "finisher"]


class _Keeper(Node):
    """Keeps every relayed wrench it is handed."""

    name = "keeper"
    inputs = {"wrench": Input("ft/relayed", Wrench)}

    def __init__(self) -> None:
        super().__init__()
        self.got: list[Wrench] = []

    def on_wrench(self, msg: Wrench, ctx: Context) -> None:
        self.got.append(msg)


def test_a_published_message_reaches_every_subscriber_as_one_object_with_its_header_and_is_encoded_only_if_wanted():
    frames: list[str] = []
    first, second = _Keeper(), _Keeper()
    ex = InProcessExecutor([Relay(), first, second], names=["relay", "first", "second"], keep_published=False,
                           on_frame=lambda t, topic, payload: frames.append(topic), on_frame_topics={"elsewhere"})
    ex.feed([(5, "ft/wrench", _wrench(0, 5)), (9, "ft/wrench", _wrench(1, 9))])
    ex.run()
    assert len(first.got) == 2 and all(a is b for a, b in zip(first.got, second.got))  # decoded once: shared
    assert [m.header.seq for m in first.got] == [0, 1] and [m.header.pub_ns for m in first.got] == [5, 9]
    assert [m.force[0] for m in first.got] == [0.0, 1.0]
    assert ex.host("first").counters["in.ft/relayed.received"] == 2
    assert frames == []  # nobody wants ft/relayed's bytes: not encoded


class _NanRelay(Relay):
    """Relays a wrench with a NaN force: a bug the subscriber must reject, not handle."""

    def on_wrench(self, msg: Wrench, ctx: Context) -> None:
        ctx.publish("out", Wrench(force=np.array([np.nan, 0.0, 0.0]), torque=np.zeros(3)), stamp_ns=msg.header.stamp_ns)


def test_an_invalid_published_message_is_rejected_by_its_subscriber_as_on_the_bus():
    keeper = _Keeper()
    ex = InProcessExecutor([_NanRelay(), keeper], names=["relay", "keeper"], keep_published=False)
    ex.feed([(5, "ft/wrench", _wrench(0, 5))])
    ex.run()
    host = ex.host("keeper")
    assert keeper.got == [] and host.counters["in.ft/relayed.rejected"] == 1
    assert "NaN" in host.last_error


class _MovingDeadline(Node):
    """Asks for a deadline at 5 ms, moves it to 8 ms on the first wrench, back to 5 ms on
    the second; records when ``on_deadline`` runs (ns) and stops asking once it ran."""

    name = "moving_deadline"
    inputs = {"wrench": Input("ft/wrench", Wrench)}

    def __init__(self) -> None:
        super().__init__()
        self.due: int | None = 5_000_000
        self.fired: list[int] = []
        self.seen = 0

    def on_wrench(self, msg: Wrench, ctx: Context) -> None:
        self.seen += 1
        self.due = 8_000_000 if self.seen == 1 else 5_000_000

    def next_deadline_ns(self) -> int | None:
        return self.due

    def on_deadline(self, ctx: Context) -> None:
        self.fired.append(ctx.now_ns())
        self.due = None


def test_a_moved_deadline_fires_at_its_new_time_only_and_one_moved_back_fires_again():
    moved = _MovingDeadline()
    ex = InProcessExecutor([moved])
    ex.feed([(1_000_000, "ft/wrench", _wrench(0, 1_000_000))])
    ex.run(until_ns=20_000_000)
    assert moved.fired == [8_000_000]  # not at the 5 ms it asked for first

    back = _MovingDeadline()
    ex = InProcessExecutor([back])
    ex.feed([(1_000_000, "ft/wrench", _wrench(0, 1_000_000)), (2_000_000, "ft/wrench", _wrench(1, 2_000_000))])
    ex.run(until_ns=20_000_000)
    assert back.fired == [5_000_000]  # moved to 8 ms, then back to 5 ms: fires once, at 5 ms
    assert ex.now_ns == 20_000_000


class _Writer(Node):
    """A device-side node: writes one byte to its simulated port every 3 ms."""

    name = "writer"

    def __init__(self) -> None:
        self.device = SimDevice("sim:/dev/wake-test")
        self.timers = {"tick": 0.003}
        self.written: list[int] = []

    def start(self, ctx: Context) -> None:
        self.device.plug()

    def on_timer_tick(self, ctx: Context) -> None:
        self.device.write(b"x")
        self.written.append(ctx.now_ns())

    def stop(self, ctx: Context) -> None:
        self.device.unplug()


class _Ticker(Node):
    """Makes a simulated instant every 0.5 ms (nothing else)."""

    name = "ticker"
    timers = {"tick": 0.0005}

    def on_timer_tick(self, ctx: Context) -> None:
        pass


class _PortReader(Node):
    """A driver-like node: due at once while bytes wait on its link, no bus input."""

    name = "reader"

    def __init__(self) -> None:
        self.link = SimLink("/dev/wake-test", stale_after_s=1.0)
        self.received: list[int] = []
        self.deadline_reads = 0

    def start(self, ctx: Context) -> None:
        self.link.open(ctx.now_ns())

    def io_sources(self) -> list:
        return []

    def next_deadline_ns(self) -> int | None:
        self.deadline_reads += 1
        return self.link.next_attempt_ns()

    def on_deadline(self, ctx: Context) -> None:
        if not self.link.is_open:
            self.link.open(ctx.now_ns())
        self.received += [ctx.now_ns()] * len(self.link.recv(ctx.now_ns()))


def test_a_device_write_wakes_its_reader_at_that_instant_and_only_writes_make_it_read_deadlines():
    def run(io_changes) -> tuple[list[int], list[int], int]:
        writer, reader = _Writer(), _PortReader()
        ex = InProcessExecutor([writer, _Ticker(), reader], io_changes=io_changes)
        ex.run(until_ns=300_000_000)
        ex.stop()
        return writer.written, reader.received, reader.deadline_reads

    written, received, reads_on_change = run(host_side_changes)
    written_all, received_all, reads_every_instant = run(None)
    assert len(written) == 100 and received == written  # every byte read at the instant it was written
    assert (written_all, received_all) == (written, received)
    assert reads_every_instant > 600  # one per simulated instant (600 of them)
    assert reads_on_change < 350  # only after a write (100) and after the reader's own calls


class _TwoPortWriter(Node):
    """Writes one byte to each of two simulated devices every 2 ms."""

    name = "two_writer"
    timers = {"tick": 0.002}

    def __init__(self) -> None:
        self.devices = [SimDevice("/dev/order-a"), SimDevice("/dev/order-b")]

    def start(self, ctx: Context) -> None:
        for device in self.devices:
            device.plug()

    def on_timer_tick(self, ctx: Context) -> None:
        for device in self.devices:
            device.write(b"x")

    def stop(self, ctx: Context) -> None:
        for device in self.devices:
            device.unplug()


class _PublishingReader(Node):
    """Reads its device when due and publishes one wrench per read; logs its reads."""

    def __init__(self, path: str, topic: str, log: list[str]) -> None:
        self.name = f"reader_{topic}"
        self.outputs = {"out": Output(topic, Wrench)}
        self.link = SimLink(path, stale_after_s=1.0)
        self.log = log

    def start(self, ctx: Context) -> None:
        self.link.open(ctx.now_ns())

    def io_sources(self) -> list:
        return []

    def next_deadline_ns(self) -> int | None:
        return self.link.next_attempt_ns()

    def on_deadline(self, ctx: Context) -> None:
        if self.link.recv(ctx.now_ns()):
            self.log.append(f"{self.name} read at {ctx.now_ns()}")
            ctx.publish("out", _wrench(0, ctx.now_ns()), stamp_ns=ctx.now_ns())


class _OrderSink(Node):
    """Logs the messages of both readers as they arrive."""

    name = "sink"
    inputs = {"a": Input("a", Wrench), "b": Input("b", Wrench)}

    def __init__(self, log: list[str]) -> None:
        self.log = log

    def on_a(self, msg: Wrench, ctx: Context) -> None:
        self.log.append(f"a delivered at {ctx.now_ns()}")

    def on_b(self, msg: Wrench, ctx: Context) -> None:
        self.log.append(f"b delivered at {ctx.now_ns()}")


def test_readers_woken_by_one_write_all_read_before_what_they_publish_is_delivered():
    """Two I/O nodes made due by the same device writes read in node order, and both read before
    either's message reaches a subscriber: a deadline found due when the executor re-reads them
    comes before the messages the first reader's handler publishes at that instant."""
    log: list[str] = []
    ex = InProcessExecutor([_TwoPortWriter(), _OrderSink(log), _PublishingReader("/dev/order-a", "a", log),
                            _PublishingReader("/dev/order-b", "b", log)], io_changes=host_side_changes)
    ex.run(until_ns=4_500_000)
    ex.stop()
    assert log == [f"{what} at {t}" for t in (2_000_000, 4_000_000)
                   for what in ("reader_a read", "reader_b read", "a delivered", "b delivered")]
