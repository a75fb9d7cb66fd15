"""Recordings on disk: MCAP files of slipstack frames (write, read, inspect, replay).

File layout (one MCAP file per recording, https://mcap.dev/spec):

* message_encoding ``msgpack``: every message's data is the frame payload exactly as
  it travelled on the bus (``messages/codec.py`` wire format), so a replay decodes
  the very bytes a node received.
* one channel per (topic, message type); channel metadata ``{"type", "version"}``.
* schema encoding :data:`SCHEMA_ENCODING` (a slipstack-specific name, allowed by the
  MCAP spec for custom encodings): a JSON document describing the type's wire
  layout and fields (name, wire type, dtype, shape, units) — see
  :func:`message_schema`. A payload whose type is unknown gets schema id 0.
* ``log_time``: receive time at the recorder, **wall clock** ns since the Unix epoch
  (the MCAP convention, ``time.time_ns``); ``publish_time`` = ``header.pub_ns`` and
  ``sequence`` = ``header.seq`` (both from the publisher: ``pub_ns`` is on the
  publisher's CLOCK_MONOTONIC, not the wall clock).
* a metadata record :data:`CLOCK_METADATA` written first, holding
  ``wall_minus_monotonic_ns`` of the recording host, so receive times can be put on
  the stamps' monotonic clock (:func:`replay_into`).
* chunked (zstd) and indexed; the writer closes a chunk when it exceeds
  ``chunk_size`` bytes **or** is older than ``flush_period_s``, and flushes it to the
  OS, so a ``kill -9`` loses at most the chunk in progress. :func:`read_recording`
  reads such an unfinished file up to its last intact chunk.
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

from slipstack.lib.errors import ConfigError, DecodeError, SlipstackError
from slipstack.messages import Message, decode, registry
from slipstack.messages.base import declared_bounds
from slipstack.messages.frame import FrameHeader, SeqTracker, peek_header, publisher_key
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from slipstack.nodes.runtime.node import Node

__all__ = [
    "SCHEMA_ENCODING", "MESSAGE_ENCODING", "ROS2_MESSAGE_ENCODING", "CLOCK_METADATA", "RecordingError", "RecordedFrame",
    "RecordingWriter", "RECORDING_FORMATS", "recording_writer", "claim_recording_path", "read_recording", "TopicInfo", "RecordingInfo", "recording_info",
    "message_schema", "clock_offset_ns", "recorded_clock_offset_ns",
    "replay_into", "same_output", "match_outputs",
]

MESSAGE_ENCODING = "msgpack"
ROS2_MESSAGE_ENCODING = "cdr"
"""The message encoding of a rosbag2 MCAP file, which :func:`read_recording` reads too."""
SCHEMA_ENCODING = "slipstack-fields+json"
CLOCK_METADATA = "slipstack.clock"
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
    """Create the empty file ``path`` (and its folders) for a new recording, before anything
    is recorded, so that a path that cannot be written fails at once rather than after a run.

    Raises:
        ConfigError: ``path`` exists (a recording is never overwritten, nor written through a
            link), or cannot be written; the message says what to do.
    """
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        open(path, "xb").close()
    except OSError as exc:
        if os.path.lexists(path):
            raise ConfigError(f"recording {path} exists; pass recording:=NEW.mcap (or path:=NEW.mcap) "
                              "or delete it") from None
        raise ConfigError(f"cannot write the recording {path} ({exc.strerror}); pass recording:=PATH "
                          "in a folder you may write") from None


class RecordingWriter:
    """Write frames to an MCAP file (see the module docstring for the layout).

    Args:
        path: output file (parent folders are created).
        chunk_size: close a chunk above this many bytes.
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
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._fh = open(self.path, "wb")
        self._writer = Writer(self._fh, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile=self.PROFILE, library="slipstack")
        self.wall_minus_monotonic_ns = wall_minus_monotonic_ns
        if wall_minus_monotonic_ns is not None:
            self._writer.add_metadata(CLOCK_METADATA, {"wall_minus_monotonic_ns": str(int(wall_minus_monotonic_ns))})
            self._fh.flush()
        self._flush_period_ns = round(flush_period_s * 1e9)
        self._chunk_opened_ns: int | None = None
        self._schemas: dict[str, int] = {}
        self._channels: dict[tuple[str, str], int] = {}
        self.counts: dict[str, int] = defaultdict(int)
        self.closed = False

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
        """Append one frame received at ``log_time_ns`` (wall-clock ns)."""
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
        self._written(topic, log_time_ns)

    def _written(self, topic: str, log_time_ns: int) -> None:
        """Count a frame written at ``log_time_ns`` and close the chunk if it is old enough."""
        self.counts[topic] += 1
        if self._chunk_opened_ns is None:
            self._chunk_opened_ns = log_time_ns
        if log_time_ns - self._chunk_opened_ns >= self._flush_period_ns:
            self.flush()

    def tick(self, now_ns: int) -> None:
        """Flush the chunk in progress if it is older than the flush period (call when idle too)."""
        if self._chunk_opened_ns is not None and now_ns - self._chunk_opened_ns >= self._flush_period_ns:
            self.flush()

    def flush(self) -> None:
        """Close the chunk in progress and hand it to the OS (survives ``kill -9``)."""
        self._writer.flush()
        self._chunk_opened_ns = None

    def close(self) -> None:
        """Finish the file: last chunk, summary, indexes, footer. Idempotent."""
        if not self.closed:
            self.closed = True
            self._writer.finish()
            self._fh.close()

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
    progress: Callable[[int], None] | None = None,
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


