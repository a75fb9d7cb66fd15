"""The control path split over two machines against the same path on one, and CURVE against plain tcp.

Runs Fig. 15's closed loop (a copy of the scene that lasts the run) three ways, one
after the other in one invocation, on this computer:

More in docs/modules.md, `tests/bench/bench_two_hosts.py`.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import msgpack
import numpy as np

from _versions import print_versions
from _stack import StackRun, free_udp_port, long_scene

from slipstack.launch.launch_file import launch_files_dir
from slipstack.nodes.runtime import curve
from slipstack.nodes.runtime.graph_info import read_graph
from slipstack.nodes.runtime.transport import make_pub, make_sub


def _tap(graph_dir: Path, seconds: float) -> tuple[list[float], int, int]:
    """Latencies (ms) of fresh grip commands over ``seconds``, watchdog repeats, fail-safe commands."""
    import zmq

    graph = read_graph(graph_dir)  # the graph's keys, with machines this machine's
    ends = [n["pub"] for n in graph["nodes"].values() if "grip/command" in n["outputs"]]
    ctx = zmq.Context()
    sock = make_sub(ctx, ends, "grip/command", rcvhwm=100_000)
    latencies: list[float] = []
    repeats = fail_safe = 0
    prev_slip = None
    end = time.monotonic() + seconds
    try:
        while time.monotonic() < end:
            if not sock.poll(100):
                continue
            _, payload = sock.recv_multipart()
            _, _, (_, _, pub, src), body = msgpack.unpackb(payload, raw=False, strict_map_key=False,
                                                          ext_hook=lambda code, data: None)
            fail_safe += "fail-safe" in body
            if src.get("slip") is not None and src.get("slip") == prev_slip:
                repeats += 1
            elif src.get("ft") is not None:
                latencies.append((pub - src["ft"]) / 1e6)
            prev_slip = src.get("slip")
    finally:
        sock.close(linger=0)
        ctx.term()
        curve.use_keys(None)
    return latencies, repeats, fail_safe


def _one_hop(name: str, endpoint: str, keys: Path | None, frames: int) -> dict:
    """Latency (ms) of ``frames`` frames, one at a time, from an XPUB bound at ``endpoint`` to a SUB."""
    import zmq

    curve.use_keys(keys, "robot", {"127.0.0.1": "robot"}, insecure=keys is None)
    ctx = zmq.Context.instance()  # kept: a CURVE server's authenticator thread lives on it
    pub = make_pub(ctx, endpoint)
    sub = make_sub(ctx, [endpoint], "t")
    try:
        while not pub.poll(100):  # the subscription has arrived
            pass
        pub.recv()
        payload = bytes(100)
        lat = []
        load0 = os.getloadavg()[0]
        for _ in range(frames):
            sent = time.monotonic_ns()
            pub.send_multipart([b"t", sent.to_bytes(8, "big") + payload])
            if sub.poll(100):
                _, body = sub.recv_multipart()
                lat.append((time.monotonic_ns() - int.from_bytes(body[:8], "big")) / 1e6)
            time.sleep(0.001)
    finally:
        pub.close(linger=0)
        sub.close(linger=0)
        curve.use_keys(None)
    return _row(name, lat, 0, frames - len(lat), (load0, os.getloadavg()[0]), flag="lost")


def _row(name: str, lat: list[float], repeats: int, flagged: int, load: tuple[float, float], note: str = "",
         flag: str = "fail-safe") -> dict:
    """One printed and returned result: latencies (ms) timed, watchdog repeats, ``flagged``
    frames (fail-safe commands, or lost hops), the load average before and after."""
    a = np.asarray(lat)
    row = {"config": name, "timed": len(a), "p50_ms": float(np.percentile(a, 50)) if len(a) else float("nan"),
           "p99_ms": float(np.percentile(a, 99)) if len(a) else float("nan"), "watchdog_repeats": repeats,
           flag: flagged, "load_before": load[0], "load_after": load[1], "note": note}
    print(f"{name:24s} {len(a):6d} timed  p50 {row['p50_ms']:.3f} ms  p99 {row['p99_ms']:.3f} ms  "
          f"{flag} {flagged}  load {load[0]:.2f}->{load[1]:.2f}  {note}", flush=True)
    return row


def _one_host(common: list[str], args: argparse.Namespace) -> dict:
    load0 = os.getloadavg()[0]
    with StackRun(["fig15", *common]) as run:
        run.wait_running()
        time.sleep(args.warmup)
        lat, rep, fs = _tap(run.run_root / "current", args.duration)
    return _row("one host", lat, rep, fs, (load0, os.getloadavg()[0]))


def _two_hosts(name: str, file: str, common: list[str], args: argparse.Namespace) -> dict:
    first = random.randrange(20000, 32000, 100)  # below the ephemeral ports (32768-60999)
    both = [file, *common, f"first_port:={first}", f"last_port:={first + 99}"]
    load0 = os.getloadavg()[0]
    with StackRun([*both, "--machine", "robot"]) as robot, StackRun([*both, "--machine", "workstation"]) as ws:
        robot.wait_running()
        ws.wait_running()
        time.sleep(args.warmup)
        lat, rep, fs = _tap(ws.run_root / "current", args.duration)
        peer = json.loads((ws.run_root / "current" / "graph.json").read_text())["machine"]["peers"]["robot"]
    note = f"clock offset {peer.get('offset_ns', 0) / 1e3:+.0f} µs ± {peer.get('uncertainty_ns', 0) / 1e3:.0f} µs"
    return _row(name, lat, rep, fs, (load0, os.getloadavg()[0]), note)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                epilog="Prints one line per configuration and a JSON summary (--json FILE).")
    p.add_argument("--only-hops", action="store_true", help="only the one-hop part")
    p.add_argument("--duration", type=float, default=20.0, help="seconds timed per configuration (default 20)")
    p.add_argument("--warmup", type=float, default=3.0, help="seconds after the graph is up before timing (default 3)")
    p.add_argument("--hops", type=int, default=5000, help="frames per transport in the one-hop part (default 5000)")
    p.add_argument("--json", metavar="FILE", help="also write the rows as JSON")
    args = p.parse_args(argv)
    print_versions()
    with tempfile.TemporaryDirectory(prefix="ssb2-") as tmp_dir:
        tmp = Path(tmp_dir)
        keys = tmp / "keys"
        subprocess.run([sys.executable, "-m", "slipstack.launch.cli", "keys", str(keys), "--machine", "robot",
                        "--machine", "workstation"], check=True, capture_output=True)
        rows = [] if args.only_hops else _stack_rows(tmp, keys, args)
        port = random.randrange(20000, 32000)  # below the ephemeral ports (32768-60999)
        hops = [_one_hop("one hop, ipc", f"ipc://{tmp}/hop.pub", None, args.hops),
                _one_hop("one hop, plain tcp", f"tcp://127.0.0.1:{port}", None, args.hops),
                _one_hop("one hop, tcp + CURVE", f"tcp://127.0.0.1:{port + 1}", keys / "robot", args.hops)]
    ipc, tcp, secure = hops
    print(f"one hop: tcp / ipc p50 {tcp['p50_ms'] / ipc['p50_ms']:.2f}x, CURVE / tcp p50 "
          f"{secure['p50_ms'] / tcp['p50_ms']:.2f}x, p99 {secure['p99_ms'] / tcp['p99_ms']:.2f}x; "
          f"cores {os.cpu_count()}")
    if rows:
        one, split, plain = rows
        print(f"stack: split / one host p50 {split['p50_ms'] / one['p50_ms']:.2f}x, p99 "
              f"{split['p99_ms'] / one['p99_ms']:.2f}x; CURVE / plain tcp p50 "
              f"{split['p50_ms'] / plain['p50_ms']:.2f}x, p99 {split['p99_ms'] / plain['p99_ms']:.2f}x")
    if args.json:
        Path(args.json).write_text(json.dumps(rows + hops, indent=1))
    return 0


def _stack_rows(tmp: Path, keys: Path, args: argparse.Namespace) -> list[dict]:
    """Fig. 15 on one host, split with CURVE, split over plain tcp: one row each."""
    scene = long_scene("fig15", args.warmup + args.duration + 30.0, tmp / "fig15_long.toml")
    common = [f"scene:={scene}", "record:=false", "monitor:=false", "check:=false", f"rdt_port:={free_udp_port()}"]
    plain = tmp / "plain.toml"  # the same graph, tcp without CURVE
    plain.write_text(f'[launch]\nextends = "{launch_files_dir() / "two_hosts.toml"}"\ninsecure = true\n\n'
                     + "".join(f'[machines.{m}]\naddress = "$({m}_address)"\nports = ["$(first_port)", '
                               f'"$(last_port)"]\nnodes = {nodes}\n\n'
                               for m, nodes in (("robot", '["rig", "ft_driver", "tactile_driver"]'),
                                                ("workstation", '["fusion", "cor_estimator", "slip_detector", '
                                                                '"grip_controller", "monitor", "recorder"]'))))
    return [_one_host(common, args),
            _two_hosts("two hosts, CURVE", "two_hosts", [*common, f"keys:={keys}"], args),
            _two_hosts("two hosts, plain tcp", str(plain), common, args)]


if __name__ == "__main__":
    sys.exit(main())
