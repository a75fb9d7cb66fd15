"""The recorder: subscribe to topics of the running graph and write them to MCAP.

One recorder, the ``recorder`` node (:class:`Recorder`, on :class:`BusRecorder`):
in a launch file (params ``topics``, ``path``) it records its own graph;
``slipstack bag record`` (:func:`record`) runs the same node in its own process,
attached to a running graph.

More in docs/modules.md, `nodes/recording/recorder.py`.
"""

from __future__ import annotations

import json
import os
import time
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any, Callable

import zmq

from slipstack.lib.errors import ConfigError
from slipstack.messages.frame import peek_header
from slipstack.nodes.recording.bag_io import (LOSS_METADATA, RECORDING_FORMATS, RecordingWriter, claim_recording_path,
                                              recording_writer)
from slipstack.nodes.recording.loss import NUMBERED_REPORT, RECORDING_REPORT, LossLedger, loss_text
from slipstack.nodes.runtime.curve import secure_connect
from slipstack.nodes.runtime.graph_info import (RUN_DIR_ENV, find_run_dir, read_graph, time_base_clock,
                                                topic_endpoints)
from slipstack.nodes.runtime.host import DIAGNOSTICS_TOPIC
from slipstack.nodes.runtime.node import Context, Node
from slipstack.nodes.runtime.process import ProcessExecutor, RunSpec
from slipstack.nodes.runtime.tool_pub import tool_name
from slipstack.nodes.runtime.run_dir import write_private_file
from slipstack.nodes.runtime.transport import make_sub, run_root

__all__ = ["BusRecorder", "Recorder", "RecorderParams", "default_output_path", "record"]

REFRESH_PERIOD_S = 0.5
RCVHWM = 100_000  # a recorder must not drop: ~100 s of a 1 kHz topic
DRAIN_LIMIT = 5000  # frames per drain: ~0.1 s of work, then timers and diagnostics get their turn
CLOSE_QUIET_S = 0.2
"""On close, frames are written until none came for this long (the last ones of stopped publishers)."""
BEHIND_AFTER_S = 1.0
"""Frames written later than this after they were sent: the recorder says it is falling behind."""


def default_output_path(now: datetime | None = None) -> Path:
    """``runs/<YYYYmmdd-HHMMSS>.mcap`` under the current directory (local time)."""
    stamp = (now or datetime.now()).strftime("%Y%m%d-%H%M%S")
    return Path("runs") / f"{stamp}.mcap"


