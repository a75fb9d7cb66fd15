"""End-to-end latency of the real stack: F/T sample → ``grip/command``, with loss and CPU.

More in docs/modules.md, `tests/bench/bench_stack_latency.py`.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import subprocess

import msgpack
import numpy as np
import zmq

from _versions import print_versions
from _stack import ProcSampler, StackRun, free_udp_port, long_scene
from slipstack.nodes.runtime.stage_cpu import STAGE_CPU_ENV

TOPICS = ("ft/wrench", "contact", "slip", "grip/command", "rig/truth", "diagnostics")
TRUTH_SAMPLES = 500  # rig/truth frames kept: enough to pin the rig's t0, then the tap unsubscribes
LIGHT_TOPICS = ("grip/command", "diagnostics")  # --light: end-to-end only, the tap's own load is minimal
TARGET_P50_MS, TARGET_P99_MS = 1.0, 3.0
STAGES = ("poll", "receive", "decode", "handler", "encode", "send", "loop")  # nodes/runtime/stage_cpu.py
LOSS_SUFFIXES = (".lost", ".rejected", ".dropped_hwm")


def _no_ext(code: int, data: bytes) -> None:
    return None  # arrays are not needed here: skip them without numpy


def _unpack(payload: bytes) -> list:
    return msgpack.unpackb(payload, ext_hook=_no_ext, raw=False, strict_map_key=False)


# -- the tap ---------------------------------------------------------------------------------
@dataclass
class Tap:
    """Live subscriber to the graph's publishers; keeps one compact row per message.

    Rows (ints are CLOCK_MONOTONIC ns; ``recv`` is when the tap read the frame):
    ``ft/wrench`` (seq, stamp, pub, recv, device_seq, status); ``contact`` (seq, stamp,
    pub, recv, src_ft, src_tactile); ``slip`` likewise; ``grip/command`` (seq, stamp,
    pub, recv, src_ft, src_tactile, src_slip, reason, src_ft_oldest: the oldest F/T sample of the
    batch the command judged, or src_ft); ``rig/truth`` (seq, stamp, pub,
    recv); ``diagnostics`` (recv, node, counters).
    """

    graph: dict[str, Any]
    topics: tuple[str, ...] = TOPICS
    rows: dict[str, list[tuple]] = field(default_factory=lambda: defaultdict(list))
    gaps: Counter = field(default_factory=Counter)

    def __post_init__(self) -> None:
        self.ctx = zmq.Context()
        self.poller = zmq.Poller()
        self.socks: dict[zmq.Socket, str] = {}
        self._last_seq: dict[tuple[str, str], int] = {}
        for node in self.graph["nodes"].values():
            wanted = [t for t in node["outputs"] if t in self.topics]
            if not node.get("pub") or not wanted:
                continue
            s = self.ctx.socket(zmq.SUB)
            s.setsockopt(zmq.LINGER, 0)
            s.setsockopt(zmq.RCVHWM, 200_000)  # the tap itself must never be the one that drops
            for t in wanted:
                s.setsockopt(zmq.SUBSCRIBE, t.encode())
            s.connect(node["pub"])
            self.poller.register(s, zmq.POLLIN)
            self.socks[s] = node["pub"]

    def close(self) -> None:
        for s in self.socks:
            s.close(linger=0)
        self.ctx.term()

    def run_until(self, t_end_s: float, stop_when: Any = None) -> None:
        """Collect until CLOCK_MONOTONIC ``t_end_s`` (s), or until ``stop_when()`` is true."""
        now = time.monotonic
        while now() < t_end_s:
            for sock, _ in self.poller.poll(50):
                self._drain(sock)
            if stop_when is not None and stop_when():
                return

    def _drain(self, sock: zmq.Socket) -> None:
        origin = self.socks[sock]
        rows, last_seq = self.rows, self._last_seq
        while True:
            try:
                topic_b, payload = sock.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                return
            recv = time.monotonic_ns()
            topic = topic_b.decode()
            if topic == "rig/truth" and len(rows[topic]) >= TRUTH_SAMPLES:
                continue  # unsubscribed below; frames already queued are ignored
            _, _, (stamp, seq, pub, src), body = _unpack(payload)
            key = (topic, origin)
            prev = last_seq.get(key)
            if prev is not None and seq > prev + 1:
                self.gaps[topic] += seq - prev - 1
            last_seq[key] = seq
            if topic == "ft/wrench":
                rows[topic].append((seq, stamp, pub, recv, body[3], body[4]))
            elif topic == "contact":
                rows[topic].append((seq, stamp, pub, recv, src.get("ft"), src.get("tactile")))
            elif topic == "slip":
                rows[topic].append((seq, stamp, pub, recv, src.get("ft"), src.get("tactile"), body[0]))
            elif topic == "grip/command":
                rows[topic].append((seq, stamp, pub, recv, src.get("ft"), src.get("tactile"), src.get("slip"), body[2],
                                    src.get("ft_oldest", src.get("ft"))))
            elif topic == "rig/truth":
                rows[topic].append((seq, stamp, pub, recv))
                if len(rows[topic]) == TRUTH_SAMPLES:  # t0 is known: spare the 1 kHz stream
                    sock.setsockopt(zmq.UNSUBSCRIBE, b"rig/truth")
            else:
                rows[topic].append((recv, body[0], body[2]))


# -- the raw pyzmq + msgpack reference ----------------------------------------------------------
RAW_SUBSCRIBER = r"""
import sys, time, msgpack, zmq
endpoint, topic = sys.argv[1], sys.argv[2]
sock = zmq.Context().socket(zmq.SUB)
sock.setsockopt(zmq.LINGER, 0)
sock.setsockopt(zmq.RCVHWM, 100)
sock.setsockopt(zmq.SUBSCRIBE, topic.encode())
sock.connect(endpoint)
poller = zmq.Poller()
poller.register(sock, zmq.POLLIN)
poller.register(sys.stdin.fileno(), zmq.POLLIN)
n = 0
while True:
    for item, _ in poller.poll(50):
        if item is sock:
            while sock.getsockopt(zmq.EVENTS) & zmq.POLLIN:
                _, payload = sock.recv_multipart(zmq.NOBLOCK)
                msgpack.unpackb(payload, raw=False)
                n += 1
        elif not sys.stdin.readline():
            sys.exit(0)
        else:
            print(n, time.process_time_ns(), flush=True)
