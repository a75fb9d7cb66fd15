"""Recordings on disk: MCAP files of slipstack frames (write, read, inspect, replay).

File layout (one MCAP file per recording, https://mcap.dev/spec):

More in docs/modules.md, `nodes/recording/bag_io.py`.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import typing
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, NamedTuple

import numpy as np
from mcap.records import Channel, Chunk, Footer, Message as McapMessage, Metadata, Schema
from mcap.data_stream import ReadDataStream
from mcap.reader import SeekingReader
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import MCAP0_MAGIC, CompressionType, Writer

from slipstack.lib.errors import DecodeError, SlipstackError
from slipstack.lib.output_file import claim_output
from slipstack.messages import Message, decode, registry
from slipstack.messages.base import declared_bounds
from slipstack.messages.frame import FrameHeader, SeqTracker, peek_header, publisher_key
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from slipstack.nodes.runtime.node import Node

__all__ = [
    "SCHEMA_ENCODING", "MESSAGE_ENCODING", "ROS2_MESSAGE_ENCODING", "CLOCK_METADATA", "LOSS_METADATA", "RecordingError",
    "RecordedFrame", "RecordingWriter", "RECORDING_FORMATS", "recording_writer", "claim_recording_path",
    "read_recording", "TopicInfo", "RecordingInfo", "recording_info", "recorded_loss",
    "message_schema", "clock_offset_ns", "recorded_clock_offset_ns",
    "replay_into", "FLOAT_RTOL", "FLOAT_ATOL", "same_value", "same_output", "match_outputs",
]

MESSAGE_ENCODING = "msgpack"
ROS2_MESSAGE_ENCODING = "cdr"
"""The message encoding of a rosbag2 MCAP file, which :func:`read_recording` reads too."""
SCHEMA_ENCODING = "slipstack-fields+json"
CLOCK_METADATA = "slipstack.clock"
LOSS_METADATA = "slipstack.loss"
"""Metadata record written as the recorder closes the file: ``{"topics": JSON}``, what the
file misses per topic (``nodes/recording/loss.py``: ``recorded``, ``missing`` and its parts)."""
DEFAULT_CHUNK_SIZE = 256 * 1024
DEFAULT_FLUSH_PERIOD_S = 1.0


class RecordingError(SlipstackError):
    """A recording cannot be read (not MCAP, truncated when ``tolerant=False``, corrupt)."""


class RecordedFrame(NamedTuple):
    """One recorded frame: receive time (wall-clock ns), topic, payload as on the bus."""

    log_time_ns: int
    topic: str
    payload: bytes
    publish_time_ns: int = 0
    sequence: int = 0


# -- schemas ------------------------------------------------------------------------------

_WIRE = "[type, version, [stamp_ns, seq, pub_ns, {source: stamp_ns}], [fields in order]]"


def _field_rows(cls: type[Message]) -> list[dict[str, Any]]:
    hints = typing.get_type_hints(cls)
    rows = []
    for f in dataclasses.fields(cls):
        if f.name == "header":
            continue
        spec = f.metadata.get("array")
        if spec is not None:
            row = {"name": f.name, "type": "array", "dtype": spec.dtype, "shape": list(spec.shape)}
        else:
            hint = hints[f.name]
            row = {"name": f.name, "type": getattr(typing.get_origin(hint) or hint, "__name__", str(hint))}
            bounds = declared_bounds(f, hint)
            if bounds:
                row["bounds"] = bounds
        row["units"] = f.metadata.get("doc", "")
        rows.append(row)
    return rows


def message_schema(cls: type[Message]) -> dict[str, Any]:
    """The :data:`SCHEMA_ENCODING` document of a message type (JSON-serialisable).

    ``{"type", "version", "wire", "header": [...], "fields": [{"name", "type",
    "dtype"?, "shape"?, "bounds"?, "units"}]}``; ``shape`` entries ``null`` are free,
    ``"rows*cols"`` the product of those fields; ``bounds`` are the field's declared
    limits as JSON Schema keywords (``minimum``, ``enum``, ``maxLength`` …); ``units``
    is the field's declared unit (``""`` if none).
    """
    return {
        "type": cls.TYPE,
        "version": cls.VERSION,
        "wire": _WIRE,
        "header": ["stamp_ns:int", "seq:int", "pub_ns:int", "sources:{str:int}"],
        "fields": _field_rows(cls),
    }




# -- writing ------------------------------------------------------------------------------

def claim_recording_path(path: Path) -> None:
    """Create the empty file ``path`` for a new recording, before anything is recorded, so that
    a path that cannot be written fails at once rather than after a run. Its folder is made if
    its parent exists (``runs/`` in the current directory), never a whole tree (a typo's).

    Raises:
        ConfigError: ``path`` exists (a recording is never overwritten, nor written through a
            link), or cannot be written; the message says what to do.
    """
    claim_output(path, what="the recording", change="pass recording:=NEW.mcap (or path:=NEW.mcap)", force_option=None)


class RecordingWriter:
    """Write frames to an MCAP file (see the module docstring for the layout).

    A write that fails (a full disk) never raises: :attr:`error` keeps it, nothing more is
    written, and every frame from the chunk it cut on is counted per topic in
    :attr:`not_written`; :attr:`counts` are the frames in the file's intact chunks, which
    :func:`read_recording` reads (the file stays unfinished).

    Args:
        path: output file (its folder must exist: :func:`claim_recording_path`).
        chunk_size: close a chunk above this many bytes of frames.
        flush_period_s: close and flush a chunk at most this long (s, in log time)
            after its first message, so a crash loses at most that much.
        wall_minus_monotonic_ns: the host's ``time.time_ns() - time.monotonic_ns()``,
            stored as :data:`CLOCK_METADATA` (``None``: not stored).
    """

    PROFILE = ""
    """The MCAP header's profile (none: slipstack's own layout)."""

    def __init__(
        self,
        path: str | os.PathLike,
        *,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        flush_period_s: float = DEFAULT_FLUSH_PERIOD_S,
        wall_minus_monotonic_ns: int | None = None,
    ) -> None:
        self.path = Path(path)
        self._fh = open(self.path, "wb")
        # chunks are closed here, never inside add_message: each is then flushed whole or counted lost
        self._writer = Writer(self._fh, chunk_size=1 << 62, compression=CompressionType.ZSTD)
        self._chunk_size = chunk_size
        self.wall_minus_monotonic_ns = wall_minus_monotonic_ns
        self._flush_period_ns = round(flush_period_s * 1e9)
        self._chunk_opened_ns: int | None = None
        self._chunk_bytes = 0
        self._schemas: dict[str, int] = {}
        self._channels: dict[tuple[str, str], int] = {}
        self.counts: dict[str, int] = defaultdict(int)
        self._pending: dict[str, int] = defaultdict(int)
        self.not_written: dict[str, int] = defaultdict(int)
        self.error: OSError | None = None
        self.closed = False
        self._guard(lambda: self._writer.start(profile=self.PROFILE, library="slipstack"))
        if wall_minus_monotonic_ns is not None:
            self._guard(lambda: self._writer.add_metadata(
                CLOCK_METADATA, {"wall_minus_monotonic_ns": str(int(wall_minus_monotonic_ns))}))
        self._guard(self._fh.flush)

    def _guard(self, step: Callable[[], object]) -> bool:
        """Run one write ``step``; on an OSError keep it in :attr:`error`, count the chunk in
        progress as not written and write nothing more. True if it succeeded."""
        if self.error is not None:
            return False
        try:
            step()
            return True
        except OSError as exc:
            self.error = exc
            for topic, n in self._pending.items():
                self.not_written[topic] += n
            self._pending.clear()
            try:
                self._fh.close()
            except OSError:  # its buffer could not be written either
                pass
            return False

    def _channel(self, topic: str, head: FrameHeader | None) -> int:
        type_name = head.type_name if head else ""
        key = (topic, type_name)
        cid = self._channels.get(key)
        if cid is None:
            cls = registry.get(type_name)
            schema_id = 0
            if cls is not None:
                schema_id = self._schemas.get(type_name, 0)
                if not schema_id:
                    data = json.dumps(message_schema(cls)).encode()
                    schema_id = self._writer.register_schema(type_name, SCHEMA_ENCODING, data)
                    self._schemas[type_name] = schema_id
            meta = {"type": type_name, "version": str(head.version) if head else ""}
            cid = self._writer.register_channel(topic, MESSAGE_ENCODING, schema_id, meta)
            self._channels[key] = cid
        return cid

    def write(self, topic: str, payload: bytes, log_time_ns: int) -> None:
        """Append one frame received at ``log_time_ns`` (wall-clock ns); after a failed write
        it is only counted in :attr:`not_written`."""
        if self._failed(topic):
            return
        head = peek_header(payload)
        log_time_ns = int(log_time_ns)
        if head is None:
            cid = self._channel(topic, None)
            publish_time = sequence = 0
        else:  # the channel of a known (topic, type) without the registry walk
            cid = self._channels.get((topic, head.type_name)) or self._channel(topic, head)
            publish_time, sequence = head.pub_ns, head.seq & 0xFFFFFFFF
        self._writer.add_message(cid, log_time_ns, payload if type(payload) is bytes else bytes(payload),
                                 publish_time, sequence)
        self._written(topic, log_time_ns, len(payload))

    def _failed(self, topic: str) -> bool:
        """After a failed write: count a frame of ``topic`` as not written; True then."""
        if self.error is None:
            return False
        self.not_written[topic] += 1
        return True

    def _written(self, topic: str, log_time_ns: int, n_bytes: int) -> None:
        """Count a frame of ``n_bytes`` written at ``log_time_ns`` into the chunk in progress,
        and close the chunk if it is big or old enough."""
        self._pending[topic] += 1
        self._chunk_bytes += n_bytes
        if self._chunk_opened_ns is None:
            self._chunk_opened_ns = log_time_ns
        if self._chunk_bytes >= self._chunk_size or log_time_ns - self._chunk_opened_ns >= self._flush_period_ns:
            self.flush()

    def tick(self, now_ns: int) -> None:
        """Flush the chunk in progress if it is older than the flush period (call when idle too)."""
        if self._chunk_opened_ns is not None and now_ns - self._chunk_opened_ns >= self._flush_period_ns:
            self.flush()

    def flush(self) -> None:
        """Close the chunk in progress and hand it to the OS (survives ``kill -9``)."""
        if self._guard(self._writer.flush):
            for topic, n in self._pending.items():
                self.counts[topic] += n
            self._pending.clear()
        self._chunk_opened_ns = None
        self._chunk_bytes = 0

    def close(self, metadata: dict[str, dict[str, str]] | None = None) -> None:
        """Finish the file: last chunk, ``metadata`` records (name → key → value), summary,
        indexes, footer. Idempotent. After a failed write the file is left unfinished."""
        if self.closed:
            return
        self.closed = True
        self.flush()
        for name, record in (metadata or {}).items():
            self._guard(lambda: self._writer.add_metadata(name, record))
        if self._guard(self._writer.finish):
            self._guard(self._fh.close)

    def __enter__(self) -> "RecordingWriter":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


RECORDING_FORMATS = ("slipstack", "ros2")
"""How a recording is written: :class:`RecordingWriter`'s layout, or rosbag2's (``ros2_bag.py``)."""


def recording_writer(path: str | os.PathLike, fmt: str = "slipstack", **kwargs: Any) -> RecordingWriter:
    """A writer of format ``fmt`` (:data:`RECORDING_FORMATS`); ``kwargs`` as :class:`RecordingWriter`'s."""
    if fmt == "ros2":
        from slipstack.nodes.recording.ros2_bag import Ros2RecordingWriter

        return Ros2RecordingWriter(path, **kwargs)
    return RecordingWriter(path, **kwargs)


