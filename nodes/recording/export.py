"""``bag export``: a recording as JSON that Foxglove opens, as JSON lines, or as ROS 2 (``ros2_bag.py``).

The MCAP export (``mcap-json``) holds:

More in docs/modules.md, `nodes/recording/export.py`.
"""

from __future__ import annotations

import base64
import itertools
import json
import os
import sys
from pathlib import Path
from typing import Any, Callable, Iterable

import numpy as np
from mcap.writer import CompressionType, Writer

from slipstack.lib.errors import DecodeError
from slipstack.lib.output_file import output_file
from slipstack.messages import Cor, TactileFrame, Wrench, decode
from slipstack.messages.json_schema import TIME_SCHEMA, json_schema, to_json, wall_time
from slipstack.nodes.recording.foxglove_scene import PAD_FRAME, SCENE_TOPIC, SCENE_UPDATE_SCHEMA, ContactScene
from slipstack.nodes.recording.bag_io import (
    CLOCK_METADATA, DEFAULT_CHUNK_SIZE, LOSS_METADATA, RecordedFrame, RecordingError, clock_offset_ns, read_recording,
    recorded_clock_offset_ns, recorded_loss,
)

__all__ = ["export_recording", "pad_image", "foxglove_topic", "RAW_IMAGE_SCHEMA", "PAD_IMAGE_TOPIC", "EXPORT_FORMATS"]

EXPORT_FORMATS = ("mcap-json", "jsonl", "ros2")
PAD_IMAGE_TOPIC = "/pad/pressure"
"""The Foxglove topic of the pad image (live and exported)."""


def foxglove_topic(topic: str) -> str:
    """The Foxglove topic of a bus topic, live and exported: ``slip`` → ``/slipstack/slip``."""
    return f"/slipstack/{topic}"


RAW_IMAGE_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "foxglove.RawImage",
    "description": "A raw image (Foxglove's well-known schema)",
    "type": "object",
    "properties": {
        "timestamp": {**TIME_SCHEMA, "description": "Timestamp of image"},
        "frame_id": {"type": "string", "description": "Frame of reference for the image"},
        "width": {"type": "integer", "minimum": 0, "description": "Image width"},
        "height": {"type": "integer", "minimum": 0, "description": "Image height"},
        "encoding": {"type": "string", "description": "Encoding of the raw image data"},
        "step": {"type": "integer", "minimum": 0, "description": "Byte length of a single row"},
        "data": {"type": "string", "contentEncoding": "base64", "description": "Raw image data"},
    },
    "required": ["timestamp", "frame_id", "width", "height", "encoding", "step", "data"],
    "additionalProperties": False,
}
"""Foxglove's ``foxglove.RawImage`` in its JSON Schema form (bytes as base64)."""


def pad_image(frame: TactileFrame, wall_minus_monotonic_ns: int) -> dict[str, Any]:
    """A tactile frame as a ``foxglove.RawImage`` (:data:`RAW_IMAGE_SCHEMA`): ``32FC1``,
    ``cols`` × ``rows`` pixels in Pa, row 0 first, stamped with the sample's wall time."""
    pixels = np.ascontiguousarray(frame.pressure_pa, dtype="<f4")
    return {"timestamp": wall_time(frame.header.stamp_ns + wall_minus_monotonic_ns), "frame_id": PAD_FRAME,
            "width": frame.cols, "height": frame.rows, "encoding": "32FC1", "step": 4 * frame.cols,
            "data": base64.b64encode(pixels.tobytes()).decode("ascii")}


class _McapJson:
    """The ``mcap-json`` output: channels and schemas registered on first use."""

    def __init__(self, fh: Any, source: str | os.PathLike, offset_ns: int, recorded: bool) -> None:
        self._writer = Writer(fh, chunk_size=DEFAULT_CHUNK_SIZE, compression=CompressionType.ZSTD)
        self._writer.start(profile="", library="slipstack")
        self._writer.add_metadata(CLOCK_METADATA, {"wall_minus_monotonic_ns": str(offset_ns)})
        self._writer.add_metadata("slipstack.export", {
            "source": str(source),
            "clock_offset": "recorded" if recorded else "estimated as min(log_time - pub_ns): the recording has none",
            "clocks": "log_time, publish_time, header.stamp: wall clock; header.stamp_ns, pub_ns, sources: "
                      "CLOCK_MONOTONIC of the recording host",
        })
        self._offset_ns = offset_ns
        self._schemas: dict[str, int] = {}
        self._channels: dict[tuple[str, str], int] = {}
        self._scene = ContactScene()

    def _channel(self, topic: str, name: str, schema: Callable[[], dict[str, Any]]) -> int:
        key = (topic, name)
        if key not in self._channels:
            if name not in self._schemas:
                self._schemas[name] = self._writer.register_schema(name, "jsonschema", json.dumps(schema()).encode())
            self._channels[key] = self._writer.register_channel(topic, "json", self._schemas[name])
        return self._channels[key]

    def write(self, topic: str, msg: Any, log_time_ns: int) -> None:
        body = json.dumps(to_json(msg, self._offset_ns)).encode()
        publish = msg.header.pub_ns + self._offset_ns
        seq = msg.header.seq & 0xFFFFFFFF
        self._writer.add_message(self._channel(topic, msg.TYPE, lambda: json_schema(type(msg))), log_time_ns, body,
                                 publish_time=publish, sequence=seq)
        if isinstance(msg, TactileFrame):
            image = json.dumps(pad_image(msg, self._offset_ns)).encode()
            self._writer.add_message(self._channel(PAD_IMAGE_TOPIC, RAW_IMAGE_SCHEMA["title"], lambda: RAW_IMAGE_SCHEMA),
                                     log_time_ns, image, publish_time=publish, sequence=seq)
        elif (isinstance(msg, Wrench) and self._scene.on_wrench(msg)) or (isinstance(msg, Cor) and self._scene.on_cor(msg)):
            scene = json.dumps(self._scene.update(msg.header.stamp_ns + self._offset_ns)).encode()
            self._writer.add_message(self._channel(SCENE_TOPIC, SCENE_UPDATE_SCHEMA["title"], lambda: SCENE_UPDATE_SCHEMA),
                                     log_time_ns, scene, publish_time=publish, sequence=seq)

    def finish(self) -> None:
        self._writer.finish()