"""


class RawSubscriber:
    """The raw pyzmq + msgpack subscriber (:data:`RAW_SUBSCRIBER`) in a process of its own;
    :meth:`mark` returns (messages received, process CPU ns) at that moment."""

    def __init__(self, endpoint: str, topic: str) -> None:
        self.proc = subprocess.Popen([sys.executable, "-c", RAW_SUBSCRIBER, endpoint, topic],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)

    def mark(self) -> tuple[int, int]:
        self.proc.stdin.write("mark\n")
        self.proc.stdin.flush()
        n, cpu_ns = self.proc.stdout.readline().split()
        return int(n), int(cpu_ns)

    def close(self) -> None:
        self.proc.stdin.close()
        try:
            self.proc.wait(5)
        except subprocess.TimeoutExpired:
            self.proc.kill()


# -- statistics ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Dist:
    """Percentiles of a latency sample (µs)."""

    n: int
    p50: float
    p99: float
    p999: float
    max: float

    @staticmethod
    def of(values_ns: Any) -> Dist:
        v = np.asarray(values_ns, dtype=np.float64) / 1e3
        if v.size == 0:
            return Dist(0, math.nan, math.nan, math.nan, math.nan)
        p50, p99, p999 = np.percentile(v, [50, 99, 99.9])
        return Dist(int(v.size), float(p50), float(p99), float(p999), float(v.max()))


def _ms(us: float) -> str:
    return "–" if math.isnan(us) else f"{us / 1e3:.3f}"


def _table(head: list[str], rows: list[list[Any]]) -> str:
    out = ["| " + " | ".join(head) + " |", "|" + "|".join("---" for _ in head) + "|"]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def _dist_rows(named: list[tuple[str, Dist]]) -> list[list[Any]]:
    return [[name, d.n, _ms(d.p50), _ms(d.p99), _ms(d.p999), _ms(d.max)] for name, d in named]


def _counter_window(diags: list[tuple], t0_ns: int, t1_ns: int) -> dict[str, tuple[float, dict[str, float], dict[str, float]]]:
    """Per node: (seconds spanned, counter deltas, last counters) between the last
    diagnostics at or before ``t0_ns`` (else the first after) and the last at or before ``t1_ns``."""
    by_node: dict[str, list[tuple[int, dict]]] = defaultdict(list)
    for recv, node, counters in diags:
        by_node[node].append((recv, counters))
    out = {}
    for node, seq in by_node.items():
        before = [r for r in seq if r[0] <= t0_ns]
        first = before[-1] if before else seq[0]
        upto = [r for r in seq if r[0] <= t1_ns]
        last = upto[-1] if upto else seq[-1]
        delta = {k: v - first[1].get(k, 0) for k, v in last[1].items() if isinstance(v, (int, float))}
        out[node] = ((last[0] - first[0]) / 1e9, delta, last[1])
    return out


@dataclass
class Report:
    sections: list[str] = field(default_factory=list)
    passed: dict[str, bool] = field(default_factory=dict)

    def add(self, title: str, body: str) -> None:
        self.sections.append(f"### {title}\n\n{body}\n")

    def text(self) -> str:
        return "\n".join(self.sections)


def split_watchdog_repeats(cmd: list[tuple]) -> tuple[list[tuple], int]:
    """(commands derived from a new F/T sample, count of watchdog repeats) of the tap's
    ``grip/command`` rows in seq order: a repeat carries the previous command's slip stamp."""
    fresh, repeats = [], 0
    prev_slip = None
    for r in cmd:
        if r[6] is not None and r[6] == prev_slip:
            repeats += 1
        elif r[4] is not None:
            fresh.append(r)
        prev_slip = r[6]
    return fresh, repeats