# -- reading ------------------------------------------------------------------------------

@dataclass
class _ScanState:
    channels: dict[int, Channel] = field(default_factory=dict)
    schemas: dict[int, Schema] = field(default_factory=dict)
    metadata: dict[str, dict[str, str]] = field(default_factory=dict)
    chunks: int = 0
    finished: bool = False
    truncated_at: int | None = None
    error: str = ""


def _check_magic(path: str | os.PathLike, fh: Any) -> None:
    """Raise :class:`RecordingError` unless the file starts like an MCAP file."""
    head = fh.read(len(MCAP0_MAGIC))
    fh.seek(0)
    if not head:
        raise RecordingError(f"{path} is empty (0 bytes): not a recording. Record one with `slipstack bag record`")
    if head != MCAP0_MAGIC:
        raise RecordingError(f"{path} is not an MCAP recording (it starts with {head[:8]!r}, not the MCAP magic); "
                             "give a file written by `slipstack bag record` or the recorder node")


def _scan(path: str | os.PathLike, state: _ScanState, tolerant: bool,
          progress: Callable[[int], None] | None = None) -> Iterator[McapMessage]:
    """Messages in file order; fills ``state``; ``progress(bytes read)`` after each chunk.

    Tolerant: a damaged record ends the sequential read; if the file is finished, its
    chunk index then leads past the damage to the intact chunks after it (a damaged
    chunk costs only its own messages). Not tolerant: the first damage raises.

    Raises:
        RecordingError: not an MCAP file (empty, text, ...), cannot be opened, or damaged
            and not ``tolerant``.
    """
    try:
        fh = open(path, "rb")
    except OSError as exc:
        raise RecordingError(f"cannot open recording {path}: {exc}") from None
    with fh:
        _check_magic(path, fh)
        reader = StreamReader(fh, emit_chunks=True, validate_crcs=True)
        good_until = 0  # file offset up to which every record was read intact
        try:
            for rec in reader.records:
                if isinstance(rec, Chunk):
                    inner = breakup_chunk(rec, validate_crc=True)
                    state.chunks += 1
                else:
                    inner = [rec]
                yield from _take(inner, state)
                good_until = fh.tell()
                if progress is not None:
                    progress(good_until)
        except Exception as exc:  # noqa: BLE001 — any damage ends the sequential read
            # A file cut by kill -9 ends inside a record: mcap raises EndOfFile (an
            # McapError); a torn or corrupt chunk gives a CRC, struct or zstd error.
            state.truncated_at = fh.tell()
            state.error = f"{type(exc).__name__}: {exc}"
            if not tolerant:
                raise RecordingError(f"recording {path} is damaged or unfinished ({state.error})") from None
            yield from _chunks_after(fh, good_until, state)


