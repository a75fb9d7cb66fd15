"""What a recording misses, per topic: every frame a publisher sent that is not in the file.

A recorder sees each publisher's frames in order (``header.seq``) and each node's
``diagnostics`` (``out.<topic>.published``; the last, sent as it stops, carries ``stopped``);
a launched recorder also reads what each node reported publishing as it stopped
(:data:`NUMBERED_REPORT`). Missing = sequence gaps (a restarted publisher's first numbers
too) + before the first frame received + after the last + received but not written (a full
disk). docs/safety.md, "Availability and evidence", states the contract.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

from slipstack.lib.errors import DecodeError
from slipstack.messages import Diagnostics, decode
from slipstack.messages.frame import FrameHeader, publisher_key
from slipstack.nodes.recording.bag_io import LOSS_METADATA, RecordingWriter
from slipstack.nodes.runtime.host import DIAGNOSTICS_TOPIC as DIAGNOSTICS, STOPPED_COUNTER

__all__ = ["LossLedger", "MAX_STREAMS", "NUMBERED_REPORT", "RECORDING_REPORT", "exported_loss", "loss_text",
           "written_loss"]

NUMBERED_REPORT = "numbered.json"
"""Written into the run directory by the launcher once the graph's other processes stopped and
before the recorder stops: node → topic → frames it published (their stop reports)."""

RECORDING_REPORT = "recording.json"
"""Written into the run directory by a launched recorder as it stops: ``{"path", "topics": loss per
topic, "error"}``; the launcher adds it to the run's summary."""
MAX_STREAMS = 1024
"""Publishers (topic, or diagnostics per node) tracked; frames of further ones are counted, not tracked."""
MAX_PUBLISHERS_PER_TOPIC = 8
"""Nodes whose published counts are kept per topic (the tail is known only with one)."""


@dataclass
class _Stream:
    first_seq: int
    last_seq: int
    gaps: int = 0


@dataclass
class _Published:
    """A node's newest count of what it published on one stream, since the stream's last restart."""

    count: int
    final: bool


def _stream_key(topic: str, node: str) -> str:
    """The stream a node's frames on ``topic`` follow (``messages/frame.py: publisher_key``)."""
    return f"{topic}/{node}" if topic == DIAGNOSTICS else topic


def _topic_of(key: str) -> str:
    return DIAGNOSTICS if key.startswith(f"{DIAGNOSTICS}/") else key


class LossLedger:
    """Frames received per publisher, and what the publishers say they sent (module docstring)."""

    def __init__(self) -> None:
        self.received: dict[str, int] = {}
        self._streams: dict[str, _Stream] = {}
        self._published: dict[str, dict[str, _Published]] = {}  # stream → node → its newest count
        self.untracked = 0

    def frame(self, topic: str, payload: bytes, head: FrameHeader | None) -> int:
        """Count one frame received on ``topic`` (``head``: its peeked header); returns how
        many frames of its publisher went missing just before it."""
        self.received[topic] = self.received.get(topic, 0) + 1
        if head is None:
            return 0
        key = publisher_key(topic, payload, head)
        stream = self._streams.get(key)
        gap = 0
        if stream is None:
            if len(self._streams) >= MAX_STREAMS:
                self.untracked += 1
                return 0
            self._streams[key] = _Stream(head.seq, head.seq)
        elif head.seq > stream.last_seq:
            gap = head.seq - stream.last_seq - 1
        else:  # the publisher restarted: its numbers before this one never came
            gap = head.seq
            self._published.pop(key, None)  # a count of the old process says nothing of the new one
        if stream is not None:
            stream.gaps += gap
            stream.last_seq = head.seq
        if topic == DIAGNOSTICS:
            self._diagnostics(payload)
        return gap

    def _diagnostics(self, payload: bytes) -> None:
        try:
            msg = decode(payload, Diagnostics)
        except DecodeError:
            return
        final = bool(msg.counters.get(STOPPED_COUNTER))
        for key, value in msg.counters.items():
            if key.startswith("out.") and key.endswith(".published"):
                topic = key[4:-10]
                sent = value + msg.counters.get(f"out.{topic}.oversized", 0)  # numbered, never sent
                self._count(_stream_key(topic, msg.node), msg.node, _Published(int(sent), final))

    def _count(self, key: str, node: str, published: _Published) -> None:
        nodes = self._published.get(key)
        if nodes is None:
            if len(self._published) >= MAX_STREAMS:
                return
            nodes = self._published[key] = {}
        if node in nodes or len(nodes) < MAX_PUBLISHERS_PER_TOPIC:
            nodes[node] = published

    def numbered_at_stop(self, numbered: dict[str, dict[str, int]]) -> None:
        """Each node's count of what it published, reported as its process stopped (node → topic
        → frames): the exact count of what came after the last frame received."""
        for node, topics in numbered.items():
            for topic, count in topics.items():
                self._count(_stream_key(topic, node), node, _Published(int(count), True))

    def report(self, recorded: dict[str, int], not_written: dict[str, int]) -> dict[str, dict]:
        """Per topic: ``recorded`` (in the file), ``missing`` and its parts, and ``exact``
        (False where what was sent after the last frame is not known: a publisher whose last
        count never came, or several publishing one stream)."""
        keys = set(self._streams) | set(self._published)
        out: dict[str, dict] = {}
        for topic in sorted(set(self.received) | set(recorded) | {_topic_of(k) for k in keys}):
            gaps = before = after = 0
            exact = True
            for key in (k for k in keys if _topic_of(k) == topic):
                stream, publishers = self._streams.get(key), self._published.get(key, {})
                last = stream.last_seq if stream is not None else -1
                if stream is not None:
                    gaps += stream.gaps
                    before += stream.first_seq
                if len(publishers) == 1:
                    (count,) = publishers.values()
                    after += max(0, count.count - last - 1)
                    exact &= count.final
                elif publishers or topic != DIAGNOSTICS:  # the diagnostics of nodes stopping with the recorder
                    exact = False                         # are counted up to their last frame received
            unwritten = not_written.get(topic, 0)
            out[topic] = {"recorded": recorded.get(topic, 0), "missing": gaps + before + after + unwritten,
                          "sequence_gaps": gaps, "before_first": before, "after_last": after,
                          "not_written": unwritten, "exact": exact}
        return out