def analyse(tap: Tap, w0: int, w1: int, args: argparse.Namespace, report: Report) -> None:
    """Fill ``report`` from the tap's rows in the window [w0, w1] (CLOCK_MONOTONIC ns)."""
    rows = tap.rows
    settle = 50_000_000  # an F/T sample this close to the window's end may still be in flight

    def in_window(topic: str) -> list[tuple]:
        return [r for r in rows[topic] if w0 <= r[3] <= w1]

    wrench, contact, slip, cmd = (in_window(t) for t in ("ft/wrench", "contact", "slip", "grip/command"))
    cmd.sort(key=lambda r: r[0])
    fresh, repeats = split_watchdog_repeats(cmd)
    reasons = Counter(r[7] for r in cmd)

    # rig t0 from rig/truth: stamp = t0 + simulated time, seq counts truth samples from t = 0
    truth_period = round(1e9 / args.truth_rate)
    t0_est = np.array([r[1] - r[0] * truth_period for r in rows["rig/truth"]], dtype=np.int64)
    t0 = int(t0_est.min()) if t0_est.size else None
    ft_period = round(1e9 / args.ft_rate)
    sim_of_stamp: dict[int, int] = {}
    wrench_pub: dict[int, int] = {}
    restarted, last_dseq = False, 0
    for seq, stamp, pub, recv, dseq, status in rows["ft/wrench"]:
        if dseq >= 1:
            # a driver re-request (after backoff_ms of silence) restarts the RDT sequence at 1:
            # from then on device_seq no longer counts samples from the scene's start
            restarted = restarted or dseq <= last_dseq
            last_dseq = dseq
            if t0 is not None and not restarted:
                sim_of_stamp[stamp] = t0 + (dseq - 1) * ft_period  # newest sample of a shared stamp
        wrench_pub[stamp] = pub
    contact_pub = {r[4]: r[2] for r in rows["contact"]}
    slip_pub = {r[4]: r[2] for r in rows["slip"]}

    # a driver's status republish (stale / disconnected: device_seq −1, stamped when it noticed)
    # is no sensor sample: commands derived from one are counted, not timed
    status_stamps = {r[1] for r in rows["ft/wrench"] if r[4] < 1}
    from_status = [r for r in fresh if r[4] in status_stamps]
    fresh = [r for r in fresh if r[4] not in status_stamps]
    lat_cmd = [r[2] - r[4] for r in fresh]
    stages = [
        ("driver: F/T receive stamp → ft/wrench publish", Dist.of([r[2] - r[1] for r in wrench if r[4] >= 1])),
        ("F/T stamp → contact publish (fusion)",
         Dist.of([r[2] - r[4] for r in contact if r[4] is not None and r[4] not in status_stamps])),
        ("F/T stamp → slip publish (slip_detector)",
         Dist.of([r[2] - r[4] for r in slip if r[4] is not None and r[4] not in status_stamps])),
        ("**F/T stamp → grip/command publish** (end to end, newest sample of the batch)", Dist.of(lat_cmd)),
        ("**oldest F/T sample of the batch → grip/command publish** (every sample's worst)",
         Dist.of([r[2] - r[8] for r in fresh if r[8] is not None])),
        ("sim sample time → F/T stamp (rig pacing + UDP + driver wake)",
         Dist.of([r[1] - sim_of_stamp[r[1]] for r in wrench if r[1] in sim_of_stamp])),
        ("**sim sample time → grip/command publish**",
         Dist.of([r[2] - sim_of_stamp[r[4]] for r in fresh if r[4] in sim_of_stamp])),
        ("tactile stamp → grip/command publish (age of the tactile frame used)",
         Dist.of([r[2] - r[5] for r in fresh if r[5] is not None])),
        ("grip/command publish → received by this tap", Dist.of([r[3] - r[2] for r in cmd])),
    ]
    stages = [(name, d) for name, d in stages if d.n]  # --light leaves the per-stage rows empty
    report.add("Latency (ms) over the window", _table(["stage", "n", "p50", "p99", "p99.9", "max"], _dist_rows(stages)))

    hops = defaultdict(list)
    for r in fresh:
        ft = r[4]
        if ft in wrench_pub and ft in contact_pub and ft in slip_pub:
            hops["F/T stamp → ft/wrench publish (ft_driver)"].append(wrench_pub[ft] - ft)
            hops["ft/wrench → contact (hop + fusion)"].append(contact_pub[ft] - wrench_pub[ft])
            hops["contact → slip (hop + slip_detector)"].append(slip_pub[ft] - contact_pub[ft])
            hops["slip → grip/command (hop + grip_controller)"].append(r[2] - slip_pub[ft])
    if hops:
        report.add("Per hop, for the commands' own chains (ms)", _table(
            ["hop", "n", "p50", "p99", "p99.9", "max"], _dist_rows([(k, Dist.of(v)) for k, v in hops.items()])))

    e2e = Dist.of([r[2] - r[8] for r in fresh if r[8] is not None])
    report.passed[f"p50 ≤ {TARGET_P50_MS:g} ms"] = e2e.p50 <= TARGET_P50_MS * 1e3
    report.passed[f"p99 ≤ {TARGET_P99_MS:g} ms"] = e2e.p99 <= TARGET_P99_MS * 1e3

    # -- loss ---------------------------------------------------------------------------------
    sample_stamps = np.array(sorted(r[1] for r in wrench if r[1] <= w1 - settle and r[4] >= 1), dtype=np.int64)
    judged_from = np.array(sorted(r[4] for r in fresh if r[4] is not None), dtype=np.int64)
    # a sample is covered by the first command whose newest sample is it or a later one, within 20 ms
    nxt = np.searchsorted(judged_from, sample_stamps, side="left")
    ok = nxt < judged_from.size
    covered = int(np.sum(judged_from[nxt[ok]] - sample_stamps[ok] <= 20_000_000))
    n_samples = int(sample_stamps.size)
    dseqs = np.array([r[4] for r in wrench if r[4] >= 1], dtype=np.int64)
    rdt_gaps = int(np.sum(np.clip(np.diff(dseqs) - 1, 0, None))) if dseqs.size > 1 else 0
    rdt_resets = int(np.sum(np.diff(dseqs) <= 0)) if dseqs.size > 1 else 0
    statuses = Counter(r[5] for r in wrench)
    window = _counter_window(rows["diagnostics"], w0, w1)
    skipped = {node: {k: v for k, v in d.items() if k.endswith(".dropped") and v} for node, (_, d, _) in window.items()}
    lost = {node: {k: v for k, v in d.items() if k.endswith(LOSS_SUFFIXES) and v} for node, (_, d, _) in window.items()}
    rig_not_sent = {k: v for k, v in window.get("rig", (0, {}, {}))[1].items() if k.endswith("not_sent") and v}
    on_path = {"fusion": "in.ft/wrench.dropped", "slip_detector": "in.contact.dropped", "grip_controller": "in.slip.dropped"}
    path_skips = sum(window.get(n, (0, {}, {}))[1].get(k, 0) for n, k in on_path.items())
    fusion = window.get("fusion", (0, {}, {}))[1]
    received, carried = fusion.get("in.ft/wrench.received", 0), fusion.get("fusion.samples", fusion.get("out.contact.published", 0))
    judged = sum(d.get("slip_test.samples_judged", 0) for _, d, _ in window.values())
    span = (w1 - w0) / 1e9
    report.add("Every sample examined (counter window)", _table(["what", "count"], [
        ["F/T samples received by fusion", f"{received:g}"],
        ["… **not examined** (received − carried in contacts: skipped for a newer one or beyond a batch's depth)",
         f"{received - carried:g} ({100 * (received - carried) / received:.2f} %)" if received else "–"],
        ["… judged by the slip test (`slip_test.samples_judged`; the rest had no usable data)", f"{judged:g}"],
        ["grip commands from a new verdict per second (tap window)", f"{len(fresh) / span:.0f}" if span else "–"],
    ]))
    report.passed["every sample examined"] = received > 0 and received == carried
    loss_rows = [
        ["F/T samples received by the tap (stamp ≤ window end − 50 ms)", n_samples],
        ["… of them judged by a command from their batch or a later one within 20 ms", covered],
        ["… **without a command**", n_samples - covered],
        ["RDT device_seq gaps (UDP loss rig → driver) / stream restarts (sim-time rows stop at the first)",
         f"{rdt_gaps} / {rdt_resets}"],
        ["ft/wrench statuses", ", ".join(f"{k}: {v}" for k, v in statuses.most_common())],
    ] if "ft/wrench" in tap.topics else []
    loss_rows += [
        ["not examined on the command path (fusion + slip_detector + grip_controller `.dropped`, counter window)", f"{path_skips:g}"],
        ["commands timed / watchdog repeats (unchanged slip verdict) / from a driver's stale-status republish",
         f"{len(fresh)} / {repeats} / {len(from_status)}"],
        ["command reasons", ", ".join(f"{k}: {v}" for k, v in sorted(reasons.items()))],
        ["sequence gaps seen by the tap, per topic", ", ".join(f"{t}: {tap.gaps.get(t, 0)}" for t in tap.topics)],
        ["rig samples not sent (`rig.*_not_sent`)", ", ".join(f"{k}={v:g}" for k, v in rig_not_sent.items()) or "0"],
        ["**lost** in nodes (`.lost` `.rejected` `.dropped_hwm`)", "; ".join(
            f"{n}: " + ", ".join(f"{k}={v:g}" for k, v in c.items()) for n, c in lost.items() if c) or "0"],
        ["not examined, all nodes (`.dropped`: for a newer one, or beyond a batch's depth)", "; ".join(
            f"{n}: " + ", ".join(f"{k}={v:g}" for k, v in c.items()) for n, c in skipped.items() if c) or "0"],
    ]
    report.add("Loss", _table(["what", "count"], loss_rows))
    report.passed["zero loss"] = (
        not any(lost.values()) and not any(tap.gaps.values()) and rdt_gaps == 0 and not rig_not_sent
    )

    node_rows = []
    for node, (span, delta, last) in sorted(window.items()):
        rate = {k.split(".")[1]: v / span for k, v in delta.items() if k.startswith("out.") and k.endswith(".published") and span > 0}
        node_rows.append([
            node, f"{span:.1f}",
            ", ".join(f"{t} {hz:.0f}" for t, hz in rate.items() if t != "diagnostics") or "–",
            f"{last.get('handler.p50_us', math.nan):.0f}", f"{last.get('handler.p99_us', math.nan):.0f}",
            ", ".join(f"{k}={v:g}" for k, v in delta.items() if k.startswith("timer.") and v) or "0",
        ])
    report.add("Nodes (diagnostics over the counter window; handler percentiles = the node's last 2000 callbacks)",
               _table(["node", "counter window s", "published Hz", "handler p50 µs", "handler p99 µs", "timer ticks skipped"], node_rows))


