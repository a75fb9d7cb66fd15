"""The recorder: subscribe to topics of the running graph and write them to MCAP.

Two front ends share :class:`BusRecorder`:

* ``slipstack bag record`` (:func:`record`) — a tool attached to a running graph;
* the ``recorder`` node type, for a launch file (params ``topics``, ``path``).

Discovery: publishers are found in the graph's ``graph.json`` (``nodes/graph_info``),
re-read every :data:`REFRESH_PERIOD_S`, so nodes added later are picked up; a
respawned node binds the same endpoint and ZeroMQ reconnects to it by itself. The
recorder subscribes with its own SUB socket; it is not in the launcher's readiness
handshake, so frames published before it connected are not recorded (the first
recorded sequence number shows how many).

Frames are written raw (the bus bytes) with log_time = receive time,
``time.time_ns()`` (wall clock, the MCAP convention); see ``nodes/recording/bag_io.py``.
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any, Callable

import zmq

from slipstack.lib.errors import ConfigError
from slipstack.nodes.recording.bag_io import RecordingWriter, peek_header, publisher_key
from slipstack.nodes.runtime.curve import secure_connect
from slipstack.nodes.runtime.stop_signal import StopSignal
from slipstack.nodes.runtime.graph_info import (GRAPH_FILE, RUN_DIR_ENV, clock_offset_ns, find_run_dir, read_graph,
                                                topic_endpoints)
from slipstack.nodes.runtime.node import Context, Node
from slipstack.nodes.runtime.transport import make_sub, run_root

__all__ = ["BusRecorder", "Recorder", "RecorderParams", "default_output_path", "record"]

REFRESH_PERIOD_S = 0.5
RCVHWM = 100_000  # a recorder must not drop: ~100 s of a 1 kHz topic


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
    """

    def __init__(
        self,
        writer: RecordingWriter,
        topics: list[str] | None = None,
        *,
        run_dir: Path | None = None,
        accept: Callable[[dict[str, Any]], bool] = lambda graph: True,
    ) -> None:
        self.writer = writer
        self.topics = set(topics or [])
        self.run_dir = run_dir
        self._accept = accept
        self.zctx = zmq.Context.instance()
        self.sock = make_sub(self.zctx, [], None, rcvhwm=RCVHWM)
        if self.topics:  # prefix filters; exact match is checked per frame
            self.sock.setsockopt(zmq.UNSUBSCRIBE, b"")
            for t in sorted(self.topics):
                self.sock.setsockopt(zmq.SUBSCRIBE, t.encode())
        self.endpoints: set[str] = set()
        self.received = 0
        self.lost: dict[str, int] = {}
        self._last_seq: dict[str, int] = {}
        self._next_refresh = 0.0

    def fileno(self) -> int:
        """The socket's ZMQ_FD (readable when frames may be waiting; drain fully)."""
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
        """Write every waiting frame; returns how many. Refreshes the graph when due."""
        n = 0
        while True:
            try:
                parts = self.sock.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                break
            now = time.time_ns()
            if len(parts) != 2:
                continue
            topic = parts[0].decode(errors="replace")
            if self.topics and topic not in self.topics:
                continue
            self._count_seq(topic, parts[1])
            self.writer.write(topic, parts[1], now)
            n += 1
        self.received += n
        self.writer.tick(time.time_ns())
        if time.monotonic() >= self._next_refresh:
            self.refresh()
        return n

    def _count_seq(self, topic: str, payload: bytes) -> None:
        head = peek_header(payload)
        if head is None:
            return
        key = publisher_key(topic, head)
        last = self._last_seq.get(key)
        if last is not None and head.seq > last + 1:
            self.lost[topic] = self.lost.get(topic, 0) + head.seq - last - 1
        self._last_seq[key] = head.seq

    def close(self) -> None:
        """Write what is left and finish the file (summary and indexes)."""
        self.drain()
        self.writer.close()
        self.sock.close(linger=0)


# -- the launch-file node ---------------------------------------------------------------

@dataclass(frozen=True)
class RecorderParams:
    topics: list[str] = field(default_factory=list, metadata={"help": "topics to record; empty: all"})
    path: str = field(default="", metadata={"help": "output .mcap (default runs/<timestamp>.mcap)"})