def _take(records: Iterable[Any], state: _ScanState) -> Iterator[McapMessage]:
    """The messages of ``records``; the other records go into ``state``."""
    for r in records:
        if isinstance(r, McapMessage):
            yield r
        elif isinstance(r, Channel):
            state.channels[r.id] = r
        elif isinstance(r, Schema):
            state.schemas[r.id] = r
        elif isinstance(r, Metadata):
            state.metadata[r.name] = dict(r.metadata)
        elif isinstance(r, Footer):
            state.finished = True


def _chunks_after(fh: Any, offset: int, state: _ScanState) -> Iterator[McapMessage]:
    """Messages of the intact indexed chunks that start at or after ``offset`` (none if the
    file has no summary: an unfinished file); counts the chunks skipped as damaged."""
    try:
        fh.seek(0)  # the reader checks the magic where it starts
        summary = SeekingReader(fh, validate_crcs=True).get_summary()
    except Exception:  # noqa: BLE001 — no readable footer or summary: nothing to recover
        return
    if summary is None or not summary.chunk_indexes:
        return
    state.channels.update(summary.channels)
    state.schemas.update(summary.schemas)
    damaged = recovered = 0
    for index in sorted(summary.chunk_indexes, key=lambda c: c.chunk_start_offset):
        if index.chunk_start_offset < offset:
            continue
        try:
            fh.seek(index.chunk_start_offset + 1 + 8)  # past the opcode and the record length
            records = breakup_chunk(Chunk.read(ReadDataStream(fh)), validate_crc=True)
        except Exception:  # noqa: BLE001 — this chunk is damaged too: skip it
            damaged += 1
            continue
        recovered += 1
        state.chunks += 1
        yield from _take(records, state)
    state.finished = True
    state.error += f"; {damaged} chunk(s) skipped as damaged, {recovered} after them read through the index"