def cpu_section(sampler: ProcSampler, report: Report) -> None:
    rows = [[s.name, s.pid, f"{100 * s.cpu:.1f}", f"{s.nvcsw_per_s:.0f}", f"{s.vcsw_per_s:.0f}"]
            for s in sorted(sampler.shares, key=lambda s: -s.cpu if not math.isnan(s.cpu) else 0)]
    total = sum(s.cpu for s in sampler.shares if not math.isnan(s.cpu))
    rows.append(["**sum**", "", f"{100 * total:.1f}", "", ""])
    others = max(0.0, sampler.machine_busy - total)
    top = "; ".join(f"{name} {100 * c:.0f}%" for name, c in sampler.others[:4] if c >= 0.01)
    body = _table(["process", "pid", "CPU % of one core", "invol. ctx sw/s", "vol. ctx sw/s"], rows)
    body += (f"\n\nMachine: {sampler.ncpu} CPUs, {100 * sampler.machine_busy:.0f}% of one core busy on average "
             f"({100 * sampler.machine_busy / sampler.ncpu:.0f}% of the machine); load average {sampler.loadavg}; "
             f"everything else {100 * others:.0f}% of a core" + (f" (top: {top})" if top else "") + ".")
    report.add("CPU over the window", body)


def _processes(graph: dict[str, Any]) -> dict[int, list[str]]:
    """pid → names of the nodes it runs (a container's members share one)."""
    out: dict[int, list[str]] = defaultdict(list)
    for name, node in graph["nodes"].items():
        if node.get("pid"):
            out[node["pid"]].append(name)
    return out