class Recorder(Node):
    """Records topics of its own graph to an MCAP file (see ``slipstack bag``)."""

    name = "recorder"
    timers = {"poll": 0.05}
    taps_bus = True  # subscribes to every topic in ``params.topics`` (all if empty)
    Params = RecorderParams

    def __init__(self, params: RecorderParams | None = None) -> None:
        super().__init__(params)
        self.bus: BusRecorder | None = None

    def start(self, ctx: Context) -> None:
        path = Path(self.params.path) if self.params.path else default_output_path()
        if os.path.lexists(path):  # never overwrite a recording (or write through a link)
            raise ConfigError(f"recording {path} exists; pass recording:=NEW.mcap (or path:=NEW.mcap) or delete it")
        writer = RecordingWriter(path, wall_minus_monotonic_ns=time.time_ns() - ctx.now_ns())  # the graph's time base
        # Launched: the launcher names our graph in $SLIPSTACK_RUN_DIR and counts us in
        # every publisher's readiness handshake (``taps_bus``), so no first sample is missed.
        env_dir = os.environ.get(RUN_DIR_ENV)
        self.bus = BusRecorder(writer, list(self.params.topics), run_dir=Path(env_dir) if env_dir else None)
        ctx.log(f"recording to {path}")

    def io_sources(self) -> list[BusRecorder]:
        return [self.bus] if self.bus is not None else []

    def on_readable(self, source: BusRecorder, ctx: Context) -> None:
        ctx.count("recorder.written", source.drain())

    def on_timer_poll(self, ctx: Context) -> None:
        if self.bus is not None:
            ctx.count("recorder.written", self.bus.drain())
            for topic, n in self.bus.lost.items():
                ctx.count(f"recorder.{topic}.lost", n)
            self.bus.lost.clear()

    def stop(self, ctx: Context) -> None:
        if self.bus is not None:
            self.bus.close()
            ctx.log(f"wrote {self.bus.writer.path} ({self.bus.received} frames)")


# -- the command line -------------------------------------------------------------------

def record(
    out: Path,
    topics: list[str] | None,
    run_dir: str | None = None,
    duration_s: float | None = None,
    echo: Callable[[str], None] = lambda s: print(s, file=sys.stderr, flush=True),
) -> int:
    """``slipstack bag record``: record until SIGINT/SIGTERM or ``duration_s``; returns the frame count.

    Prints the output path on stdout first.

    Raises:
        ConfigError: no running graph (names how to start one), or a topic no node of
            the graph publishes (names the ones it does); nothing is written then.
    """
    rd = find_run_dir(run_dir)
    graph = read_graph(rd)
    published = topic_endpoints(graph)
    unknown = sorted(set(topics or []) - set(published))
    if unknown:
        raise ConfigError(f"no node of the running graph publishes {', '.join(unknown)}; "
                          f"its topics: {', '.join(sorted(published)) or 'none'} (or -a for all)")
    writer = RecordingWriter(out, wall_minus_monotonic_ns=time.time_ns() - time.monotonic_ns() - clock_offset_ns(graph))
    bus = BusRecorder(writer, topics, run_dir=rd)
    stop = StopSignal().install()
    try:
        bus.refresh()
        if not bus.endpoints:
            echo(f"warning: {rd / GRAPH_FILE} lists no publisher of {', '.join(topics or ['any topic'])} yet; waiting")
        print(out, flush=True)
        echo(f"recording {', '.join(topics) if topics else 'all topics'} from {rd} to {out}")
        end = None if not duration_s else time.monotonic() + duration_s
        poller = zmq.Poller()
        poller.register(bus.sock, zmq.POLLIN)
        while not stop.requested and (end is None or time.monotonic() < end):
            poller.poll(100)
            bus.drain()
    finally:
        bus.close()
        stop.restore()
    lost = ", ".join(f"{t}: {n}" for t, n in sorted(bus.lost.items())) or "none"
    echo(f"wrote {out}: {bus.received} frames; sequence gaps seen: {lost}")
    return bus.received