def read_recording(
    path: str | os.PathLike, topics: Iterable[str] | None = None, *, tolerant: bool = True,
    progress: Callable[[int], None] | None = None, on_damage: Callable[[str], None] | None = None,
    metadata: dict[str, dict[str, str]] | None = None,
) -> Iterator[RecordedFrame]:
    """Iterate the recorded frames in file (= receive) order.

    A rosbag2 MCAP file (CDR messages) reads as the frames its messages were made of
    (``nodes/recording/ros2_bag.py``; needs the ``ros2`` extra).

    Args:
        path: an MCAP file written by :class:`RecordingWriter` (or any MCAP file).
        topics: keep only these topics (``None``: all).
        tolerant: read an unfinished file (no summary, e.g. after ``kill -9``) up to
            its last intact chunk; ``False`` raises :class:`RecordingError` instead.
        progress: called with the bytes of the file read so far, after each chunk.
        on_damage: called once at the end with what was damaged, if anything was (tolerant).
        metadata: filled at the end with the file's metadata records (name → key → value).
    """
    wanted = None if topics is None else set(topics)
    state = _ScanState()
    ros2 = None  # a rosbag2 layout's reader, made at its first CDR message
    for m in _scan(path, state, tolerant, progress):
        channel = state.channels[m.channel_id]
        if channel.message_encoding == ROS2_MESSAGE_ENCODING:
            if ros2 is None:
                from slipstack.nodes.recording.ros2_bag import Ros2Frames

                ros2 = Ros2Frames(state.channels, state.schemas)
            yield from ros2.frames(m, wanted)
        elif wanted is None or channel.topic in wanted:
            yield RecordedFrame(m.log_time, channel.topic, m.data, m.publish_time, m.sequence)
    if ros2 is not None:
        yield from ros2.flush()
    if metadata is not None:
        metadata.update(state.metadata)
    if state.error and on_damage is not None:
        on_damage(state.error)