def handled_messages(graph: dict[str, Any], names: list[str], deltas: dict[str, dict[str, float]]) -> tuple[float, str]:
    """(messages the process of ``names`` took in over the counter window, what they are):
    frames its nodes handled from the bus (received − dropped − rejected; not ``diagnostics``,
    not topics a member of the same process hands over), or, for a driver (no bus input)
    and the rig, the samples it published (the rig: ``rig/truth``, one per simulated sample)."""
    local = {t for n in names for t in graph["nodes"][n]["outputs"]}
    n_in, topics = 0.0, set()
    for n in names:
        d = deltas.get(n, {})
        for topic in graph["nodes"][n]["inputs"]:
            if topic in local or topic == "diagnostics":
                continue
            n_in += d.get(f"in.{topic}.received", 0) - d.get(f"in.{topic}.dropped", 0) - d.get(f"in.{topic}.rejected", 0)
            topics.add(topic)
    if n_in and not any(graph["nodes"][n]["type"] == "rig" for n in names):  # the rig: per sample it simulates
        return n_in, "in " + ", ".join(sorted(topics))
    out = [t for n in names for t in graph["nodes"][n]["outputs"] if t not in ("diagnostics", "grip/state")]
    return sum(deltas.get(n, {}).get(f"out.{t}.published", 0) for n in names for t in out), "out " + ", ".join(out)