class BusRecorder:
    """One SUB socket on the graph's publishers, writing every frame it receives.

    Args:
        writer: where frames go.
        topics: exact topic names to keep; empty: every topic.
        run_dir: the graph's run directory; ``None``: look it up on each refresh
            (``$SLIPSTACK_RUN_DIR`` or ``<run root>/current``), accepting a graph only
            if ``accept(graph)`` says so.
        clock: the graph's clock (ns), that frames are sent on: how far behind the
            writing is (:attr:`lag_ns`).

    Every frame of every publisher is counted (``nodes/recording/loss.py``), the
    ``diagnostics`` too, which tell what each node sent: :meth:`close` returns what the
    file misses per topic and stores it in the file (:data:`LOSS_METADATA`).
    """

    def __init__(
        self,
        writer: RecordingWriter,
        topics: list[str] | None = None,
        *,
        run_dir: Path | None = None,
        accept: Callable[[dict[str, Any]], bool] = lambda graph: True,
        clock: Callable[[], int] = time.monotonic_ns,
    ) -> None:
        self.writer = writer
        self.topics = set(topics or [])
        self.run_dir = run_dir
        self._accept = accept
        self.zctx = zmq.Context.instance()
        self.sock = make_sub(self.zctx, [], None, rcvhwm=RCVHWM)
        if self.topics:  # prefix filters; exact match is checked per frame; diagnostics count the loss
            self.sock.setsockopt(zmq.UNSUBSCRIBE, b"")
            for t in sorted(self.topics | {DIAGNOSTICS_TOPIC}):
                self.sock.setsockopt(zmq.SUBSCRIBE, t.encode())
        self.endpoints: set[str] = set()
        self.received = 0
        self.lost: dict[str, int] = {}
        """Frames missing per topic (sequence gaps) since the node last took them (it clears it)."""
        self.lost_total = 0
        self.ledger = LossLedger()
        self.lag_ns = 0
        """How long after it was sent the newest frame was written (the graph's clock, ns)."""
        self.more_waiting = False
        """The last :meth:`drain` stopped at its limit: more frames may wait."""
        self._clock = clock
        self._next_refresh = 0.0

    def fileno(self) -> int:
        """The socket's ZMQ_FD (readable when frames may be waiting; the node's timer drains what one wake-up left)."""
        return self.sock.getsockopt(zmq.FD)

    def refresh(self) -> None:
        """Connect to publishers listed in ``graph.json`` that are not connected yet."""
        self._next_refresh = time.monotonic() + REFRESH_PERIOD_S
        run_dir = self.run_dir
        if run_dir is None:
            chosen = os.environ.get(RUN_DIR_ENV)
            run_dir = Path(chosen) if chosen else run_root() / "current"
        try:
            graph = read_graph(run_dir)
        except (OSError, ValueError):
            return
        if not self._accept(graph):
            return
        for topic, eps in topic_endpoints(graph).items():
            if self.topics and topic not in self.topics:
                continue
            for ep in eps:
                if ep not in self.endpoints:
                    secure_connect(self.sock, ep)
                    self.sock.connect(ep)
                    self.endpoints.add(ep)

    def drain(self) -> int:
        """Write the waiting frames, at most :data:`DRAIN_LIMIT` (the node's timer drains the
        rest: its diagnostics and status go on while it catches up); returns how many.
        Refreshes the graph when due."""
        n = 0
        head = None
        self.more_waiting = True
        for _ in range(DRAIN_LIMIT):
            try:
                parts = self.sock.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                self.more_waiting = False
                break
            now = time.time_ns()
            if len(parts) != 2:
                continue
            topic = parts[0].decode(errors="replace")
            head = peek_header(parts[1])
            gap = self.ledger.frame(topic, parts[1], head)
            if gap:
                self.lost[topic] = self.lost.get(topic, 0) + gap
                self.lost_total += gap
            if self.topics and topic not in self.topics:
                continue
            self.writer.write(topic, parts[1], now)
            n += 1
        if head is not None:
            self.lag_ns = self._clock() - head.pub_ns
        self.received += n
        self.writer.tick(time.time_ns())
        if time.monotonic() >= self._next_refresh:
            self.refresh()
        return n

    def close(self, numbered: dict[str, dict[str, int]] | None = None) -> dict[str, dict]:
        """Write what is left and finish the file, with what it misses per topic, which is
        returned. ``numbered``: node → topic → frames it published, reported as it stopped (the
        graph has stopped: frames are written until none came for :data:`CLOSE_QUIET_S`)."""
        self.drain()
        while self.more_waiting:
            self.drain()
        while numbered is not None and (self.drain() or self.sock.poll(round(CLOSE_QUIET_S * 1e3))):
            pass
        if numbered:
            try:
                self.ledger.numbered_at_stop(numbered)
            except (TypeError, ValueError, AttributeError):  # not what the launcher writes: left out
                pass
        self.writer.flush()  # the chunk in progress: in the file, or counted as not written
        loss = self.ledger.report(self.writer.counts, self.writer.not_written)
        if self.topics:
            loss = {t: v for t, v in loss.items() if t in self.topics}
        self.writer.close({LOSS_METADATA: {"topics": json.dumps(loss)}})
        self.sock.close(linger=0)
        return loss


# -- the node ---------------------------------------------------------------------------

