#!/usr/bin/env python3
"""Two fingers against one, in real time, in the same run: every F/T sample examined, sample → squeeze command, CPU.

More in docs/modules.md, `tests/bench/bench_gripper_latency.py`.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import msgpack
import numpy as np
import zmq

from _stack import ProcSampler, StackRun, free_udp_port, long_scene
from bench_stack_latency import Dist, _counter_window, _ms

ONE = {"label": "one finger", "launch": [], "scene": "default", "ft": ("ft/wrench",)}
TWO = {"label": "two fingers", "launch": ["gripper"], "scene": "grasp_pickup",
       "ft": ("finger0/ft/wrench", "finger1/ft/wrench")}


def _no_ext(code: int, data: bytes) -> None:
    return None


class Tap:
    """SUB to every publisher of the wanted topics; keeps (topic, stamp, pub, recv, sources) rows."""

    def __init__(self, graph: dict, topics: tuple[str, ...]) -> None:
        self.ctx = zmq.Context()
        self.poller = zmq.Poller()
        self.socks = []
        self.rows: dict[str, list] = defaultdict(list)
        for node in graph["nodes"].values():
            wanted = [t for t in node["outputs"] if t in topics]
            if not node.get("pub") or not wanted:
                continue
            s = self.ctx.socket(zmq.SUB)
            s.setsockopt(zmq.LINGER, 0)
            s.setsockopt(zmq.RCVHWM, 200_000)
            for t in wanted:
                s.setsockopt(zmq.SUBSCRIBE, t.encode())
            s.connect(node["pub"])
            self.poller.register(s, zmq.POLLIN)
            self.socks.append(s)

    def run_until(self, t_end_s: float) -> None:
        while time.monotonic() < t_end_s:
            for sock, _ in self.poller.poll(50):
                for _ in range(1000):  # then look at the clock: a tap behind the stream still ends on time
                    try:
                        topic_b, payload = sock.recv_multipart(zmq.NOBLOCK)
                    except zmq.Again:
                        break
                    recv = time.monotonic_ns()
                    _, _, (stamp, seq, pub, src), body = msgpack.unpackb(payload, ext_hook=_no_ext, raw=False,
                                                                          strict_map_key=False)
                    topic = topic_b.decode()
                    if topic == "diagnostics":
                        self.rows[topic].append((recv, body[0], body[2]))
                    else:
                        self.rows[topic].append((stamp, pub, recv, src, body[3] if topic.endswith("ft/wrench") else 0))

    def close(self) -> None:
        for s in self.socks:
            s.close(linger=0)
        self.ctx.term()


def measure(stack: dict, args: argparse.Namespace, tmp: Path) -> dict:
    # the scene runs from the rig's start: it must outlast the graph's start (up to the 90 s allowed for the
    # first command below on a busy machine), the warm-up and the measurement
    scene = long_scene(stack["scene"], args.warmup + args.duration + 120.0, tmp / f"{stack['scene']}-long.toml")
    launch = [*stack["launch"], f"ft_rate_hz:={args.ft_rate:g}", f"tactile_rate_hz:={args.tactile_rate:g}",
              "truth_rate_hz:=250", "record:=false", "monitor:=false", "check:=false", f"scene:={scene}",
              f"rdt_port:={free_udp_port()}"]
    if stack is TWO:
        launch.append(f"rdt_port_1:={free_udp_port()}")
    run = StackRun(launch)
    tap = None
    try:
        graph = run.wait_running()
        tap = Tap(graph, (*stack["ft"], "grip/command", "diagnostics"))
        deadline = time.monotonic() + 90.0
        while not tap.rows["grip/command"] and time.monotonic() < deadline and run.running():
            tap.run_until(time.monotonic() + 0.5)
        if not tap.rows["grip/command"]:
            raise RuntimeError(f"{stack['label']}: no grip command:\n{run.log()[-3000:]}")
        tap.run_until(time.monotonic() + args.warmup)
        sampler = ProcSampler({**run.node_pids})
        w0 = time.monotonic_ns()
        sampler.start()
        tap.run_until(w0 / 1e9 + args.duration)
        sampler.stop()
        w1 = time.monotonic_ns()
        if not run.running():
            raise RuntimeError(f"{stack['label']}: the launch ended during the measurement:\n{run.log()[-3000:]}")
        tap.run_until(time.monotonic() + 2.0)  # the commands of the window's last samples (a busy tap lags)
    finally:
        if tap is not None:
            tap.close()
        run.stop()
    return analyse(stack, graph, tap, sampler, w0, w1)


def analyse(stack: dict, graph: dict, tap: Tap, sampler: ProcSampler, w0: int, w1: int) -> dict:
    commands = sorted((r for r in tap.rows["grip/command"]), key=lambda r: r[1])
    latencies = []
    for k, topic in enumerate(stack["ft"]):
        key = "ft" if len(stack["ft"]) == 1 else f"ft{k}"
        judged = np.array([r[3].get(key, -1) for r in commands], dtype=np.int64)
        pubs = np.array([r[1] for r in commands], dtype=np.int64)
        best = np.maximum.accumulate(judged)  # the newest sample of this sensor any command so far derived from
        samples = np.array([r[0] for r in tap.rows[topic] if w0 <= r[2] <= w1 - 50_000_000 and r[4] >= 1], dtype=np.int64)
        # a busy tap lags behind the stream (commands on another socket than the samples): samples newer than
        # the newest this sensor's commands the tap got derive from are left out, not counted lost (n shows it)
        samples = samples[samples <= best[-1]] if len(best) else samples
        first = np.searchsorted(best, samples, side="left")  # the first command that judged it or a later sample
        ok = first < len(pubs)
        latencies.append(pubs[first[ok]] - samples[ok])
        latencies.append(np.full(int((~ok).sum()), np.iinfo(np.int64).max // 2))  # never judged: counted as lost
    window = _counter_window(tap.rows["diagnostics"], w0, w1)
    received = carried = 0.0
    for node, (_, delta, _) in window.items():
        if graph["nodes"].get(node, {}).get("type") == "fusion":
            received += sum(v for k, v in delta.items() if k.startswith("in.") and k.endswith("ft/wrench.received"))
            carried += delta.get("fusion.samples", 0.0)
    shares = {s.name: s.cpu for s in sampler.shares if not math.isnan(s.cpu)}
    control = sum(c for name, c in shares.items() if not name.startswith("rig"))
    lat = Dist.of(np.concatenate(latencies)) if latencies else Dist.of([])
    return {"label": stack["label"], "lat": lat, "received": received, "not_examined": received - carried,
            "control_cores": control, "cores": shares, "load": sampler.loadavg}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--duration", type=float, default=20.0, help="measurement window per launch (s)")
    p.add_argument("--warmup", type=float, default=5.0, help="seconds after the first command before measuring")
    p.add_argument("--rounds", type=int, default=2, help="launches of each stack, alternated")
    p.add_argument("--ft-rate", type=float, default=1000.0, help="every F/T sensor's rate (Hz)")
    p.add_argument("--tactile-rate", type=float, default=500.0, help="every pad's rate (Hz)")
    args = p.parse_args()
    os.environ["SLIPSTACK_STAGE_CPU"] = "0"
    results = []
    with tempfile.TemporaryDirectory(prefix="ssb-grip-", dir="/tmp") as tmp:
        for _ in range(args.rounds):
            for stack in (ONE, TWO):
                r = measure(stack, args, Path(tmp))
                results.append(r)
                print(f"{r['label']}: p50 {_ms(r['lat'].p50)} ms, p99 {_ms(r['lat'].p99)} ms (n {r['lat'].n}); "
                      f"F/T samples received {r['received']:g}, not examined {r['not_examined']:g}; drivers + "
                      f"control {r['control_cores']:.2f} cores; load {r['load']}", flush=True)
    print("\n| round | stack | samples | not examined | p50 ms | p99 ms | p99 two/one | drivers + control, cores |")
    print("|---|---|---|---|---|---|---|---|")
    for i in range(0, len(results), 2):
        one, two = results[i], results[i + 1]
        for r in (one, two):
            ratio = f"{two['lat'].p99 / one['lat'].p99:.2f}" if r is two and one["lat"].p99 > 0 else ""
            print(f"| {i // 2 + 1} | {r['label']} | {r['received']:g} | {r['not_examined']:g} | {_ms(r['lat'].p50)} | "
                  f"{_ms(r['lat'].p99)} | {ratio} | {r['control_cores']:.2f} |")
    for r in results:
        print(f"\n{r['label']}: cores per process: " + ", ".join(f"{n} {c:.2f}" for n, c in sorted(r["cores"].items())))
    return 0


if __name__ == "__main__":
    sys.exit(main())