def cpu_per_message_section(graph: dict[str, Any], tap: Tap, w0: int, w1: int, sampler: ProcSampler,
                            raw: tuple[float, float] | None, report: Report) -> None:
    """Per process: cores, messages taken in per second, CPU µs per message, split by stage."""
    window = _counter_window(tap.rows["diagnostics"], w0, w1)
    deltas = {node: d for node, (_, d, _) in window.items()}
    cores = {s.pid: s.cpu for s in sampler.shares}
    rows, product = [], 0.0
    for pid, names in sorted(_processes(graph).items(), key=lambda kv: kv[1]):
        span = max((window[n][0] for n in names if n in window), default=0.0)
        n_msgs, what = handled_messages(graph, names, deltas)
        c = cores.get(pid, math.nan)
        if not names[0].startswith("rig"):
            product += c
        rate = n_msgs / span if span > 0 else math.nan
        per_msg = c * 1e6 / rate if rate else math.nan
        stage_us = [sum(deltas.get(n, {}).get(f"cpu.{st}_us", 0.0) for n in names) / n_msgs if n_msgs else math.nan
                    for st in STAGES]
        traced = any(deltas.get(n, {}).get("cpu.loop_us") for n in names)
        other = per_msg - sum(stage_us) if traced else math.nan
        rows.append([", ".join(names), f"{c:.3f}", f"{rate:.0f} ({what})", f"**{per_msg:.0f}**",
                     *(f"{v:.1f}" if traced else "–" for v in stage_us), f"{other:.1f}" if traced else "–"])
    if raw is not None:
        raw_cores, raw_rate = raw
        rows.append(["raw pyzmq + msgpack SUB (ft/wrench), same run", f"{raw_cores:.3f}", f"{raw_rate:.0f}",
                     f"**{raw_cores * 1e6 / raw_rate:.0f}**" if raw_rate else "–", *("" for _ in STAGES), ""])
    body = _table(["process", "cores", "messages/s taken in", "CPU µs / message", *STAGES,
                   "other threads (ZeroMQ I/O)"], rows)
    body += (f"\n\nDrivers and control path together (every process but the rig): **{product:.3f} cores**. "
             "Stages are main-thread CPU per message (nodes/runtime/stage_cpu.py); a driver's device read "
             "and protocol decode are in its handler; other threads = process CPU − their sum.")
    report.add("CPU per handled message", body)