@dataclass(frozen=True)
class TopicInfo:
    """Per-topic numbers of a recording.

    rate_hz: (count − 1) / (last − first receive time). seq_gaps: sequence numbers
    missing between consecutive frames of each publisher in the file (a restart, where
    seq goes back, is not a gap). missing: every frame sent and not in the file, as the
    recorder counted it when it closed the file (:data:`LOSS_METADATA`; ``None``: not
    known, the file was not closed by a recorder), with its parts in ``loss``.
    """

    topic: str
    types: tuple[str, ...]
    count: int
    rate_hz: float
    seq_gaps: int
    first_seq: int
    last_seq: int
    missing: int | None = None
    loss: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class RecordingInfo:
    """What ``slipstack bag info`` prints. Times are log times (wall-clock ns, or simulated); topics are bus
    topics (a rosbag2 file's ``/slipstack/<topic>`` and its ``…/info`` are one)."""

    path: Path
    size_bytes: int
    finished: bool
    chunk_count: int
    message_count: int
    start_ns: int
    end_ns: int
    topics: dict[str, TopicInfo]
    damage: str = ""
    left_out: dict[str, str] = field(default_factory=dict)
    """A rosbag2 file's channels not read as frames → why (``Ros2Frames.left_out``)."""
    ros2: bool = False
    """Its messages are ROS 2 (CDR) ones; counted as the frames they make, one per bus frame."""
    simulated_clock: bool = False
    """Its log times are ns of the simulated clock from the run's start, not wall-clock time (a
    lock-step run's, whose :data:`CLOCK_METADATA` offset is 0)."""

    @property
    def duration_s(self) -> float:
        return (self.end_ns - self.start_ns) / 1e9 if self.message_count else 0.0


