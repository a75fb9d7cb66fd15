"""What both executors share: publishing, receiving, counting, diagnostics.

A :class:`NodeHost` wraps one node. The executor gives it a clock and a ``send``
function; the host fills headers, encodes, decodes and validates incoming frames,
detects sequence gaps, runs handlers without letting them raise, and keeps every
counter that ``diagnostics`` reports.
"""

from __future__ import annotations

import sys
import time
import traceback
from collections import defaultdict, deque
from typing import Any, Callable, Sequence, TypeVar

import numpy as np

from slipstack.lib.errors import DecodeError
from slipstack.messages import Diagnostics, Header, Message, decode, encode
from slipstack.messages.codec import MAX_PAYLOAD_BYTES
from slipstack.messages.frame import SeqTracker
from slipstack.messages.types import MAX_COUNTERS, MAX_TEXT_LEN
from slipstack.nodes.runtime.node import Node
from slipstack.nodes.runtime.stage_cpu import StageCpu

_Delivered = TypeVar("_Delivered")

__all__ = ["NodeHost", "DIAGNOSTICS_TOPIC", "STOPPED_COUNTER"]

DIAGNOSTICS_TOPIC = "diagnostics"
STOPPED_COUNTER = "stopped"
"""Set to 1 in the ``diagnostics`` a node sends as it stops (nodes/recording/loss.py reads it)."""
_MAX_ORIGINS = 256  # (input, origin) sequence trackers kept; the oldest is forgotten first
_MAX_LOGGED_ERRORS = 64  # distinct handler errors remembered so that each is logged once


def _clip(text: str) -> str:
    """Free text cut to what a Diagnostics frame may carry (:data:`MAX_TEXT_LEN` characters)."""
    return text if len(text) <= MAX_TEXT_LEN else text[: MAX_TEXT_LEN - 1] + "…"