def export_recording(path: str | os.PathLike, out: str | os.PathLike, fmt: str = "mcap-json",
                     progress: Callable[[int], None] | None = None, *, force: bool = False,
                     on_damage: Callable[[str], None] | None = None) -> int:
    """Export a recording (see the module docstring); returns the number of messages exported.

    fmt ``mcap-json``: MCAP for Foxglove. ``jsonl``: one line per message,
    ``{"log_time_ns", "topic", "type", "message"}`` (the message as in the MCAP export).
    ``ros2``: MCAP as rosbag2 writes it (:mod:`.ros2_bag`; needs the ``ros2`` extra).
    progress: called with the source file's bytes read so far, now and then.
    force: replace an existing output (else it is refused). on_damage: called with what was
    damaged in the recording, if anything (what could be read is exported all the same).

    Raises:
        RecordingError: unknown format, the output is the input, the input is no recording.
        ConfigError: the output exists (without ``force``) or cannot be written.
    """
    if fmt not in EXPORT_FORMATS:
        raise RecordingError(f"unknown export format {fmt!r}; use {', '.join(EXPORT_FORMATS)}")
    if Path(out).resolve() == Path(path).resolve():
        raise RecordingError(f"export output {out} is the recording itself; choose another path")
    metadata: dict[str, dict[str, str]] = {}  # filled once every frame is read: the loss record is at the end
    frames = read_recording(path, progress=progress, on_damage=on_damage, metadata=metadata)
    first = next(frames, None)  # an unreadable input raises here, before the output exists
    recorded = recorded_clock_offset_ns(path)
    offset = recorded if recorded is not None else clock_offset_ns(path)
    if fmt == "ros2":
        with output_file(Path(out), force=force):
            return _export_ros2(itertools.chain([first] if first is not None else [], frames), out, offset, metadata)
    n = 0
    with output_file(Path(out), force=force), open(out, "wb") as fh:
        mcap = _McapJson(fh, path, offset, recorded is not None) if fmt == "mcap-json" else None
        for frame in itertools.chain([first] if first is not None else [], frames):
            try:
                msg = decode(frame.payload)
            except DecodeError:
                continue
            if mcap is not None:
                mcap.write(foxglove_topic(frame.topic), msg, frame.log_time_ns)
            else:
                line = {"log_time_ns": frame.log_time_ns, "topic": frame.topic, "type": msg.TYPE,
                        "message": to_json(msg, offset)}
                fh.write(json.dumps(line).encode() + b"\n")
            n += 1
        if mcap is not None:
            mcap.finish()
    return n


def _export_ros2(frames: Iterable[RecordedFrame], out: str | os.PathLike, offset_ns: int,
                 metadata: dict[str, dict[str, str]]) -> int:
    """Write ``frames`` as rosbag2 MCAP with the source's loss record (``metadata``, filled as ``frames``
    are read), counting what the export leaves out as missing too."""
    from slipstack.nodes.recording.loss import exported_loss
    from slipstack.nodes.recording.ros2_bag import Ros2RecordingWriter

    with Ros2RecordingWriter(out, wall_minus_monotonic_ns=offset_ns) as writer:
        for frame in frames:
            writer.write(frame.topic, frame.payload, frame.log_time_ns)
        writer.flush()  # counts: the frames in the file
        loss = recorded_loss(metadata)
        if loss is not None:  # none: a file no recorder closed, whose export says "not known" alike
            writer.close({LOSS_METADATA: {"topics": json.dumps(exported_loss(loss, writer.counts))}})
    if writer.skipped:
        left = ", ".join(f"{t} ({n})" for t, n in sorted(writer.skipped.items()))
        print(f"bag export: left out, no ROS 2 message for their type or not decodable: {left}", file=sys.stderr)
    return sum(writer.counts.values())
