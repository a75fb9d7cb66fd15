"""The control path under an injection flood: F/T stamp → ``grip/command`` latency
before, during and after floods, measured side by side in one run of the real stack.

Launches the default graph (as ``bench_stack_latency.py`` does, no recorder, no
monitor), taps ``grip/command`` and ``diagnostics`` and runs these phases of
``--phase`` seconds each, in order:

1. ``baseline``: no flood;
2. ``rate flood``: a separate process injects ``--rate`` frames/s (default 20 kHz) of
   garbage (``--payload garbage``: random bytes, rejected on decode) or of valid
   stale-stamped wrenches (``--payload stale``) into every ``ft/wrench`` subscriber's
   injection endpoint — what ``topic pub`` and ``bag play`` reach;
3. ``recovery``: no flood;
4. ``big-frame flood``: the same process sends ``--big-mb`` MB frames (default 10) as
   fast as ZeroMQ takes them.

For each phase: commands derived from a new F/T sample (watchdog repeats and
commands derived from injected samples left out; the latter counted, with the
time of the last one), their rate, the latency ``pub_ns − sources['ft']`` p50 /
p99 (ms), the p99 over the
baseline's (ratio), the fail-safe share, the injection counters of the
``ft/wrench`` subscribers (``inject.dropped_rate``, ``in.ft/wrench.rejected``), and
the CPU of the control container, of the flooding process and of the machine. The
machine's load average before and after is printed (read the ratio against it).

    python tests/bench/bench_flood.py                 # 4 phases of 10 s
    python tests/bench/bench_flood.py --phase 5 --payload stale
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

PHASES = ("baseline", "rate flood", "recovery", "big-frame flood")
FLOOD_TOPIC = "ft/wrench"
INJECTED_STAMP = 1  # ns: the sample stamp of every injected stale wrench (so its commands can be told apart)


# -- the flooding process --------------------------------------------------------------------
def flood(graph_path: Path, kind: str, rate_hz: float, big_mb: float, payload: str, seconds: float) -> None:
    """Inject into every ``ft/wrench`` subscriber for ``seconds``; prints frames/s sent as JSON."""
    import zmq

    from slipstack.messages import Header, Wrench, encode
    from slipstack.nodes.tools.topic_pub import Injector
    from slipstack.nodes.tools.topic_tools import resolve_topic

    injector = Injector(resolve_topic(json.loads(graph_path.read_text()), FLOOD_TOPIC), linger_s=0.0)
    injector.wait_for_subscribers(5.0)
    (sock,) = injector.sender.socks  # the nodes on this machine share one socket
    origin = injector.sender.origin
    rng = np.random.default_rng(1)
    stale = [encode(Wrench(force=np.array([0.0, 0.0, -1.0]), frame="pad"), Header(INJECTED_STAMP, k, INJECTED_STAMP, {}))
             for k in range(1000)]
    garbage = [rng.bytes(120) for _ in range(1000)]
    frames = stale if payload == "stale" else garbage
    big = b"\x00" * round(big_mb * 1e6)
    topic = FLOOD_TOPIC.encode()
    sent = 0
    t0 = time.monotonic()
    end = t0 + seconds
    if kind == "rate":
        per_ms = rate_hz / 1000.0
        due = t0
        while due < end:
            now = time.monotonic()
            if now < due:
                time.sleep(due - now)
            target = int((time.monotonic() - t0) * 1000 * per_ms)
            while sent < target:
                sock.send_multipart((topic, frames[sent % len(frames)], origin), zmq.NOBLOCK)
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
    fail_safe = sum(r[7] == "fail-safe" for r in cmd) / max(len(cmd), 1)
    counters = _counter_window(tap.rows["diagnostics"], w0, w1)
    injected = {k: sum(delta.get(k, 0) for _, delta, _ in counters.values())
                for k in ("inject.dropped_rate", f"in.{FLOOD_TOPIC}.rejected")}
    ratio = dist.p99 / baseline_p99 if baseline_p99 else 1.0
    row = [name, dist.n, f"{dist.n / ((w1 - w0) / 1e9):.0f}", _ms(dist.p50), _ms(dist.p99), f"{ratio:.2f}",
           f"{100 * fail_safe:.1f} %", repeats, len(injected_cmds),
           f"{(max(r[3] for r in injected_cmds) - w0) / 1e6:.0f}" if injected_cmds else "–",
           f"{injected['inject.dropped_rate']:.0f}",
           f"{injected[f'in.{FLOOD_TOPIC}.rejected']:.0f}", _cpu(sampler, "control"), _cpu(sampler, "flooder"),
           f"{sampler.machine_busy:.2f}"]
    return row, dist


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__.split("\n\n", 1)[1])
    p.add_argument("--phase", type=float, default=10.0, help="seconds per phase (default 10)")
    p.add_argument("--warmup", type=float, default=5.0, help="seconds after the first command before measuring")
    p.add_argument("--rate", type=float, default=20_000.0, help="injected frames per second (default 20000)")
    p.add_argument("--payload", choices=("garbage", "stale"), default="garbage",
                   help="rate flood: random bytes or valid stale-stamped wrenches (default garbage)")
    p.add_argument("--big-mb", type=float, default=10.0, help="size of a big frame, MB (default 10)")
    p.add_argument("--ft-rate", type=float, default=1000.0, help="F/T sample rate (Hz)")
    p.add_argument("--tactile-rate", type=float, default=500.0, help="tactile frame rate (Hz)")
    p.add_argument("--worker", choices=("rate", "big"), help=argparse.SUPPRESS)
    p.add_argument("--graph", type=Path, help=argparse.SUPPRESS)
    return p.parse_args(argv)


def _start_flood(args: argparse.Namespace, graph_path: Path, kind: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, __file__, "--worker", kind, "--graph", str(graph_path), "--rate", str(args.rate),
         "--big-mb", str(args.big_mb), "--payload", args.payload, "--phase", str(args.phase)],
        stdout=subprocess.PIPE, text=True,
    )


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    print_versions()
    if args.worker:
        flood(args.graph, args.worker, args.rate, args.big_mb, args.payload, args.phase)
        return 0
    load_before = _load()
    windows: dict[str, tuple[int, int]] = {}
    samplers: dict[str, ProcSampler] = {}
    floods: dict[str, str] = {}
    with tempfile.TemporaryDirectory(prefix="ssb-flood-", dir="/tmp") as tmp:
        total = args.warmup + 4 * args.phase + 30.0
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
                for phase in PHASES:
                    worker = None
                    if phase.endswith("flood"):
                        worker = _start_flood(args, graph_path, "rate" if phase == "rate flood" else "big")
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
    for phase in PHASES:
        row, dist = _phase_row(phase, tap, *windows[phase], baseline_p99, samplers[phase])
        baseline_p99 = baseline_p99 or dist.p99
        rows.append(row)
    print(f"## control path under injection floods: F/T {args.ft_rate:g} Hz, tactile {args.tactile_rate:g} Hz, "
          f"{args.phase:g} s per phase\n")
    print(_table(["phase", "commands", "Hz", "p50 ms", "p99 ms", "p99 / baseline", "fail-safe", "watchdog repeats",
                  "from injected samples", "last of them, ms into the phase",
                  "inject.dropped_rate", f"in.{FLOOD_TOPIC}.rejected", "control CPU %", "flooder CPU %",
                  "machine busy (cores)"], rows))
    for phase, line in floods.items():
        sent = json.loads(line)
        print(f"\n{phase}: {sent['sent']} frames sent in {sent['seconds']:.1f} s "
              f"({sent['sent'] / sent['seconds']:.0f}/s, {args.payload if sent['kind'] == 'rate' else f'{args.big_mb:g} MB each'})")
    print(f"\nload average (1, 5, 15 min) before: {load_before}; after: {load_after}; {os.cpu_count()} cores")
    return 0


if __name__ == "__main__":
    sys.exit(main())