@dataclass(frozen=True)
class RecorderParams:
    topics: list[str] = field(default_factory=list, metadata={"help": "topics to record; empty: all"})
    path: str = field(default="", metadata={"help": "output .mcap (default runs/<timestamp>.mcap)"})
    run_dir: str = field(default="", metadata={
        "help": "run directory of the graph to record; empty: the graph that launched this node"})
    duration_s: float = field(default=0.0, metadata={"help": "stop after this long (s); 0: until stopped"})
    format: str = field(default="slipstack", metadata={
        "help": "slipstack (msgpack frames as on the bus) or ros2 (as rosbag2 writes MCAP; the ros2 extra)"})


class Recorder(Node):
    """Records topics of a graph to an MCAP file (its own graph in a launch file; the
    one ``slipstack bag record`` attaches to)."""

    name = "recorder"
    timers = {"poll": 0.05}
    taps_bus = True  # subscribes to every topic in ``params.topics`` (all if empty)
    outlives_graph = True  # a launch stops it last and lets it write what it still holds
    Params = RecorderParams

    def __init__(self, params: RecorderParams | None = None, *,
                 on_recording: Callable[[Path], None] | None = None) -> None:
        """``on_recording(path)`` is called once the file is open and the publishers the
        graph lists are connected (``bag record`` prints the path then). Log times are
        mapped to stamps through the executor's clock: the graph's time base (``bag
        record`` gives its executor the graph's, nodes/runtime/time_base.py)."""
        super().__init__(params)
        if self.params.format not in RECORDING_FORMATS:
            raise ConfigError(f"recorder format must be one of {', '.join(RECORDING_FORMATS)}, got {self.params.format!r}")
        if not self.params.duration_s >= 0.0:
            raise ConfigError(f"recorder duration_s must be >= 0 s (0: until stopped), got {self.params.duration_s!r}")
        self.bus: BusRecorder | None = None
        self._on_recording = on_recording
        self._end_ns: int | None = None
        self._behind = False
        self._error_said = False

    def start(self, ctx: Context) -> None:
        p = self.params
        path = Path(p.path) if p.path else default_output_path()
        claim_recording_path(path)  # never overwrites a recording; a path it cannot write fails here
        # stamps are on the graph's time base: wall time = stamp + (wall − graph clock)
        writer = recording_writer(path, p.format, wall_minus_monotonic_ns=time.time_ns() - ctx.now_ns())
        # Launched: the launcher names our graph in $SLIPSTACK_RUN_DIR and counts us in
        # every publisher's readiness handshake (``taps_bus``), so no first sample is missed.
        chosen = p.run_dir or os.environ.get(RUN_DIR_ENV)
        self.bus = BusRecorder(writer, list(p.topics), run_dir=Path(chosen) if chosen else None, clock=ctx.now_ns)
        self.bus.refresh()
        if not self.bus.endpoints:
            ctx.log(f"warning: the graph lists no publisher of {', '.join(p.topics or ['any topic'])} yet; waiting")
        ctx.log(f"recording {', '.join(p.topics) if p.topics else 'all topics'} to {path}")
        if p.duration_s:
            self._end_ns = ctx.now_ns() + round(p.duration_s * 1e9)
        if self._on_recording is not None:
            self._on_recording(path)

    def io_sources(self) -> list[BusRecorder]:
        return [self.bus] if self.bus is not None else []

    def on_readable(self, source: BusRecorder, ctx: Context) -> None:
        ctx.count("recorder.written", source.drain())

    def on_timer_poll(self, ctx: Context) -> None:
        bus = self.bus
        if bus is not None:
            ctx.count("recorder.written", bus.drain())
            for topic, n in bus.lost.items():
                ctx.count(f"recorder.{topic}.lost", n)
            bus.lost.clear()
            self._say_behind(bus.lag_ns, ctx)
            error = bus.writer.error
            if error is not None and not self._error_said:
                self._error_said = True
                ctx.set_status("error", f"cannot write the recording: {error.strerror}")
                ctx.report_error(f"cannot write the recording {bus.writer.path} ({error.strerror}): from now on "
                                 "frames are counted as not written, not recorded; free space on its disk, or "
                                 "record to another (recording:=PATH)")
        if self._end_ns is not None and ctx.now_ns() >= self._end_ns:
            ctx.shutdown()

    def _say_behind(self, lag_ns: int, ctx: Context) -> None:
        """Status ``behind`` (and a log line) while frames are written more than
        :data:`BEHIND_AFTER_S` after they were sent; ``ok`` again once caught up."""
        if self._error_said:
            return
        if not self._behind and lag_ns > BEHIND_AFTER_S * 1e9:
            self._behind = True
            ctx.count("recorder.fell_behind")
            ctx.set_status("behind", f"writing frames {lag_ns / 1e9:.1f} s after they were sent")
            ctx.log(f"warning: falling behind: writing frames {lag_ns / 1e9:.1f} s after they were sent (the "
                    f"machine is busy); they wait in its queue, up to {RCVHWM} per publisher")
        elif self._behind and lag_ns < BEHIND_AFTER_S * 1e9 / 2:
            self._behind = False
            ctx.set_status("ok")
            ctx.log("caught up")

    def stop(self, ctx: Context) -> None:
        if self.bus is None:
            return
        run_dir = os.environ.get(RUN_DIR_ENV) if not self.params.run_dir else None
        numbered = None
        if run_dir:  # launched: what each node published, as the launcher heard it when they stopped
            try:
                numbered = json.loads((Path(run_dir) / NUMBERED_REPORT).read_text())
            except (OSError, ValueError):
                numbered = {}  # the nodes' diagnostics tell it instead, as in `bag record`
        loss = self.bus.close(numbered if isinstance(numbered, dict) else {} if run_dir else None)
        ctx.log(f"wrote {self.bus.writer.path}: {sum(v['recorded'] for v in loss.values())} frames; {loss_text(loss)}")
        if run_dir:  # launched: the launcher adds it to the run's summary
            report = {"path": str(self.bus.writer.path), "topics": loss,
                      "error": self.bus.writer.error.strerror if self.bus.writer.error else ""}
            try:
                write_private_file(Path(run_dir), RECORDING_REPORT, json.dumps(report))
            except OSError as exc:
                ctx.report_error(f"cannot write {RECORDING_REPORT} in the run directory ({exc.strerror})")


