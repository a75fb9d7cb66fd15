"""Transport latency: slipstack ProcessExecutor chains beside raw pyzmq + msgpack.

A source publishes at ``--rate`` Hz (paced by absolute deadlines), ``hops - 1``
relays forward, a sink measures ``receive time - source stamp`` (CLOCK_MONOTONIC,
same clock in every process) and counts what arrived. Two payload sizes: a
``Wrench`` (~108 B encoded) and a 12×16 ``TactileFrame`` (~1.2 KB). Every process is
forked (no ZeroMQ context exists before the fork), endpoints are ``ipc://``.

More in docs/modules.md, `tests/bench/bench_transport.py`.
"""

from __future__ import annotations

import argparse
import dataclasses
import multiprocessing as mp
import os
import signal
import tempfile
import time
import timeit
from typing import Any

import msgpack
import numpy as np

from slipstack.messages import Header, Message, TactileFrame, Wrench, decode, encode
from slipstack.nodes.runtime.node import Input, Node, Output
from _versions import print_versions

WARMUP = 200  # first messages left out of the statistics


def make_message(size: str) -> Message:
    if size == "small":
        return Wrench(force=np.array([0.5, -0.25, 10.0]), torque=np.array([0.01, 0.02, -0.003]))
    n = 12 * 16
    return TactileFrame(rows=12, cols=16, pressure_pa=np.linspace(0, 5e4, n, dtype=np.float32),
                        saturated=np.zeros(n, bool), dead=np.zeros(n, bool))


class CpuPerMessage:
    """Process CPU time per message (µs), counted from the first message on."""

    def __init__(self) -> None:
        self.n = 0
        self.cpu0_ns = 0
        self.thread0_ns = 0

    def count(self) -> None:
        if self.n == 0:
            self.cpu0_ns = time.process_time_ns()
            self.thread0_ns = time.thread_time_ns()
        self.n += 1

    def us_per_message(self) -> float:
        return (time.process_time_ns() - self.cpu0_ns) / 1e3 / (self.n - 1) if self.n > 1 else float("nan")

    def thread_us_per_message(self) -> float:
        """The calling (main) thread's CPU per message, µs: the process's without ZeroMQ's I/O thread."""
        return (time.thread_time_ns() - self.thread0_ns) / 1e3 / (self.n - 1) if self.n > 1 else float("nan")


# -- raw pyzmq + msgpack ---------------------------------------------------------------------
def _raw_process(role: str, ep_in: str | None, ep_out: str | None, size: int, rate: float,
                 ready: Any, results: Any, msg: Message | None = None) -> None:
    """One raw pyzmq process; with ``msg``, frames are that message encoded and decoded by
    slipstack's codec (the ``raw+codec`` case), otherwise msgpack lists of ``size`` bytes."""
    import zmq

    ctx = zmq.Context()
    stop = {"now": False}
    signal.signal(signal.SIGINT, lambda *_: stop.__setitem__("now", True))
    pub = sub = None
    if ep_out:
        pub = ctx.socket(zmq.XPUB)
        pub.setsockopt(zmq.LINGER, 0)
        pub.bind(ep_out)
    if ep_in:
        sub = ctx.socket(zmq.SUB)
        sub.setsockopt(zmq.LINGER, 0)
        sub.setsockopt(zmq.RCVHWM, 1000)
        sub.setsockopt(zmq.SUBSCRIBE, b"t")
        sub.connect(ep_in)
    ready.set()
    if pub is not None:
        while not stop["now"] and not pub.poll(100):
            pass  # wait for the downstream subscription (no slow-joiner loss)
        if stop["now"]:
            return
        pub.recv()
    if role == "source":
        overhead = len(msgpack.packb([time.monotonic_ns(), 0, b""]))
        blob = b"x" * max(0, size - overhead - 3)
        period = round(1e9 / rate)
        due = time.monotonic_ns() + period
        seq = 0
        cpu = CpuPerMessage()
        while not stop["now"]:
            now = time.monotonic_ns()
            if due > now:
                time.sleep((due - now) / 1e9)
            if msg is None:
                pub.send_multipart((b"t", msgpack.packb([time.monotonic_ns(), seq, blob])))
            else:
                stamp = time.monotonic_ns()
                pub.send_multipart((b"t", encode(msg, Header(stamp, seq, stamp, {}))))
            cpu.count()
            seq += 1
            due += period
        results.put(("sent", seq))
        results.put(("cpu_source", cpu.us_per_message()))
    elif role == "relay":
        while not stop["now"]:
            if sub.poll(100):
                _, payload = sub.recv_multipart()
                if msg is None:
                    pub.send_multipart((b"t", msgpack.packb(msgpack.unpackb(payload))))
                else:
                    got = decode(payload, type(msg))
                    pub.send_multipart((b"t", encode(got, Header(got.header.stamp_ns, got.header.seq,
                                                                 time.monotonic_ns(), {}))))
    else:
        lat: list[int] = []
        cpu = CpuPerMessage()
        while not stop["now"]:
            if sub.poll(100):
                _, payload = sub.recv_multipart()
                if msg is None:
                    now = time.monotonic_ns()
                    stamp, seq, _ = msgpack.unpackb(payload)
                else:  # as a node: the stamp is known once the frame is decoded and valid
                    stamp = decode(payload, type(msg)).header.stamp_ns
                    now = time.monotonic_ns()
                lat.append(now - stamp)
                cpu.count()
        _put_sink_results(results, lat, cpu)
    ctx.destroy(linger=0)