@dataclass(frozen=True)
class TopicInfo:
    """Per-topic numbers of a recording.

    rate_hz: (count − 1) / (last − first receive time). seq_gaps: sequence numbers
    missing between consecutive frames of each publisher (a restart, where seq goes
    back, is not a gap).
    """

    topic: str
    types: tuple[str, ...]
    count: int
    rate_hz: float
    seq_gaps: int
    first_seq: int
    last_seq: int


@dataclass(frozen=True)
class RecordingInfo:
    """What ``slipstack bag info`` prints. Times are wall-clock ns (log time)."""

    path: Path
    size_bytes: int
    finished: bool
    chunk_count: int
    message_count: int
    start_ns: int
    end_ns: int
    topics: dict[str, TopicInfo]
    damage: str = ""

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
    for m in _scan(path, state, tolerant=True, progress=progress):
        ch = state.channels[m.channel_id]
        topic = ch.topic
        counts[topic] += 1
        first.setdefault(topic, m.log_time)
        last[topic] = m.log_time
        schema = state.schemas.get(ch.schema_id)
        types[topic].add(ch.metadata.get("type") or (schema.name if schema is not None else ""))
        head = peek_header(m.data)
        seq = head.seq if head else m.sequence
        seq_first.setdefault(topic, seq)
        seq_last[topic] = seq
        gaps[topic] += seq_tracker.update(seq, publisher_key(topic, m.data, head))
    topics = {
        t: TopicInfo(
            t, tuple(sorted(types[t])), counts[t],
            (counts[t] - 1) / ((last[t] - first[t]) / 1e9) if last[t] > first[t] else 0.0,
            gaps[t], seq_first[t], seq_last[t],
        )
        for t in sorted(counts)
    }
    return RecordingInfo(
        Path(path), os.path.getsize(path), state.finished, state.chunks, sum(counts.values()),
        min(first.values(), default=0), max(last.values(), default=0), topics, state.error,
    )


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
    ex = InProcessExecutor([node], remaps={node.name: remap}, start_ns=start)
    ex.feed(events)
    ex.run()
    ex.stop()
    return dict(ex.published)


def same_output(a: Message, b: Message, *, check_seq: bool = False) -> str | None:
    """``None`` if ``a`` and ``b`` are the same output, else the first differing field.

    Same means: same type, equal ``header.stamp_ns`` and ``header.sources`` (and
    ``header.seq`` if ``check_seq``), and equal body fields (arrays: same dtype, shape
    and values, NaN equal to NaN). ``header.pub_ns`` is ignored: it is executor time.
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
        if isinstance(x, np.ndarray):
            if x.dtype != y.dtype or x.shape != y.shape or not np.array_equal(x, y, equal_nan=x.dtype.kind == "f"):
                return name
        elif x != y and not (isinstance(x, float) and math.isnan(x) and isinstance(y, float) and math.isnan(y)):
            return f"{name} ({x!r} vs {y!r})"
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