def recording_info(path: str | os.PathLike, progress: Callable[[int], None] | None = None) -> RecordingInfo:
    """Scan a recording (finished or not) and count what it holds; ``progress`` as for
    :func:`read_recording`."""
    state = _ScanState()
    counts: dict[str, int] = defaultdict(int)
    first: dict[str, int] = {}
    last: dict[str, int] = {}
    types: dict[str, set[str]] = defaultdict(set)
    seq_first: dict[str, int] = {}
    seq_last: dict[str, int] = {}
    gaps: dict[str, int] = defaultdict(int)
    seq_tracker = SeqTracker()
    ros2 = None  # a rosbag2 layout's reader: its messages counted as the frames they make (read_recording)

    def count(frame: RecordedFrame, type_name: str) -> None:
        topic = frame.topic
        counts[topic] += 1
        first.setdefault(topic, frame.log_time_ns)
        last[topic] = frame.log_time_ns
        types[topic].add(type_name)
        head = peek_header(frame.payload)
        seq = head.seq if head else frame.sequence
        seq_first.setdefault(topic, seq)
        seq_last[topic] = seq
        gaps[topic] += seq_tracker.update(seq, publisher_key(topic, frame.payload, head))

    for m in _scan(path, state, tolerant=True, progress=progress):
        ch = state.channels[m.channel_id]
        schema = state.schemas.get(ch.schema_id)
        if ch.message_encoding == ROS2_MESSAGE_ENCODING:
            if ros2 is None:
                from slipstack.nodes.recording.ros2_bag import Ros2Frames

                ros2 = Ros2Frames(state.channels, state.schemas)
            for frame in ros2.frames(m, None):
                count(frame, ros2.topic_types.get(frame.topic, ""))
        else:
            count(RecordedFrame(m.log_time, ch.topic, m.data, m.publish_time, m.sequence),
                  ch.metadata.get("type") or (schema.name if schema is not None else ""))
    for frame in ros2.flush() if ros2 is not None else ():
        count(frame, ros2.topic_types.get(frame.topic, ""))
    loss = recorded_loss(state.metadata) or {}
    topics = {
        t: TopicInfo(
            t, tuple(sorted(types[t])), counts[t],
            (counts[t] - 1) / ((last[t] - first[t]) / 1e9) if last[t] > first[t] else 0.0,
            gaps[t], seq_first[t], seq_last[t],
            loss[t]["missing"] if t in loss else None, loss.get(t, {}),
        )
        for t in sorted(counts)
    }
    for t in sorted(set(loss) - set(counts)):  # a topic sent and wholly missing
        topics[t] = TopicInfo(t, (), 0, 0.0, 0, 0, 0, loss[t]["missing"], loss[t])
    return RecordingInfo(
        Path(path), os.path.getsize(path), state.finished, state.chunks, sum(counts.values()),
        min(first.values(), default=0), max(last.values(), default=0), topics, state.error,
        ros2.left_out if ros2 is not None else {}, ros2 is not None,
        state.metadata.get(CLOCK_METADATA, {}).get("wall_minus_monotonic_ns") == "0",
    )


def recorded_loss(metadata: dict[str, dict[str, str]]) -> dict[str, dict[str, Any]] | None:
    """Topic → its loss, from a file's metadata records (:data:`LOSS_METADATA`); ``None`` if it has
    none (no recorder closed it), empty if it is unreadable."""
    record = metadata.get(LOSS_METADATA)
    if record is None:
        return None
    try:
        topics = json.loads(record.get("topics", "{}"))
        return {str(t): v for t, v in topics.items() if isinstance(v, dict) and isinstance(v.get("missing"), int)}
    except (ValueError, AttributeError):
        return {}