# -- slipstack nodes -------------------------------------------------------------------------
class BenchSource(Node):
    """Publishes a fixed message on a timer; reports how many it sent."""

    def __init__(self, msg: Message, rate: float, results: Any) -> None:
        super().__init__()
        self.msg, self.results = msg, results
        self.outputs = {"out": Output("t0", type(msg))}
        self.timers = {"tick": 1.0 / rate}
        self.sent = 0
        self.cpu = CpuPerMessage()

    def on_timer_tick(self, ctx: Any) -> None:
        ctx.publish("out", self.msg, stamp_ns=ctx.now_ns())
        self.cpu.count()
        self.sent += 1

    def stop(self, ctx: Any) -> None:
        self.results.put(("sent", self.sent))
        self.results.put(("cpu_source", self.cpu.us_per_message()))


class BenchRelay(Node):
    """Republishes each message with its stamp (like the demo relay)."""

    def __init__(self, msg_type: type[Message], k: int) -> None:
        super().__init__()
        self.inputs = {"x": Input(f"t{k}", msg_type, policy="queue")}
        self.outputs = {"out": Output(f"t{k + 1}", msg_type)}

    def on_x(self, msg: Message, ctx: Any) -> None:
        ctx.publish("out", msg, stamp_ns=msg.header.stamp_ns)


class BenchSink(Node):
    """Records receive time minus source stamp."""

    def __init__(self, msg_type: type[Message], k: int, results: Any) -> None:
        super().__init__()
        self.inputs = {"x": Input(f"t{k}", msg_type, policy="queue")}
        self.results = results
        self.lat: list[int] = []
        self.cpu = CpuPerMessage()

    def on_x(self, msg: Message, ctx: Any) -> None:
        self.lat.append(ctx.now_ns() - msg.header.stamp_ns)
        self.cpu.count()

    def stop(self, ctx: Any) -> None:
        _put_sink_results(self.results, self.lat, self.cpu)


def _put_sink_results(results: Any, lat: list[int], cpu: CpuPerMessage) -> None:
    results.put(("lat", np.array(lat, dtype=np.int64)))
    results.put(("cpu_sink", cpu.us_per_message()))
    results.put(("cpu_sink_thread", cpu.thread_us_per_message()))


def _slip_process(node_factory: Any, spec_kwargs: dict, ready: Any) -> None:
    from slipstack.nodes.runtime.process import ProcessExecutor, RunSpec

    node = node_factory()
    ex = ProcessExecutor([(node, RunSpec(**spec_kwargs))])
    ready.set()
    ex.run()


