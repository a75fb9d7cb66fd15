"""``slipstack topic hz``, ``topic delay`` and ``topic bw``: a topic's rate, latency or bandwidth, over a window.

Cheap by design (a 1 kHz topic must cost a few percent of a core, ros2cli#795):
payloads are never decoded. The loop blocks in ``poll`` until frames arrive, then
drains them, taking the receive time (CLOCK_MONOTONIC) of each frame. With
``--use-stamps`` the times are the header's ``stamp_ns`` instead, read by
:func:`~slipstack.messages.frame.peek_header` straight from the MessagePack bytes without unpacking the body.

More in docs/modules.md, `nodes/tools/topic_hz.py`.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import deque
from dataclasses import dataclass
from typing import Callable

import numpy as np
import zmq

from slipstack.lib.errors import ConfigError
from slipstack.messages.frame import peek_header
from slipstack.nodes.runtime.graph_info import time_base_clock
from slipstack.nodes.tools.topic_tools import load_graph, resolve_topic
from slipstack.nodes.runtime.stop_signal import stop_on_signals
from slipstack.nodes.runtime.transport import make_sub

__all__ = ["RateStats", "rate_stats", "format_delay", "format_bandwidth", "main_hz", "main_delay", "main_bw"]

_BATCH = 5000


@dataclass(frozen=True)
class RateStats:
    """Rate (Hz) and period statistics (s) over ``window`` time points."""

    rate_hz: float
    min_s: float
    max_s: float
    std_s: float
    window: int


def rate_stats(times_ns: np.ndarray) -> RateStats | None:
    """Statistics of an increasing series of times (integer ns); ``None`` below 2 points."""
    if times_ns.size < 2:
        return None
    periods = np.diff(times_ns) * 1e-9
    span = periods.sum()
    if span <= 0:
        return None
    return RateStats((times_ns.size - 1) / span, float(periods.min()), float(periods.max()),
                     float(periods.std()), int(times_ns.size))


def _format_rate(times_ns: np.ndarray, use_stamps: bool) -> str:
    series = np.sort(times_ns) if use_stamps else times_ns
    s = rate_stats(series)
    if s is None:
        return ""
    return (f"average rate: {s.rate_hz:.3f}\n\tmin: {s.min_s:.6f}s max: {s.max_s:.6f}s "
            f"std dev: {s.std_s:.6f}s window: {s.window}\n")


def format_delay(delays_ns: np.ndarray) -> str:
    """ros2's ``topic delay`` lines for delays (receive time − header stamp, ns)."""
    if not delays_ns.size:
        return ""
    d = delays_ns * 1e-9
    return (f"average delay: {d.mean():.6f}s\n\tmin: {d.min():.6f}s max: {d.max():.6f}s "
            f"std dev: {d.std():.6f}s window: {d.size}\n")


def _size(n: float) -> str:
    """Bytes with the unit ros2 uses (B, KB, MB: powers of 1000)."""
    for unit, scale in (("MB", 1e6), ("KB", 1e3)):
        if n >= scale:
            return f"{n / scale:.2f} {unit}"
    return f"{n:.2f} B" if n != int(n) else f"{int(n)} B"


def format_bandwidth(frames: np.ndarray) -> str:
    """ros2's ``topic bw`` lines for rows ``(receive time ns, payload bytes)``: bytes per
    second over the window (the bytes after the first frame over the time since it) and
    the payload sizes."""
    if frames.shape[0] < 2:
        return ""
    span_s = (frames[-1, 0] - frames[0, 0]) * 1e-9
    if span_s <= 0:
        return ""
    sizes = frames[:, 1]
    return (f"average: {_size(sizes[1:].sum() / span_s)}/s\n\tmean: {_size(float(sizes.mean()))} "
            f"min: {_size(int(sizes.min()))} max: {_size(int(sizes.max()))} window: {frames.shape[0]}\n")


def main_hz(args: argparse.Namespace) -> int:
    """Print rate statistics once per second until Ctrl-C (or ``--duration``)."""
    use_stamps = args.use_stamps
    return _watch(args, lambda now, stamp, size: stamp if use_stamps else now, use_stamps,
                  lambda series: _format_rate(series, use_stamps))


def main_delay(args: argparse.Namespace) -> int:
    """``topic delay``: receive time minus the header's ``stamp_ns`` (the sensor sample the
    message derives from: sample-to-here latency), once per second."""
    return _watch(args, lambda now, stamp, size: now - stamp, True, format_delay)


def main_bw(args: argparse.Namespace) -> int:
    """``topic bw``: payload bytes per second and payload sizes, once per second."""
    return _watch(args, lambda now, stamp, size: (now, size), False, format_bandwidth)


def _watch(args: argparse.Namespace, value: Callable[[int, int, int], object], needs_stamp: bool,
           report: Callable[[np.ndarray], str]) -> int:
    """Collect ``value(receive_ns, stamp_ns, payload bytes)`` (a number or a tuple of
    them) per frame of ``args.topic`` over the last ``args.window`` frames; print
    ``report(values as an int64 array, one row per frame)`` once per second until Ctrl-C
    or ``args.duration``. Receive times and stamps are CLOCK_MONOTONIC ns on the graph's
    time base (with machines: this machine's clock plus its offset to the first machine's)."""
    _, graph = load_graph(args.run_dir)
    info = resolve_topic(graph, args.topic)
    endpoints = [e.address for e in info.publishers if e.address]
    if not endpoints:
        raise ConfigError(f"topic {info.name} has no publisher in this graph")
    if args.window < 2:
        raise ConfigError("--window must be at least 2")
    topic_b = info.name.encode()
    ctx = zmq.Context.instance()
    sock = make_sub(ctx, endpoints, info.name, rcvhwm=max(1000, args.window))
    values: deque[int] = deque(maxlen=args.window)
    append = values.append
    clock = time_base_clock(graph)
    recv = sock.recv_multipart
    unparsed = 0
    new = 0
    start = clock()
    next_print = start + 1_000_000_000
    end = start + round(args.duration * 1e9) if args.duration else None
    out = sys.stdout
    stop_on_signals()
    try:
        while end is None or clock() < end:
            wait_ms = max(0, (next_print - clock()) // 1_000_000)
            if sock.poll(wait_ms):
                for _ in range(_BATCH):
                    try:
                        topic, payload = recv(zmq.NOBLOCK)
                    except zmq.Again:
                        break
                    except ValueError:  # not two parts: not one of ours
                        continue
                    if topic != topic_b:
                        continue
                    new += 1
                    stamp = 0
                    if needs_stamp:
                        head = peek_header(payload)
                        if head is None:
                            unparsed += 1
                            continue
                        stamp = head.stamp_ns
                    append(value(clock(), stamp, len(payload)))
            now = clock()
            if now >= next_print:
                next_print += 1_000_000_000 * (1 + (now - next_print) // 1_000_000_000)
                if not new:
                    out.write("no new messages\n")
                else:
                    out.write(report(np.array(values, dtype=np.int64)))
                    if unparsed:
                        out.write(f"\t{unparsed} frame(s) without a readable header stamp\n")
                new = 0
                out.flush()
    except KeyboardInterrupt:
        pass
    finally:
        sock.close(linger=0)
    return 0