def clock_offset_ns(path: str | os.PathLike, frames: list[RecordedFrame] | None = None) -> int:
    """Wall minus monotonic clock of the recording host, ns: log time − this = receive
    time on the stamps' clock.

    From the :data:`CLOCK_METADATA` record; without one, estimated from ``frames`` as
    min(log time − publish time) (i.e. assuming the fastest frame took no time).
    """
    recorded = recorded_clock_offset_ns(path)
    if recorded is not None:
        return recorded
    frames = frames if frames is not None else list(read_recording(path))
    return min((f.log_time_ns - f.publish_time_ns for f in frames), default=0)


def recorded_clock_offset_ns(path: str | os.PathLike) -> int | None:
    """The :data:`CLOCK_METADATA` offset (wall − monotonic, ns) of a recording; ``None`` if it has none."""
    state = _ScanState()
    for _ in _scan(path, state, tolerant=True):
        break  # the metadata record precedes the first chunk
    meta = state.metadata.get(CLOCK_METADATA)
    return int(meta["wall_minus_monotonic_ns"]) if meta else None




# -- replay into a node -------------------------------------------------------------------

def replay_into(
    node: Node,
    path: str | os.PathLike,
    input_topics: Iterable[str] | None = None,
    *,
    timing: str = "receive",
    remap: dict[str, str] | None = None,
    log: Callable[[str], None] | None = None,
) -> dict[str, list[Message]]:
    """Feed a recording's input frames to one node in an :class:`InProcessExecutor`.

    Args:
        node: a fresh node object (its state starts empty).
        input_topics: topics to feed (default: the node's input topics after ``remap``).
        timing: ``receive`` feeds each frame at the recorder's receive time put on the
            monotonic clock of the stamps (log time − :data:`CLOCK_METADATA` offset;
            if absent, the offset is estimated as min(log time − pub_ns)) — the
            interleaving of topics the live graph saw; ``stamp`` feeds at
            ``header.stamp_ns`` (sample order). Either way ``ctx.now_ns()`` is on the
            stamps' clock, so ages (now − stamp) stay meaningful.
        remap: the node's default topic → topic (as in its launch entry).
        log: receives the node's log lines (``[name] text``; default: kept by the executor).

    Returns:
        topic → messages the node published (decoded, in publication order).

    The payloads fed are the recorded bytes, so the node decodes exactly what it
    received live. Outputs reproduce the live ones in body, ``stamp_ns`` and
    ``sources`` when the node derives them from its inputs; ``pub_ns`` (executor
    time) differs, and ``seq`` differs if the recording began mid-stream — compare
    with :func:`same_output` / :func:`match_outputs`.
    """
    if timing not in ("receive", "stamp"):
        raise ValueError(f"timing must be 'receive' or 'stamp', got {timing!r}")
    remap = remap or {}
    topics = set(input_topics) if input_topics is not None else {
        remap.get(i.topic, i.topic) for i in node.inputs.values()
    }
    frames = list(read_recording(path, topics))
    events = []
    if timing == "stamp":
        for f in frames:
            head = peek_header(f.payload)
            if head is not None:
                events.append((head.stamp_ns, f.topic, f.payload))
    else:
        offset = clock_offset_ns(path, frames)
        events = [(f.log_time_ns - offset, f.topic, f.payload) for f in frames]
    start = min((t for t, _, _ in events), default=0)
    ex = InProcessExecutor([node], remaps={node.name: remap}, start_ns=start, log=log)
    ex.feed(events)
    ex.run()
    ex.stop()
    return dict(ex.published)


FLOAT_RTOL = 1e-9
"""Relative tolerance of :func:`same_output` for float64 values (float32: 8 of its ulps, 9.5e-7);
docs/portability.md §1 says why replays compare floats with one."""
FLOAT_ATOL = 1e-12
"""Absolute floor of that tolerance, in the field's SI unit (for values that cancel to ~0)."""


def _float_rtol(dtype: np.dtype) -> float:
    return max(FLOAT_RTOL, 8 * float(np.finfo(dtype).eps))