# -- profiling -------------------------------------------------------------------------------
def start_profilers(pids: dict[str, int], seconds: float, out_dir: Path, rate_hz: int) -> list[tuple[str, Path, subprocess.Popen]]:
    """One ``py-spy record --format raw --nonblocking`` per node process for ``seconds`` (s)."""
    py_spy = Path(sys.executable).parent / "py-spy"
    out_dir.mkdir(parents=True, exist_ok=True)
    procs = []
    for name, pid in pids.items():
        out = out_dir / f"{name}.txt"
        cmd = [str(py_spy), "record", "--format", "raw", "--nonblocking", "--rate", str(rate_hz),
               "--duration", str(max(1, round(seconds))), "--pid", str(pid), "--output", str(out)]
        procs.append((name, out, subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)))
    return procs


def _frame_name(frame: str) -> str:
    """``func (path/to/file.py:12)`` → ``func (file.py)``."""
    func, _, where = frame.partition(" (")
    return f"{func} ({Path(where.rsplit(':', 1)[0]).name})" if where else func


def profile_section(profiles: list[tuple[str, Path, subprocess.Popen]], report: Report, top: int = 8) -> None:
    """Top functions per node: self share and inclusive share of the on-CPU samples."""
    lines = []
    for name, path, proc in profiles:
        try:
            proc.wait(30)
        except subprocess.TimeoutExpired:
            proc.kill()
        if not path.exists():
            lines.append(f"**{name}**: no profile (py-spy failed; is it installed? pip install py-spy)")
            continue
        own, incl, total = Counter(), Counter(), 0
        for line in path.read_text().splitlines():
            stack, _, n = line.rpartition(" ")
            if not stack or not n.isdigit():
                continue
            frames = [_frame_name(f) for f in stack.split(";")]
            total += int(n)
            own[frames[-1]] += int(n)
            for f in set(frames):
                incl[f] += int(n)
        if not total:
            continue
        busy = [(f, c) for f, c in incl.most_common() if c < 0.95 * total][:top]
        lines.append(f"**{name}** ({total} on-CPU samples)\n\n" + _table(
            ["self %", "function", "", "inclusive %", "function "],
            [[f"{100 * a[1] / total:.0f}", a[0], "", f"{100 * b[1] / total:.0f}", b[0]]
             for a, b in zip(own.most_common(top), busy)]))
    report.add("Where the CPU goes (py-spy, on-CPU samples only)", "\n\n".join(lines))