# -- running a case --------------------------------------------------------------------------
def _run_case(impl: str, size: str, hops: int, rate: float, duration: float) -> dict[str, Any]:
    fork = mp.get_context("fork")
    results = fork.Queue()
    msg = make_message(size)
    nbytes = len(encode(msg))
    with tempfile.TemporaryDirectory(prefix="bt-", dir="/tmp") as d:
        eps = [f"ipc://{d}/n{k}.pub" for k in range(hops)]
        procs: list[tuple[str, Any]] = []  # (role, process), sink first
        for k in range(hops, -1, -1):  # k = position in the chain: 0 source, hops sink
            role = "source" if k == 0 else "sink" if k == hops else "relay"
            ep_in = eps[k - 1] if k > 0 else None
            ep_out = eps[k] if k < hops else None
            ready = fork.Event()
            if impl in ("raw", "raw+codec"):
                target = _raw_process
                args = (role, ep_in, ep_out, nbytes, rate, ready, results, msg if impl == "raw+codec" else None)
            else:
                mtype = type(msg)
                factory = {
                    "source": lambda: BenchSource(msg, rate, results),
                    "relay": (lambda k=k: BenchRelay(mtype, k - 1)),
                    "sink": (lambda k=k: BenchSink(mtype, k - 1, results)),
                }[role]
                spec = {"name": f"n{k}", "pub": ep_out, "subs": {f"t{k - 1}": [ep_in]} if ep_in else {},
                        "expected_subscribers": {f"t{k}": 1} if ep_out else {}}
                target, args = _slip_process, (factory, spec, ready)
            p = fork.Process(target=target, args=args, daemon=True)
            p.start()
            ready.wait(10)
            procs.append((role, p))
        time.sleep(duration)
        for role, p in reversed(procs):  # source first, sink last
            os.kill(p.pid, signal.SIGINT)
            time.sleep(0.3 if role == "source" else 0.05)
        got: dict[str, Any] = {}
        for _ in range(5):
            key, value = results.get(timeout=20)
            got[key] = value
        for _, p in procs:
            p.join(5)
    lat = got["lat"][WARMUP:] / 1e3
    return {"impl": impl, "size": nbytes, "hops": hops, "n": len(got["lat"]), "sent": got["sent"],
            "p50": np.percentile(lat, 50), "p99": np.percentile(lat, 99), "p999": np.percentile(lat, 99.9),
            "loss": got["sent"] - len(got["lat"]), "cpu_source": got["cpu_source"], "cpu_sink": got["cpu_sink"],
            "cpu_sink_thread": got["cpu_sink_thread"]}


# -- codec profile ---------------------------------------------------------------------------
def _per_call_us(fn: Any, n: int = 20000) -> float:
    return min(timeit.repeat(fn, number=n, repeat=3)) / n * 1e6


def _prototype_ext_hook() -> Any:
    """Array ext decoding with the parsed header (dtype, shape, size) cached by its bytes."""
    from slipstack.messages.codec import ARRAY_EXT, unpack_array

    cache: dict[bytes, tuple[np.dtype, tuple[int, ...], int, int]] = {}

    def hook(code: int, data: bytes) -> Any:
        if code != ARRAY_EXT or not data:
            return unpack_array(data) if code == ARRAY_EXT else msgpack.ExtType(code, data)
        n = data[0]
        off = 2 + n + 4 * data[1 + n] if len(data) > 1 + n else 0
        head = data[:off]
        hit = cache.get(head)
        if hit is None:
            arr = unpack_array(data)  # full checks once per distinct header
            cache[head] = (arr.dtype, arr.shape, arr.size, arr.nbytes)
            return arr
        dtype, shape, count, nbytes = hit
        if len(data) - off != nbytes:
            return unpack_array(data)  # raises DecodeError naming the mismatch
        arr = np.frombuffer(data, dtype=dtype, count=count, offset=off)
        return arr if len(shape) == 1 else arr.reshape(shape)

    return hook