class NodeHost:
    """Runs one node's handlers for an executor.

    Args:
        node: the node object.
        name: the instance name in the graph (defaults to the node class's name).
        clock: returns executor time in ns.
        send: ``send(topic, payload)`` puts an encoded frame on the bus.
        remap: default topic name → topic name used in this graph.
        measure_handlers: time handlers with the wall clock for diagnostics (off in
            the deterministic in-process executor).
        log: writes one line.
        stage_cpu: charges this node's decode, handler, encode and send to their
            stages (benchmarks: :mod:`slipstack.nodes.runtime.stage_cpu`); ``None``: off.
        listened: ``listened(topic)`` is true while a subscriber outside this process
            wants ``topic``; when false, a publication is neither encoded nor sent (it
            is still counted, numbered and handed over in-process). ``None``: always send.
        send_raw: ``send_raw(topic, payload)`` for :meth:`publish_raw` (default: ``send``);
            an executor whose ``send`` reaches only outside subscribers delivers raw
            frames in-process with it.
    """

    def __init__(
        self,
        node: Node,
        clock: Callable[[], int],
        send: Callable[[str, bytes], None],
        *,
        name: str | None = None,
        remap: dict[str, str] | None = None,
        measure_handlers: bool = True,
        log: Callable[[str], None] | None = None,
        stage_cpu: StageCpu | None = None,
        listened: Callable[[str], bool] | None = None,
        send_raw: Callable[[str, bytes], None] | None = None,
    ) -> None:
        self.node = node
        self.name = name or node.name
        self.clock = clock
        self._send = send
        self._send_raw = send_raw or send
        remap = remap or {}
        self.input_topics = {n: remap.get(i.topic, i.topic) for n, i in node.inputs.items()}
        self.output_topics = {n: remap.get(o.topic, o.topic) for n, o in node.outputs.items()}
        self._seq: dict[str, int] = {n: 0 for n in node.outputs}
        # counter names, built once (the hot path only indexes them)
        self._published_key = {n: f"out.{t}.published" for n, t in self.output_topics.items()}
        self._in_keys = {
            n: (f"in.{t}.received", f"in.{t}.rejected", f"in.{t}.lost", f"in.{t}.dropped")
            for n, t in self.input_topics.items()
        }
        self._seq_tracker = SeqTracker(_MAX_ORIGINS)
        self._input_types = {n: i.type for n, i in node.inputs.items()}
        self._depths = {n: i.depth for n, i in node.inputs.items()}
        self.counters: dict[str, float] = defaultdict(int)
        self.status = "ok"
        self.detail = ""
        self.last_error = ""
        self._diag_seq = 0
        self.shutdown_requested = False
        self.sender = ""
        """Who sent the message being handled: "" for the graph's own nodes, else the injecting tool."""
        self._measure = measure_handlers
        self._durations: deque[int] = deque(maxlen=2000)
        self._logged_errors: set[tuple[str, str, str]] = set()
        self._log = log or (lambda text: print(text, file=sys.stderr, flush=True))
        self._handlers = {n: (f"on_{n}", getattr(node, f"on_{n}")) for n in node.inputs}  # (label, handler)
        self.on_publish: Callable[[str, Message, Header], None] | None = None
        """Called with every published message and its header (a container's in-process hand-over)."""
        self._timer_handlers = {n: (f"on_timer_{n}", getattr(node, f"on_timer_{n}")) for n in node.timers}
        self.stage_cpu = stage_cpu
        self._listened = listened
        self.stage_keys = {stage: (self.name, stage) for stage in ("receive", "decode", "handler", "encode", "send")}

    # -- the Context a handler sees -------------------------------------------------
    def now_ns(self) -> int:
        return self.clock()

    def input_topic(self, input_name: str) -> str:
        return self.input_topics[input_name]

    def publish(self, output: str, msg: Message, *, stamp_ns: int, sources: dict[str, int] | None = None) -> None:
        stage = self.stage_cpu
        if stage is not None:
            resume = stage.enter(self.stage_keys["encode"])
        seq = self._seq[output]
        self._seq[output] = seq + 1
        topic = self.output_topics[output]
        header = Header(int(stamp_ns), seq, self.clock(), sources or {})
        if self._listened is not None and not self._listened(topic):  # nobody on the bus: no payload
            self.counters[self._published_key[output]] += 1
            if self.on_publish is not None:
                self.on_publish(topic, msg, header)
            if stage is not None:
                stage.enter(resume)
            return
        payload = encode(msg, header)
        if len(payload) > MAX_PAYLOAD_BYTES:  # every receiver would cut the link: never send it
            self.counters[f"out.{topic}.oversized"] += 1
            self.last_error = f"{topic}: a frame of {len(payload)} bytes exceeds {MAX_PAYLOAD_BYTES}; not sent"
        else:
            if stage is not None:
                stage.enter(self.stage_keys["send"])
            self._send(topic, payload)
            self.counters[self._published_key[output]] += 1
            if self.on_publish is not None:
                self.on_publish(topic, msg, header)
        if stage is not None:
            stage.enter(resume)

    def publish_raw(self, topic: str, payload: bytes) -> None:
        """Put an already-encoded frame on the bus unchanged (recording playback)."""
        self._send_raw(topic, payload)
        self.counters[f"out.{topic}.published"] += 1

    def numbered(self) -> dict[str, int]:
        """Topic → frames this node numbered (published) on it so far: its next sequence number,
        ``diagnostics`` included."""
        return {**{self.output_topics[output]: seq for output, seq in self._seq.items()},
                DIAGNOSTICS_TOPIC: self._diag_seq}

    def count(self, name: str, increment: int = 1) -> None:
        counters = self.counters
        if name not in counters and len(counters) >= MAX_COUNTERS - 3:  # the map (+ handler.p50/p99) stays within Diagnostics' bound
            name = "counters.overflow"
        counters[name] += increment

    def set_status(self, status: str, detail: str = "") -> None:
        self.status, self.detail = status, detail

    def log(self, text: str) -> None:
        self._log(text)

    def report_error(self, text: str) -> None:
        self.last_error = text
        self._log(f"error: {text}")

    def shutdown(self) -> None:
        self.shutdown_requested = True

    # -- receiving ---------------------------------------------------------------------
    def receive(self, input_name: str, payload: bytes, origin: str = "", *, skipped: int = 0) -> Message | None:
        """Decode and validate one frame; count it; ``None`` if rejected.

        ``origin`` names the stream the frame came from (the publisher's endpoint, or
        ``"inject/<sender>"`` for frames put in by tools, ``"inject"`` if the sender gave no name): sequence gaps are tracked per topic and
        origin, and a sequence that goes back (a respawned publisher) is no loss.
        ``skipped``: frames of the same origin received before this one but not decoded
        (:meth:`skip`); they fill as much of a sequence gap.
        """
        stage = self.stage_cpu
        if stage is not None:
            resume = stage.enter(self.stage_keys["decode"])
        received, rejected, lost, _ = self._in_keys[input_name]
        counters = self.counters
        counters[received] += 1
        try:
            msg = decode(payload, self._input_types[input_name])
        except DecodeError as exc:
            counters[rejected] += 1
            self.last_error = f"{self.input_topics[input_name]}: {exc}"
            msg = None
        if stage is not None:
            stage.enter(resume)
        if msg is None:
            return None
        gap = self._seq_tracker.update(msg.header.seq, (input_name, origin), skipped)
        if gap:
            counters[lost] += gap
        return msg

    def receive_local(self, input_name: str, msg: Message, rejection: str | None = None) -> None:
        """Handle a message handed over in-process by another node of this process (counted
        as received); ``rejection``: why it failed the decoder's checks
        (:func:`~slipstack.messages.base.handed_over`): then it is counted as rejected and not
        handled, as its frame would be on the bus."""
        if self.accept_local(input_name, msg, rejection) is not None:
            self.dispatch(input_name, msg)

    def accept_local(self, input_name: str, msg: Message, rejection: str | None = None) -> Message | None:
        """Count a message handed over in-process as received, and as rejected when
        ``rejection`` says why it fails the decoder's checks; the message, or ``None`` if rejected
        (a ``batch`` input gathers the accepted ones before its handler runs)."""
        counters = self.counters
        received, rejected, _, _ = self._in_keys[input_name]
        counters[received] += 1
        if rejection is not None:
            counters[rejected] += 1
            self.last_error = f"{self.input_topics[input_name]}: {rejection}"
            return None
        return msg

    def dispatch_batch(self, input_name: str, backlog: Sequence[_Delivered],
                       accept: Callable[[_Delivered, int], Message | None]) -> None:
        """Handle a ``batch`` input's backlog, oldest first, in one call: the oldest beyond the
        input's depth are counted as received and dropped (:meth:`skip`); ``accept(item,
        skipped)`` counts each other one and returns its message, or ``None`` if rejected
        (``skipped``: how many were dropped just before it, which fill a sequence gap — the
        overflow for the first accepted one, then 0)."""
        overflow = len(backlog) - self._depths[input_name]
        if overflow > 0:
            self.skip(input_name, overflow)
            backlog = backlog[overflow:]
        else:
            overflow = 0
        msgs = []
        for item in backlog:
            msg = accept(item, overflow)
            if msg is not None:
                msgs.append(msg)
                overflow = 0
        if msgs:
            self.dispatch(input_name, tuple(msgs))

    def skip(self, input_name: str, n: int) -> None:
        """Count ``n`` frames received but skipped undecoded for a newer one (drain-to-latest)."""
        if n:
            received, _, _, dropped = self._in_keys[input_name]
            self.counters[received] += n
            self.counters[dropped] += n

    def count_dropped(self, input_name: str, n: int) -> None:
        """Count frames skipped on purpose (drain-to-latest, queue overflow)."""
        if n:
            self.counters[self._in_keys[input_name][3]] += n

    def _guarded(self, label: str, fn: Callable[..., None], *args: Any) -> None:
        stage = self.stage_cpu
        if stage is None and not self._measure:  # in-process, no stage CPU: nothing to time
            try:
                fn(*args)
            except Exception as exc:  # a handler bug must not kill the control loop
                self._handler_failed(label, exc)
            return
        if stage is not None:
            resume = stage.enter(self.stage_keys["handler"])
        t0 = time.perf_counter_ns() if self._measure else 0
        try:
            fn(*args)
        except Exception as exc:  # a handler bug must not kill the control loop
            self._handler_failed(label, exc)
        if self._measure:
            self._durations.append(time.perf_counter_ns() - t0)
        if stage is not None:
            stage.enter(resume)

    def _handler_failed(self, label: str, exc: Exception) -> None:
        """Count, show and log (once per distinct error) the exception ``exc`` a callback raised."""
        self.counters["handler_errors"] += 1
        self.status = "error"
        self.detail = f"{label} raised; see log"
        self.last_error = _clip(f"{label}: {type(exc).__name__}: {exc}")
        seen = (label, type(exc).__name__, str(exc))
        if seen not in self._logged_errors:  # a repeating error is logged once, then counted
            if len(self._logged_errors) < _MAX_LOGGED_ERRORS:
                self._logged_errors.add(seen)
            self._log(f"error in {label} (logged once; repeats count as handler_errors on diagnostics):\n"
                      f"{traceback.format_exc().rstrip()}")

    def dispatch(self, input_name: str, msg: Message, *, sender: str = "") -> None:
        """Run the input's handler; exceptions are counted and logged, never raised.
        ``sender``: the tool that injected ``msg`` ("" for the graph's own publishers), the
        handler's ``ctx.sender``."""
        label, handler = self._handlers[input_name]
        if not sender:  # the graph's own: the hot path
            self._guarded(label, handler, msg, self)
            return
        self.sender = sender
        try:
            self._guarded(label, handler, msg, self)
        finally:
            self.sender = ""

    def fire_timer(self, timer: str) -> None:
        label, handler = self._timer_handlers[timer]
        self._guarded(label, handler, self)

    def call(self, label: str, fn: Callable[..., None], *args: Any) -> None:
        """Run any node callback (start, stop, on_readable) under the same guard."""
        self._guarded(label, fn, *args)

    # -- diagnostics -------------------------------------------------------------------
    def diagnostics(self, *, final: bool = False) -> bytes:
        """Encode the node's current :class:`Diagnostics` frame; ``final``: its last, as it
        stops (counter :data:`STOPPED_COUNTER` = 1: what it published is complete)."""
        counters = dict(self.counters)
        if final:
            counters[STOPPED_COUNTER] = 1
        if self._durations:
            d = np.fromiter(self._durations, dtype=np.int64)
            counters["handler.p50_us"] = float(np.percentile(d, 50)) / 1e3
            counters["handler.p99_us"] = float(np.percentile(d, 99)) / 1e3
        if self.stage_cpu is not None:
            counters.update(self.stage_cpu.counters(self.name))
        now = self.clock()
        status = self.status if not self.detail else f"{self.status}: {self.detail}"
        msg = Diagnostics(
            node=self.name,
            status=_clip(status),
            counters=counters,
            last_error=_clip(self.last_error),
            header=Header(now, self._diag_seq, now, {}),
        )
        self._diag_seq += 1
        return encode(msg)