# -- main ------------------------------------------------------------------------------------
def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter,
                                epilog="Prints markdown tables; exits 1 if a target (p50, p99, zero loss) is missed.")
    p.add_argument("--duration", type=float, default=60.0, help="measurement window (s)")
    p.add_argument("--warmup", type=float, default=5.0, help="seconds after the scene starts before measuring")
    p.add_argument("--ft-rate", type=float, default=1000.0, help="F/T sample rate (Hz)")
    p.add_argument("--tactile-rate", type=float, default=500.0, help="tactile frame rate (Hz)")
    p.add_argument("--truth-rate", type=float, default=1000.0, help="rig/truth rate (Hz)")
    p.add_argument("--scene", default="default", help="scene (shipped name or path); repeated to last the run")
    p.add_argument("--keep-monitor", action="store_true", help="keep the monitor node (monitor:=true)")
    p.add_argument("--launch-file", default=None, help="launch file (default: the default graph)")
    p.add_argument("--set", action="append", default=[], metavar="name:=value", help="more launch arguments")
    p.add_argument("--light", action="store_true",
                   help="tap only grip/command and diagnostics (end-to-end row and loss counters only; least load)")
    p.add_argument("--profile", metavar="DIR", type=Path, default=None,
                   help="also run py-spy on every node over the window (raw stacks in DIR) and print top functions "
                        "(needs py-spy in this Python's bin directory: pip install py-spy)")
    p.add_argument("--profile-rate", type=int, default=200, help="py-spy samples per second")
    p.add_argument("--no-stages", action="store_true",
                   help="run the nodes without per-stage CPU accounting (SLIPSTACK_STAGE_CPU; it costs ~1 µs a stage)")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    print_versions()
    report = Report()
    with tempfile.TemporaryDirectory(prefix="ssb-scene-", dir="/tmp") as tmp:
        scene = long_scene(args.scene, args.warmup + args.duration + 30.0, Path(tmp) / "long.toml")
        launch_args = [*([args.launch_file] if args.launch_file else []),
                       f"ft_rate_hz:={args.ft_rate:g}", f"tactile_rate_hz:={args.tactile_rate:g}",
                       f"truth_rate_hz:={args.truth_rate:g}", "record:=false",
                       f"monitor:={'true' if args.keep_monitor else 'false'}", f"scene:={scene}",
                       *([] if any(a.startswith("rdt_port:=") for a in args.set) else [f"rdt_port:={free_udp_port()}"]),
                       *args.set]
        print(f"launching: slipstack launch {' '.join(launch_args)}", file=sys.stderr)
        os.environ[STAGE_CPU_ENV] = "0" if args.no_stages else "1"  # StackRun passes our environment on
        run = StackRun(launch_args)
        tap, profiles, raw_sub, raw = None, [], None, None
        try:
            graph = run.wait_running()
            tap = Tap(graph, LIGHT_TOPICS if args.light else TOPICS)
            # the scene starts once the drivers stream: wait for the first command
            tap.run_until(time.monotonic() + 60.0, stop_when=lambda: bool(tap.rows["grip/command"]) or not run.running())
            if not tap.rows["grip/command"]:
                raise RuntimeError(f"the stack is not commanding the grip:\n{run.log()}")
            tap.run_until(time.monotonic() + args.warmup, stop_when=lambda: not run.running())
            ft_pub = next((n["pub"] for n in graph["nodes"].values() if "ft/wrench" in n["outputs"]), None)
            raw_sub = RawSubscriber(ft_pub, "ft/wrench") if ft_pub else None
            tap.run_until(time.monotonic() + 1.0)  # the raw subscriber connects
            pids = {**run.node_pids, "launcher": run.proc.pid, "bench tap (this process)": os.getpid(),
                    **({"raw pyzmq + msgpack SUB": raw_sub.proc.pid} if raw_sub else {})}
            sampler = ProcSampler(pids)
            profiles = (start_profilers(run.node_pids, args.duration, args.profile, args.profile_rate)
                        if args.profile else [])
            raw0 = raw_sub.mark() if raw_sub else None
            w0 = time.monotonic_ns()
            sampler.start()
            tap.run_until(w0 / 1e9 + args.duration, stop_when=lambda: not run.running())
            sampler.stop()
            w1 = time.monotonic_ns()
            if raw_sub:
                raw1 = raw_sub.mark()
                seconds = (w1 - w0) / 1e9
                raw = ((raw1[1] - raw0[1]) / 1e9 / seconds, (raw1[0] - raw0[0]) / seconds)
            if not run.running():
                raise RuntimeError(f"the launch ended during the measurement:\n{run.log()[-3000:]}")
        finally:
            for _, _, prof in profiles:
                if prof.poll() is None and not run.running():
                    prof.kill()
            if raw_sub is not None:
                raw_sub.close()
            if tap is not None:
                tap.close()
            left = run.stop()
            if left:
                print(f"WARNING: node processes still alive after stop: {left}", file=sys.stderr)
        print(f"stopped the launch (exit code {run.proc.returncode}); no node process left: {not left}", file=sys.stderr)

    head = (f"## slipstack end-to-end latency: F/T {args.ft_rate:g} Hz, tactile {args.tactile_rate:g} Hz, "
            f"truth {args.truth_rate:g} Hz, {(w1 - w0) / 1e9:.1f} s window after {args.warmup:g} s warm-up\n\n"
            f"`slipstack launch {' '.join(a if not a.startswith('scene:=') else 'scene:=<' + args.scene + ' repeated>' for a in launch_args)}`\n")
    report.sections.append(head)
    analyse(tap, w0, w1, args, report)
    cpu_section(sampler, report)
    cpu_per_message_section(graph, tap, w0, w1, sampler, raw, report)
    if profiles:
        profile_section(profiles, report)
    verdict = ", ".join(f"{k}: {'PASS' if ok else 'FAIL'}" for k, ok in report.passed.items())
    report.sections.append(f"**Targets (F/T stamp → grip/command publish):** {verdict}\n")
    print(report.text())
    return 0 if all(report.passed.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