def _prototype_array_check(example: np.ndarray) -> Any:
    """A validator for one array field: exact dtype, shape, and finiteness via one dot product."""
    dtype, shape = example.dtype, example.shape
    zeros = np.zeros(example.size) if example.dtype.kind == "f" else None

    def check(v: np.ndarray) -> np.ndarray:
        if type(v) is not np.ndarray or v.dtype != dtype or v.shape != shape:
            raise ValueError("bad array")
        if zeros is not None and v.reshape(-1) @ zeros != 0.0:  # 0·inf and 0·nan are nan
            raise ValueError("non-finite")
        return v

    return check


def _thread_us(step: Any, n: int = 20000, repeat: int = 5) -> float:
    """Least main-thread CPU per call of ``step(k)`` over ``repeat`` runs of ``n`` calls, µs."""
    best = float("inf")
    for _ in range(repeat):
        t0 = time.thread_time_ns()
        for k in range(n):
            step(k)
        best = min(best, (time.thread_time_ns() - t0) / n / 1e3)
    return best


def receive_path() -> None:
    """A wake-up's receive path, one frame at a time, in one thread over ``inproc`` (no I/O
    thread, no scheduler: what is left is the code): the executor's drain, decode, sequence
    tracking and guarded handler against raw ``recv_multipart`` + slipstack ``decode``; both
    include the send and a ``poll(0)``, as equal parts."""
    import zmq

    from slipstack.nodes.runtime.process import RunSpec, _Member

    ctx = zmq.Context()
    msg = make_message("small")
    frames = [encode(msg, Header(k, k, k, {})) for k in range(20000)]
    sink = BenchSink(type(msg), 0, None)
    member_pub, raw_pub = ctx.socket(zmq.PUB), ctx.socket(zmq.PUB)
    member_pub.bind("inproc://member")
    raw_pub.bind("inproc://raw")
    member = _Member(sink, RunSpec(name="sink", subs={"t0": ["inproc://member"]}), ctx)
    (member_sub, _), = member.sub_topic.items()
    raw_sub = ctx.socket(zmq.SUB)
    raw_sub.setsockopt(zmq.SUBSCRIBE, b"")
    raw_sub.connect("inproc://raw")
    time.sleep(0.2)  # subscriptions reach the publishers
    member_poller, raw_poller = zmq.Poller(), zmq.Poller()
    member_poller.register(member_sub, zmq.POLLIN)
    raw_poller.register(raw_sub, zmq.POLLIN)

    def framework(k: int) -> None:
        member_pub.send_multipart((b"t0", frames[k]))
        member_poller.poll(0)
        member.drain("x", member_sub)

    def raw(k: int) -> None:
        raw_pub.send_multipart((b"t0", frames[k]))
        raw_poller.poll(0)
        decode(raw_sub.recv_multipart(zmq.NOBLOCK)[1], type(msg))

    fw_us, raw_us = _thread_us(framework), _thread_us(raw)
    print(f"\n### receive path per wake-up, {msg.TYPE} over inproc (main-thread CPU, least of 5 × 20 000)\n")
    print("| path | µs per message |\n| --- | ---: |")
    print(f"| raw pyzmq: send, poll, recv_multipart, decode | {raw_us:.2f} |")
    print(f"| framework: send, poll, drain (read, decode, sequence, counters, guarded handler) | {fw_us:.2f} |")
    print(f"| framework's own share | {fw_us - raw_us:.2f} |")
    ctx.destroy(linger=0)


