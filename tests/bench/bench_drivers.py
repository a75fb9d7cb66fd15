"""Driver throughput: device emulator → driver process → ZeroMQ SUB, counting loss.

Cases (each ``--duration`` seconds after a warm-up):

- ``ft_driver`` on RDT (loopback UDP) at 7 kHz, one record per datagram;
- ``tactile_driver`` on M1616 (16×16, pty) at 1 kHz;
- ``tactile_driver`` on DSACON32 (16×16, pty, push mode fps=1000) at 1 kHz.

More in docs/modules.md, `tests/bench/bench_drivers.py`.
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import zmq

from slipstack.messages import decode
from slipstack.nodes.devices.emulators import Dsacon32Emulator, M1616Emulator, RdtUdpServer
from _versions import print_versions

CLK_TCK = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLK_TCK  # utime, stime


def make_case(name: str):
    """(node type, url, rate Hz, emulator, send() -> bool, extra params)."""
    if name == "rdt":
        emu = RdtUdpServer()
        f, t = [1.0, 2.0, 3.0], [0.1, 0.2, 0.3]
        return "ft_driver", emu.url + "?stale_ms=5", 7000.0, emu, lambda: emu.send_ft(f, t), []
    counts = (np.arange(256) * 13 % 4096).reshape(16, 16).astype(np.uint16)
    if name == "m1616":
        emu = M1616Emulator()
        return "tactile_driver", f"m1616://{emu.path}?rate_hz=1000", 1000.0, emu, lambda: emu.send_tactile(counts), []
    if name == "dsacon32":
        emu = Dsacon32Emulator()
        return ("tactile_driver", f"dsacon32://{emu.path}?fps=1000", 1000.0, emu,
                lambda: emu.send_tactile(counts), [])
    raise SystemExit(f"unknown case {name!r}")


def run_case(name: str, duration_s: float, run_dir: Path) -> dict:
    node, url, rate, emu, send, params = make_case(name)
    endpoint = f"ipc://{run_dir}/{name}.pub"
    log = open(run_dir / f"{name}.log", "wb")
    proc = subprocess.Popen([sys.executable, "-m", "slipstack.launch.cli", "run", node, f"url:={url}", *params,
                             "--pub", endpoint], stdout=log, stderr=subprocess.STDOUT)
    sub = zmq.Context.instance().socket(zmq.SUB)
    sub.setsockopt(zmq.RCVHWM, 100_000)
    sub.setsockopt(zmq.SUBSCRIBE, b"ft/wrench")
    sub.setsockopt(zmq.SUBSCRIBE, b"tactile/frame")
    sub.connect(endpoint)
    received = 0
    latencies: list[int] = []
    statuses: dict[str, int] = {}

    def drain(record: bool) -> None:
        nonlocal received
        while True:
            try:
                _, payload = sub.recv_multipart(zmq.NOBLOCK)
            except zmq.Again:
                return
            msg = decode(payload)
            statuses[msg.status] = statuses.get(msg.status, 0) + (1 if record else 0)
            if msg.status == "ok":
                received += 1
                if record:
                    latencies.append(time.monotonic_ns() - msg.header.stamp_ns)

    try:
        _pace(send, rate, 10.0, lambda: drain(False), stop_when=lambda: received > 0)  # handshake, warm-up
        if not received:
            raise SystemExit(f"{name}: no data from the driver\n{(run_dir / f'{name}.log').read_text()}")
        time.sleep(0.3)
        drain(False)
        received = 0
        statuses.clear()
        cpu0, t0 = cpu_seconds(proc.pid), time.monotonic()
        sent = _pace(send, rate, duration_s, lambda: drain(True))
        window = time.monotonic() - t0
        cpu = cpu_seconds(proc.pid) - cpu0
        deadline = time.monotonic() + 1.0
        while time.monotonic() < deadline and received < sent:
            drain(True)
            time.sleep(0.01)
    finally:
        sub.close(linger=0)
        proc.send_signal(signal.SIGINT)
        proc.wait(10)
        log.close()
        emu.close()
    lat = np.array(latencies) / 1e3
    return dict(case=name, node=node, rate=rate, sent=sent, published=received, loss=sent - received,
                cpu=100.0 * cpu / window, p50=np.percentile(lat, 50) if lat.size else float("nan"),
                p99=np.percentile(lat, 99) if lat.size else float("nan"),
                other={k: v for k, v in statuses.items() if k != "ok" and v})


def _pace(send, rate: float, seconds: float, drain, stop_when=None) -> int:
    """Send int(rate·t) samples by time t (absolute deadlines, ~0.5 ms turns) until
    ``seconds`` pass or stop_when() holds; returns the samples actually written."""
    t0 = time.monotonic()
    due = written = 0
    while True:
        elapsed = time.monotonic() - t0
        if elapsed >= seconds or (stop_when is not None and stop_when()):
            return written
        target = int(elapsed * rate)
        while due < target:
            due += 1
            written += 1 if send() else 0
        drain()
        time.sleep(0.0005)


def tight_loop_us(name: str, n: int) -> float:
    """Thread CPU (µs) of one ``on_readable`` per sample, driver in this process (module docstring)."""
    import select
    import statistics

    from slipstack.nodes.ft_driver import FtDriver, FtDriverParams
    from slipstack.nodes.runtime.host import NodeHost
    from slipstack.nodes.tactile_driver import TactileDriver, TactileDriverParams

    def one_run() -> float:
        node_type, url, _rate, emu, send, _params = make_case(name)
        node = (FtDriver(FtDriverParams(url=url)) if node_type == "ft_driver"
                else TactileDriver(TactileDriverParams(url=url)))
        published = []
        host = NodeHost(node, time.monotonic_ns, lambda topic, payload: published.append(len(payload)), name=name)
        service = getattr(emu, "service", lambda: None)
        try:
            host.call("start", node.start, host)
            deadline = time.monotonic() + 5.0
            while node.status != "ok" and time.monotonic() < deadline:  # handshake, first samples
                send()
                service()
                time.sleep(0.002)
                node.on_readable(None, host)
            cpu_ns = 0
            for _ in range(n):
                send()
                service()
                select.select([node.backend.fileno()], [], [], 1.0)
                t0 = time.thread_time_ns()
                node.on_readable(None, host)
                cpu_ns += time.thread_time_ns() - t0
            return cpu_ns / n / 1e3
        finally:
            node.stop(host)
            emu.close()

    return statistics.median(one_run() for _ in range(5))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--duration", type=float, default=10.0, help="measured window per case (s)")
    ap.add_argument("--case", action="append", choices=["rdt", "m1616", "dsacon32"],
                    help="run only this case (repeatable)")
    ap.add_argument("--tight", type=int, metavar="N", default=0,
                    help="instead: the driver's on_readable CPU per sample in this process, no bus, N samples")
    args = ap.parse_args()
    print_versions()
    if args.tight:
        for name in args.case or ["rdt", "m1616", "dsacon32"]:
            print(f"{name:<10}{tight_loop_us(name, args.tight):8.1f} us CPU per sample (on_readable, median of 5)")
        return
    rows = []
    with tempfile.TemporaryDirectory(prefix="ssb-", dir="/tmp") as d:
        for name in args.case or ["rdt", "m1616", "dsacon32"]:
            rows.append(run_case(name, args.duration, Path(d)))
    print(f"{'case':<10}{'node':<16}{'rate Hz':>8}{'sent':>9}{'published':>11}{'loss':>7}{'CPU %':>8}"
          f"{'lat p50 us':>12}{'p99 us':>9}  other statuses")
    for r in rows:
        print(f"{r['case']:<10}{r['node']:<16}{r['rate']:>8.0f}{r['sent']:>9}{r['published']:>11}{r['loss']:>7}"
              f"{r['cpu']:>8.1f}{r['p50']:>12.0f}{r['p99']:>9.0f}  {r['other'] or '-'}")


if __name__ == "__main__":
    main()