def same_value(x: Any, y: Any) -> bool:
    """True if ``x`` and ``y`` are the same field value: floats within :data:`FLOAT_RTOL` /
    :data:`FLOAT_ATOL` (NaN equal to NaN, infinities exact); integers, strings, booleans and
    array dtypes and shapes exact; dicts, lists and tuples item by item."""
    if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
        if not (isinstance(x, np.ndarray) and isinstance(y, np.ndarray)) or x.dtype != y.dtype or x.shape != y.shape:
            return False
        if x.dtype.kind not in "fc":
            return bool(np.array_equal(x, y))
        return bool(np.isclose(x, y, rtol=_float_rtol(x.dtype), atol=FLOAT_ATOL, equal_nan=True).all())
    if (isinstance(x, float) or isinstance(y, float)) and _is_number(x) and _is_number(y):
        x, y = float(x), float(y)
        if math.isnan(x) or math.isnan(y):
            return math.isnan(x) and math.isnan(y)
        return x == y or (math.isfinite(x) and math.isfinite(y)
                          and abs(x - y) <= FLOAT_ATOL + FLOAT_RTOL * max(abs(x), abs(y)))
    if isinstance(x, dict) and isinstance(y, dict):
        return x.keys() == y.keys() and all(same_value(x[k], y[k]) for k in x)
    if isinstance(x, (list, tuple)) and isinstance(y, (list, tuple)):
        return len(x) == len(y) and all(same_value(a, b) for a, b in zip(x, y))
    return bool(x == y)


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))


def same_output(a: Message, b: Message, *, check_seq: bool = False) -> str | None:
    """``None`` if ``a`` and ``b`` are the same output, else the first differing field.

    Same means: same type, equal ``header.stamp_ns`` and ``header.sources`` (and
    ``header.seq`` if ``check_seq``), and body fields that are :func:`same_value` (floats
    within the stated tolerance, everything else exact). ``header.pub_ns`` is ignored:
    it is executor time.
    """
    if type(a) is not type(b):
        return f"type ({a.TYPE} vs {b.TYPE})"
    for label, x, y in (("header.stamp_ns", a.header.stamp_ns, b.header.stamp_ns),
                        ("header.sources", a.header.sources, b.header.sources)):
        if x != y:
            return f"{label} ({x!r} vs {y!r})"
    if check_seq and a.header.seq != b.header.seq:
        return f"header.seq ({a.header.seq} vs {b.header.seq})"
    for name in a._body_fields:  # type: ignore[attr-defined]
        x, y = getattr(a, name), getattr(b, name)
        if not same_value(x, y):
            return name if isinstance(x, np.ndarray) else f"{name} ({x!r} vs {y!r})"
    return None


class OutputMatch(NamedTuple):
    """Result of :func:`match_outputs`: pairs compared, mismatches, unmatched counts."""

    matched: int
    mismatches: list[tuple[int, str]]
    only_recorded: int
    only_replayed: int


def match_outputs(recorded: list[Message], replayed: list[Message]) -> OutputMatch:
    """Pair recorded and replayed outputs by ``header.stamp_ns`` and compare each pair.

    A recording starts and ends mid-stream, so outputs whose inputs (or whose
    outputs) fall outside it are counted as unmatched, not as mismatches.
    mismatches: ``(stamp_ns, what differs)`` from :func:`same_output`.
    """
    by_stamp: dict[int, list[Message]] = defaultdict(list)
    for m in replayed:
        by_stamp[m.header.stamp_ns].append(m)
    matched = 0
    mismatches = []
    only_recorded = 0
    for m in recorded:
        bucket = by_stamp.get(m.header.stamp_ns)
        if not bucket:
            only_recorded += 1
            continue
        other = bucket.pop(0)
        matched += 1
        diff = same_output(m, other)
        if diff is not None:
            mismatches.append((m.header.stamp_ns, diff))
    only_replayed = sum(len(v) for v in by_stamp.values())
    return OutputMatch(matched, mismatches, only_recorded, only_replayed)