# -- the command line -------------------------------------------------------------------

def record(
    out: Path,
    topics: list[str] | None,
    run_dir: str | None = None,
    duration_s: float | None = None,
) -> int:
    """``slipstack bag record``: run a :class:`Recorder` attached to the running graph
    until SIGINT/SIGTERM or ``duration_s``; returns the frame count.

    Prints the output path on stdout once recording.

    Raises:
        ConfigError: no running graph (names how to start one), a topic no node of
            the graph publishes (names the ones it does), or an existing output file;
            nothing is written then.
    """
    rd = find_run_dir(run_dir)
    graph = read_graph(rd)
    published = topic_endpoints(graph)
    unknown = sorted(set(topics or []) - set(published))
    if unknown:
        raise ConfigError(f"no node of the running graph publishes {', '.join(unknown)}; "
                          f"its topics: {', '.join(sorted(published)) or 'none'} (or -a for all)")
    if os.path.lexists(out):
        raise ConfigError(f"{out} exists; choose another -o path or delete it")
    node = Recorder(RecorderParams(topics=list(topics or []), path=str(out), run_dir=str(rd),
                                   duration_s=duration_s or 0.0),
                    on_recording=lambda path: print(path, flush=True))
    if ProcessExecutor([(node, RunSpec(name=tool_name("bag_record")))], clock=time_base_clock(graph)).run() != 0:
        raise ConfigError(f"bag record could not start (said above); nothing was recorded to {out}")
    return node.bus.received if node.bus is not None else 0
