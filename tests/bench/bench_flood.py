"""The control path under an injection flood: F/T stamp → ``grip/command`` latency
before, during and after floods, measured side by side in one run of the real stack.

Launches the default graph (as ``bench_stack_latency.py`` does, no recorder, no
monitor), taps ``grip/command`` and ``diagnostics`` and runs these phases of
``--phase`` seconds each, in order:

More in docs/modules.md, `tests/bench/bench_flood.py`.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _versions import print_versions
from _stack import ProcSampler, StackRun, free_udp_port, long_scene
from bench_stack_latency import LIGHT_TOPICS, Dist, Tap, _counter_window, _ms, _table, split_watchdog_repeats

PHASES = {"rate": ("baseline", "rate flood", "recovery", "big-frame flood"),
          "heavy": ("baseline", "heavy flood", "after heavy", "contact flood", "after contact"),
          "tactile": ("baseline", "tactile flood", "after tactile", "after tactile 2", "after tactile 3", "after tactile 4")}
FLOOD_KIND = {"rate flood": "rate", "big-frame flood": "big", "heavy flood": "heavy", "contact flood": "contact",
              "tactile flood": "tactile"}
FLOOD_TOPIC = "ft/wrench"
HEAVY_PAD = 256  # taxels a side of the injected contacts: the largest legal pad (messages/types.py)
INJECTED_STAMP = 1  # ns: the sample stamp of every injected stale wrench (so its commands can be told apart)


# -- the flooding process --------------------------------------------------------------------
def _heavy_contact(stamp_ns: int, seq: int) -> bytes:
    """A legal contact of a 256×256 pad, pressed in its middle, stamped ``stamp_ns``."""
    from slipstack.messages import Contact, Header, encode

    n = HEAVY_PAD * HEAVY_PAD
    phi = np.zeros(n)
    rows, cols = np.divmod(np.arange(n), HEAVY_PAD)
    phi[(abs(rows - 128) < 40) & (abs(cols - 128) < 40)] = 10.0 / 6400
    return encode(Contact(rows=HEAVY_PAD, cols=HEAVY_PAD, pitch_m=1.25e-3, phi=phi, f_n=10.0,
                          f_t=np.array([0.5, 0.0]), tau=0.0, cop=np.zeros(2), area_m2=1e-4, mask=phi > 0,
                          has_tactile=True), Header(stamp_ns, seq, stamp_ns, {"ft": stamp_ns, "tactile": stamp_ns}))


def flood(graph_path: Path, kind: str, rate_hz: float, big_mb: float, payload: str, seconds: float,
          sources: int = 8000) -> None:
    """Inject into every ``ft/wrench`` (``contact`` for the contact flood) subscriber for
    ``seconds``; prints frames/s sent as JSON."""
    import zmq

    from slipstack.messages import Header, Wrench, encode
    from slipstack.nodes.tools.topic_pub import Injector
    from slipstack.nodes.tools.topic_tools import resolve_topic

    topic_name = {"contact": "contact", "tactile": "tactile/frame"}.get(kind, FLOOD_TOPIC)
    injector = Injector(resolve_topic(json.loads(graph_path.read_text()), topic_name), linger_s=0.0)
    injector.wait_for_subscribers(5.0)
    print("flooding", flush=True)  # the phase starts now, not when this process was started
    (sock,) = injector.sender.socks  # the nodes on this machine share one socket
    origin = injector.sender.origin
    rng = np.random.default_rng(1)
    stale = [encode(Wrench(force=np.array([0.0, 0.0, -1.0]), frame="pad"), Header(INJECTED_STAMP, k, INJECTED_STAMP, {}))
             for k in range(1000)]
    garbage = [rng.bytes(120) for _ in range(1000)]
    frames = stale if payload == "stale" else garbage
    if kind == "heavy":  # ~70 KB each: a header naming `sources` source stamps, legal and costly to decode
        many = {f"s{k}": INJECTED_STAMP for k in range(sources)}
        frames = [encode(Wrench(force=np.array([0.0, 0.0, -1.0]), frame="pad"), Header(INJECTED_STAMP, k,
                                                                                       INJECTED_STAMP, many))
                  for k in range(50)]
    big = b"\x00" * round(big_mb * 1e6)
    topic = topic_name.encode()
    sent = 0
    t0 = time.monotonic()
    end = t0 + seconds
    if kind == "contact":  # stamped now: judged in full, not refused as stale
        period = 1.0 / rate_hz
        due = t0
        while time.monotonic() < end:
            time.sleep(max(0.0, due - time.monotonic()))
            try:
                sock.send_multipart((topic, _heavy_contact(time.monotonic_ns(), sent), origin), zmq.NOBLOCK)
                sent += 1
            except zmq.Again:
                pass
            due = max(due + period, time.monotonic() - period)  # a slot missed on a busy machine is skipped
    elif kind == "tactile":  # an empty pad, stamped now, at `rate_hz`
        from slipstack.messages import TactileFrame

        empty = TactileFrame(pressure_pa=np.zeros(256, dtype="<f4"), saturated=np.zeros(256, bool),
                             dead=np.zeros(256, bool))
        period = 1.0 / rate_hz
        due = t0
        while time.monotonic() < end:
            time.sleep(max(0.0, due - time.monotonic()))
            now_ns = time.monotonic_ns()
            try:
                sock.send_multipart((topic, encode(empty, Header(now_ns, sent, now_ns, {})), origin), zmq.NOBLOCK)
            except zmq.Again:
                pass
            sent += 1
            due = max(due + period, time.monotonic() - period)
    elif kind in ("rate", "heavy"):
        per_ms = rate_hz / 1000.0
        due = t0
        while due < end:
            now = time.monotonic()
            if now < due:
                time.sleep(due - now)
            target = int((time.monotonic() - t0) * 1000 * per_ms)
            while sent < target:
                try:
                    sock.send_multipart((topic, frames[sent % len(frames)], origin), zmq.NOBLOCK)
                except zmq.Again:  # the node's queue is full: ZeroMQ takes no more now
                    pass
                sent += 1
            due += 0.001
    else:
        while time.monotonic() < end:
            try:
                sock.send_multipart((topic, big, origin), zmq.NOBLOCK)
                sent += 1
            except zmq.Again:
                time.sleep(0.0005)
    print(json.dumps({"kind": kind, "sent": sent, "seconds": time.monotonic() - t0}), flush=True)
    injector.close()


# -- the benchmark ---------------------------------------------------------------------------
def _load() -> str:
    return " ".join(Path("/proc/loadavg").read_text().split()[:3])


def _cpu(sampler: ProcSampler, part: str) -> str:
    """CPU (% of one core) of the sampled processes whose name contains ``part``."""
    shares = [s.cpu for s in sampler.shares if part in s.name]
    return f"{100 * sum(shares):.0f}" if shares else "–"


def _phase_row(name: str, tap: Tap, w0: int, w1: int, baseline_p99: float | None,
               sampler: ProcSampler) -> tuple[list, Dist]:
    cmd = sorted((r for r in tap.rows["grip/command"] if w0 <= r[3] <= w1), key=lambda r: r[0])
    fresh, repeats = split_watchdog_repeats(cmd)
    injected_cmds = [r for r in fresh if r[4] == INJECTED_STAMP]
    fresh = [r for r in fresh if r[4] != INJECTED_STAMP]
    dist = Dist.of([r[2] - r[4] for r in fresh])
    pubs = sorted(r[2] for r in fresh)
    largest_gap_ms = max((b - a for a, b in zip(pubs, pubs[1:])), default=w1 - w0) / 1e6
    fail_safe = sum(r[7] == "fail-safe" for r in cmd) / max(len(cmd), 1)
    counters = _counter_window(tap.rows["diagnostics"], w0, w1)
    injected = {k: sum(delta.get(k, 0) for _, delta, _ in counters.values())
                for k in ("inject.dropped_rate", "inject.dropped_bytes", "inject.work_pauses",
                          f"in.{FLOOD_TOPIC}.rejected")}
    ratio = dist.p99 / baseline_p99 if baseline_p99 else 1.0
    row = [name, dist.n, f"{dist.n / ((w1 - w0) / 1e9):.0f}", f"{largest_gap_ms:.0f}", _ms(dist.p50), _ms(dist.p99),
           f"{ratio:.2f}",
           f"{100 * fail_safe:.1f} %", repeats, len(injected_cmds),
           f"{(max(r[3] for r in injected_cmds) - w0) / 1e6:.0f}" if injected_cmds else "–",
           f"{injected['inject.dropped_rate']:.0f}/{injected['inject.dropped_bytes']:.0f}/"
           f"{injected['inject.work_pauses']:.0f}",
           f"{injected[f'in.{FLOOD_TOPIC}.rejected']:.0f}", _cpu(sampler, "control"), _cpu(sampler, "flooder"),
           f"{sampler.machine_busy:.2f}"]
    return row, dist


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__.split("\n\n", 1)[1])
    p.add_argument("--phase", type=float, default=10.0, help="seconds per phase (default 10)")
    p.add_argument("--warmup", type=float, default=5.0, help="seconds after the first command before measuring")
    p.add_argument("--floods", choices=tuple(PHASES), default="rate",
                   help="rate: garbage or stale frames and big frames (default); heavy: heavy legal frames")
    p.add_argument("--rate", type=float, help="injected frames per second (default 20000; heavy: 1000)")
    p.add_argument("--sources", type=int, default=8000, help="header sources of a heavy wrench (default 8000)")
    p.add_argument("--contact-rate", type=float, default=50.0, help="contacts per second of the contact flood")
    p.add_argument("--payload", choices=("garbage", "stale"), default="garbage",
                   help="rate flood: random bytes or valid stale-stamped wrenches (default garbage)")
    p.add_argument("--big-mb", type=float, default=10.0, help="size of a big frame, MB (default 10)")
    p.add_argument("--ft-rate", type=float, default=1000.0, help="F/T sample rate (Hz)")
    p.add_argument("--tactile-rate", type=float, default=500.0, help="tactile frame rate (Hz)")
    p.add_argument("--worker", choices=tuple(FLOOD_KIND.values()), help=argparse.SUPPRESS)
    p.add_argument("--graph", type=Path, help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.rate is None:
        args.rate = {"heavy": 1000.0, "tactile": 5000.0}.get(args.floods, 20_000.0)
    return args


def _start_flood(args: argparse.Namespace, graph_path: Path, kind: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, __file__, "--worker", kind, "--graph", str(graph_path),
         "--rate", str(args.contact_rate if kind == "contact" else args.rate), "--sources", str(args.sources),
         "--big-mb", str(args.big_mb), "--payload", args.payload, "--phase", str(args.phase)],
        stdout=subprocess.PIPE, text=True,
    )


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    print_versions()
    if args.worker:
        flood(args.graph, args.worker, args.rate, args.big_mb, args.payload, args.phase, args.sources)
        return 0
    phases = PHASES[args.floods]
    load_before = _load()
    windows: dict[str, tuple[int, int]] = {}
    samplers: dict[str, ProcSampler] = {}
    floods: dict[str, str] = {}
    with tempfile.TemporaryDirectory(prefix="ssb-flood-", dir="/tmp") as tmp:
        total = args.warmup + len(phases) * args.phase + 120.0  # the scene outlasts a slow start
        scene = long_scene("default", total, Path(tmp) / "long.toml")
        launch_args = [f"ft_rate_hz:={args.ft_rate:g}", f"tactile_rate_hz:={args.tactile_rate:g}", "record:=false",
                       "monitor:=false", f"scene:={scene}", f"rdt_port:={free_udp_port()}"]
        print(f"launching: slipstack launch {' '.join(launch_args)}", file=sys.stderr)
        with StackRun(launch_args) as run:
            run.wait_running()
            graph_path = run.run_root / "current" / "graph.json"
            tap = Tap(json.loads(graph_path.read_text()), LIGHT_TOPICS)
            try:
                tap.run_until(time.monotonic() + 60.0, stop_when=lambda: bool(tap.rows["grip/command"]))
                if not tap.rows["grip/command"]:
                    raise RuntimeError(f"the stack is not commanding the grip:\n{run.log()}")
                tap.run_until(time.monotonic() + args.warmup)
                for phase in phases:
                    worker = None
                    if phase in FLOOD_KIND:
                        worker = _start_flood(args, graph_path, FLOOD_KIND[phase])
                        worker.stdout.readline()  # it is flooding from now on
                    sampler = ProcSampler({**run.node_pids, **({"flooder": worker.pid} if worker else {})})
                    sampler.start()
                    w0 = time.monotonic_ns()
                    tap.run_until(w0 / 1e9 + args.phase, stop_when=lambda: not run.running())
                    windows[phase] = (w0, time.monotonic_ns())
                    sampler.stop()
                    samplers[phase] = sampler
                    if worker is not None:
                        out, _ = worker.communicate(timeout=60)
                        floods[phase] = out.strip()
                    if not run.running():
                        raise RuntimeError(f"the launch ended during {phase}:\n{run.log()[-3000:]}")
            finally:
                tap.close()
    load_after = _load()

    rows, baseline_p99 = [], None
    for phase in phases:
        row, dist = _phase_row(phase, tap, *windows[phase], baseline_p99, samplers[phase])
        baseline_p99 = baseline_p99 or dist.p99
        rows.append(row)
    print(f"## control path under injection floods: F/T {args.ft_rate:g} Hz, tactile {args.tactile_rate:g} Hz, "
          f"{args.phase:g} s per phase\n")
    print(_table(["phase", "commands", "Hz", "largest gap ms", "p50 ms", "p99 ms", "p99 / baseline", "fail-safe",
                  "watchdog repeats", "from injected samples", "last of them, ms into the phase",
                  "inject dropped rate/bytes, work pauses", f"in.{FLOOD_TOPIC}.rejected", "control CPU %", "flooder CPU %",
                  "machine busy (cores)"], rows))
    for phase, line in floods.items():
        sent = json.loads(line)
        what = {"rate": args.payload, "big": f"{args.big_mb:g} MB each", "heavy": f"{args.sources} header sources each",
                "contact": f"{HEAVY_PAD}x{HEAVY_PAD} pad each", "tactile": "an empty pad each"}[sent["kind"]]
        print(f"\n{phase}: {sent['sent']} frames sent in {sent['seconds']:.1f} s "
              f"({sent['sent'] / sent['seconds']:.0f}/s, {what})")
    print(f"\nload average (1, 5, 15 min) before: {load_before}; after: {load_after}; {os.cpu_count()} cores")
    return 0


if __name__ == "__main__":
    sys.exit(main())