def profile() -> None:
    """Cost of each step a relay pays per message, and of prototyped cheaper steps."""
    from slipstack.messages.codec import packb, unpackb

    for size in ("small", "large"):
        msg = make_message(size)
        cls = type(msg)
        payload = encode(dataclasses.replace(msg, header=Header(1, 2, 3, {"a": 4})))
        hdr = Header(5, 6, 7, {})
        fields = cls._body_fields

        def encode_direct() -> bytes:  # prototype: encode with a new header, no dataclasses.replace
            return packb([cls.TYPE, cls.VERSION, [hdr.stamp_ns, hdr.seq, hdr.pub_ns, hdr.sources],
                          [getattr(msg, n) for n in fields]])

        def construct_new() -> Message:  # prototype: build the frozen instance without __init__
            obj = object.__new__(cls)
            obj.__dict__.update(zip(fields, [getattr(msg, n) for n in fields]), header=hdr)
            return obj

        values = {n: getattr(msg, n) for n in fields}
        fast_hook = _prototype_ext_hook()
        fast_checks = [_prototype_array_check(v) if isinstance(v, np.ndarray) else None for v in values.values()]

        def validate_fast() -> None:
            for check, v in zip(fast_checks, values.values()):
                if check is not None:
                    check(v)
        rows = [
            ("decode (unpack + validate + construct)", _per_call_us(lambda: decode(payload, cls))),
            ("  unpackb only (arrays as numpy)", _per_call_us(lambda: unpackb(payload))),
            ("  validators only", _per_call_us(lambda: [c(v) for c, v in zip(cls._validators, values.values())])),
            ("  prototype: array validators with fixed shape + dot finiteness", _per_call_us(validate_fast)),
            ("  prototype: unpackb with a cached array-header ext_hook",
             _per_call_us(lambda: msgpack.unpackb(payload, ext_hook=fast_hook, raw=False, strict_map_key=True))),
            ("  dataclass __init__ (frozen)", _per_call_us(lambda: cls(header=hdr, **values))),
            ("  prototype: object.__new__ + __dict__.update", _per_call_us(construct_new)),
            ("encode", _per_call_us(lambda: encode(msg))),
            ("dataclasses.replace(msg, header=…) in publish", _per_call_us(lambda: dataclasses.replace(msg, header=hdr))),
            ("prototype: encode with the header, no replace", _per_call_us(encode_direct)),
        ]
        print(f"\n### codec costs, {cls.TYPE} ({len(payload)} B)\n\n| step | µs per message |\n| --- | ---: |")
        for label, us in rows:
            print(f"| {label} | {us:.2f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--duration", type=float, default=10.0, help="seconds per case (default 10)")
    ap.add_argument("--rate", type=float, default=1000.0, help="source rate in Hz (default 1000)")
    ap.add_argument("--hops", type=int, nargs="+", default=[1, 6], help="chain lengths (default 1 6)")
    ap.add_argument("--sizes", nargs="+", default=["small", "large"], choices=["small", "large"])
    ap.add_argument("--profile", action="store_true",
                    help="print per-step codec costs and the receive path's cost per wake-up, and exit")
    args = ap.parse_args()
    print_versions()
    if args.profile:
        profile()
        receive_path()
        return
    with open("/proc/loadavg") as fh:
        print(f"load average at start: {' '.join(fh.read().split()[:3])}\n")
    print("| size B | hops | impl | received | p50 µs | p99 µs | p99.9 µs | loss | p50 vs raw | p50 vs raw+codec "
          "| CPU µs/msg source | CPU µs/msg sink (main thread) | sink CPU vs raw | sink CPU vs raw+codec |")
    print("| ---: | ---: | --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for size in args.sizes:
        for hops in args.hops:
            raw, fair, slip = (_run_case(impl, size, hops, args.rate, args.duration)
                               for impl in ("raw", "raw+codec", "slipstack"))
            for r in (raw, fair, slip):
                print(f"| {r['size']} | {r['hops']} | {r['impl']} | {r['n']} | {r['p50']:.0f} | {r['p99']:.0f} | "
                      f"{r['p999']:.0f} | {r['loss']} | {r['p50'] / raw['p50']:.2f}× | {r['p50'] / fair['p50']:.2f}× | "
                      f"{r['cpu_source']:.0f} | {r['cpu_sink']:.0f} ({r['cpu_sink_thread']:.0f}) | "
                      f"{r['cpu_sink'] / raw['cpu_sink']:.2f}× | {r['cpu_sink'] / fair['cpu_sink']:.2f}× |", flush=True)


if __name__ == "__main__":
    main()