def written_loss(writer: RecordingWriter) -> dict[str, dict[str, str]]:
    """The loss record (:data:`~slipstack.nodes.recording.bag_io.LOSS_METADATA`) of a writer that was
    handed every frame of its run (the lock-step run's): what misses is what it could not write.
    Flushes the chunk in progress first: a frame is counted once its chunk is written."""
    writer.flush()
    ledger = LossLedger()
    return {LOSS_METADATA: {"topics": json.dumps(ledger.report(dict(writer.counts), dict(writer.not_written)))}}


def exported_loss(loss: dict[str, dict], exported: dict[str, int]) -> dict[str, dict]:
    """The loss of a copy of a recording (``bag export``) holding ``exported`` frames per topic: the
    recording's ``loss`` (:meth:`LossLedger.report`), with its recorded frames the copy lacks (no
    ROS 2 type, undecodable, damaged, not written) as one more part, ``not_exported``."""
    out = {}
    for topic, v in loss.items():
        kept = exported.get(topic, 0)
        recorded = v.get("recorded")
        lacks = max(0, recorded - kept) if isinstance(recorded, int) else 0
        out[topic] = {**v, "recorded": kept, "missing": v["missing"] + lacks, "not_exported": lacks}
    return out


_PARTS = (("sequence_gaps", "gaps"), ("before_first", "before the first"), ("after_last", "after the last"),
          ("not_written", "not written"))


def loss_text(loss: dict[str, dict], *, topics_shown: int | None = None) -> str:
    """One phrase for a recording's loss (:meth:`LossLedger.report`): ``every frame sent is in
    it`` or ``missing ft/wrench 120 of 5000 (after the last 120); …``; with ``topics_shown``,
    the total and that many topics, those missing most first."""
    missing = {t: v for t, v in loss.items() if v["missing"] or not v["exact"]}
    if not missing:
        return "every frame sent is in it"
    at_least = "" if all(v["exact"] for v in missing.values()) else "at least "
    if topics_shown is not None:
        worst = sorted(missing.items(), key=lambda tv: -tv[1]["missing"])
        shown = ", ".join(f"{t} {v['missing']} of {v['recorded'] + v['missing']}" for t, v in worst[:topics_shown])
        total, sent = sum(v["missing"] for v in missing.values()), sum(v["recorded"] + v["missing"] for v in loss.values())
        return f"missing {at_least}{total} of {sent} frames ({shown}{', …' if len(worst) > topics_shown else ''})"
    parts = []
    for topic, v in sorted(missing.items()):
        why = ", ".join(f"{label} {v[key]}" for key, label in _PARTS if v[key])
        least = "" if v["exact"] else "at least "
        parts.append(f"{topic} {least}{v['missing']} of {v['recorded'] + v['missing']}" + (f" ({why})" if why else ""))
    return "missing " + "; ".join(parts)
