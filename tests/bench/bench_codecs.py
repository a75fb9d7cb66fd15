"""Benchmark the device codecs and the driver paths (run by hand, not by CI).

More in docs/modules.md, `tests/bench/bench_codecs.py`.
"""

from __future__ import annotations

import argparse
import select
import threading
import time

import numpy as np

from slipstack.lib.protocols import bota, dsacon32, m1616, robotiq
from slipstack.lib.protocols.ati_rdt import decode_records, encode_record
from slipstack.lib.protocols.crc import CRC16_DSACON32, CRC16_MODBUS, CRC16_X25
from slipstack.lib.protocols.framed import FramedCodec, FramedFormat, encode_frame as encode_framed
from slipstack.lib.protocols.stream import Deframer
from slipstack.nodes.devices.backends import backend_from_url
from slipstack.messages import (
    Contact, Cor, Diagnostics, GripCommand, Header, Message, RigTruth, Slip, TactileFrame, Wrench, decode, encode,
    handed_over,
)
from slipstack.nodes.devices.emulators import Dsacon32Emulator, M1616Emulator, RdtUdpServer
from _versions import print_versions


def _per_call_us(fn, n: int) -> float:
    t0 = time.perf_counter()
    for _ in range(n):
        fn()
    return (time.perf_counter() - t0) / n * 1e6


def bench_decoding(n_frames: int, chunk: int) -> list[tuple[str, int, float]]:
    """(name, frame bytes, µs per frame) for each protocol's deframer."""
    rng = np.random.default_rng(1)
    tact = rng.integers(0, 4096, (16, 16))
    dsa_payload = dsacon32.encode_frame_payload(1, tact)
    u12 = FramedFormat(header=b"\xa5\x5a", rows=16, cols=16, dtype="u12", checksum="crc16")
    ccitt = FramedFormat(header=b"\xa5\x5a", rows=16, cols=16, dtype="u16", checksum="crc16-ccitt")
    cases = {
        "robotiq (16 B, CRC-16/Modbus)": (robotiq.StreamCodec(), robotiq.encode_frame([1, 2, 3], [0.1, 0.2, 0.3])),
        "bota (37 B, CRC-16/X-25)": (bota.StreamCodec(), bota.encode_frame([1, 2, 3], [0.1, 0.2, 0.3], timestamp_us=1)),
        "dsacon32 16x16 (527 B, CRC)": (dsacon32.PacketCodec(allow_empty=False), dsacon32.encode_packet(0, dsa_payload)),
        "m1616 (519 B, no check)": (FramedCodec(m1616.FORMAT), encode_framed(m1616.FORMAT, tact)),
        "framed u12+crc16 (516 B)": (FramedCodec(u12), encode_framed(u12, tact)),
        "framed u16+crc16-ccitt (516 B)": (FramedCodec(ccitt), encode_framed(ccitt, tact)),
    }
    rows = []
    for name, (codec, frame) in cases.items():
        block = frame * chunk
        d = Deframer(codec)
        reps = max(1, n_frames // chunk)
        us = _per_call_us(lambda: d.feed(block), reps) / chunk
        assert d.counts.frames == reps * chunk and d.counts.crc_errors == 0
        rows.append((name, len(frame), us))
    record = encode_record(1, 1, 0, [1, 2, 3, 4, 5, 6])
    rows.append(("rdt record (36 B, no CRC)", 36, _per_call_us(lambda: decode_records(record), n_frames)))
    body34 = bytes(range(34))
    rows.append(("  CRC-16/X-25 over 34 B", 34, _per_call_us(lambda: CRC16_X25(body34), n_frames)))
    rows.append(("  CRC-16/Modbus over 14 B", 14, _per_call_us(lambda: CRC16_MODBUS(body34[:14]), n_frames)))
    rows.append(("  CRC DSACON32 over 519 B", 519, _per_call_us(lambda: CRC16_DSACON32(dsa_payload), n_frames // 10)))
    return rows


FIG15_PUBLISHED = {"Wrench": 6002, "TactileFrame": 3002, "Contact": 6002, "Cor": 3002, "Slip": 6002,
                   "GripCommand": 6002, "RigTruth": 3001, "Diagnostics": 96}
"""Messages of each type one ``slipstack launch fig15 --lockstep`` publishes: each is handed
over to its in-process subscribers, and encoded for the recording unless it is a ``Contact``."""
FIG15_UNRECORDED = ("Contact",)


def fig15_messages() -> dict[str, Message]:
    """One message of each type with the values, dtypes and sizes fig15 publishes."""
    rng = np.random.default_rng(2)
    pressure = rng.uniform(0.0, 4e4, 256).astype(np.float32)
    mask = pressure > 1e4
    verdict = {name: [True, 0.9886446731056432] for name in ("exact", "coulomb", "decoupled", "linear_ls", "elliptic_ls")}
    no_earlier = {"earlier_stamp_ns": np.zeros(0, np.int64), "earlier_status": np.zeros(0, np.uint8),
                  **{n: np.zeros(0) for n in ("earlier_f_n", "earlier_f_tx", "earlier_f_ty", "earlier_tau")}}
    return {
        "Wrench": Wrench(force=np.array([0.12, -0.03, -2.71]), torque=np.array([1e-3, 2e-4, -1e-4]), frame="pad",
                         device_seq=49, status="ok"),
        "TactileFrame": TactileFrame(rows=16, cols=16, pitch_m=1.25e-3, pressure_pa=pressure,
                                     saturated=np.zeros(256, bool), dead=np.zeros(256, bool), device_stamp=1_600_000_000),
        "Contact": Contact(rows=16, cols=16, pitch_m=1.25e-3, phi=np.where(mask, pressure, 0).astype(np.float64) * 1e-6, f_n=2.71875,
                           f_t=np.array([0.12, -0.03]), tau=0.0, cop=np.array([1e-3, -2e-3]), area_m2=2.25e-4, mask=mask,
                           pair_offset_ns=-4_000_000, **no_earlier),
        "Cor": Cor(case="rotation", p_c=np.array([1e-3, 2e-3]), torque_capacity=0.0079, load_torque=-1.1e-4,
                   gamma=0.0141, iterations=3, residual=6.2e-10, converged=True, status="converged"),
        "Slip": Slip(state="stick", margin=0.9877945639956087, method="exact", verdicts=verdict, gamma=0.0122,
                     f_n=2.71875, f_t=np.array([0.12, -0.03]), tau=0.0, p_c=np.array([1e-3, 2e-3]), p_c_valid=True),
        "GripCommand": GripCommand(f_n_desired=2.71875, law="tactile14", reason="slip"),
        "RigTruth": RigTruth(x=1e-5, y=-2e-5, theta=1e-4, vx=0.0, vy=0.0, omega=0.0, cor=np.zeros(2),
                             f_n_applied=2.714, f_n_command=2.7125, load_f_t=np.array([0.12, -0.03]), load_tau=-0.0),
        "Diagnostics": Diagnostics(node="fusion", counters={f"in.topic{k}.received": 1000 + k for k in range(40)}),
    }


def _best_us(fn, n: int, repeats: int = 7) -> float:
    """CPU µs per call (``time.process_time``: what other processes take is not counted),
    the least of ``repeats`` runs of ``n`` calls."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.process_time()
        for _ in range(n):
            fn()
        best = min(best, (time.process_time() - t0) / n * 1e6)
    return best


def bench_messages(n: int) -> list[tuple[str, float, float, float]]:
    """(type, µs per hand-over, per encode, per decode) for each of :func:`fig15_messages`."""
    header = Header(1_600_000_000, 1234, 1_600_000_100, {"ft": 1_600_000_000, "tactile": 1_596_000_000})
    rows = []
    for name, msg in fig15_messages().items():
        assert handed_over(msg, header)[1] is None, name
        payload = encode(msg, header)
        reps = max(1, n if len(payload) < 1000 else n // 4)
        rows.append((name, _best_us(lambda: handed_over(msg, header), reps), _best_us(lambda: encode(msg, header), reps),
                     _best_us(lambda: decode(payload), reps)))
    return rows


def _paced(rate_hz: float, seconds: float, send, stop: threading.Event) -> int:
    """Call send(k) at absolute deadlines k/rate (catching up after a late wake-up)."""
    period = 1.0 / rate_hz
    t0 = time.perf_counter()
    n_total = int(rate_hz * seconds)
    k = 0
    while k < n_total and not stop.is_set():
        due = int((time.perf_counter() - t0) / period) + 1
        while k < min(due, n_total):
            send(k)
            k += 1
        time.sleep(min(period, 0.0005))
    return k


def run_path(name: str, emulator, url: str, send, rate_hz: float, seconds: float, index_of) -> dict:
    backend = backend_from_url(url)
    backend.open(time.monotonic_ns())
    # wait for the handshake (the emulator reacts to commands inside send)
    t_end = time.monotonic() + 3.0
    while backend.poll(time.monotonic_ns()) == [] and time.monotonic() < t_end:
        send(emulator, -1)
        fd = backend.fileno()
        if fd is not None:
            select.select([fd], [], [], 0.005)
    stop = threading.Event()
    result = {}

    def sender():
        result["sent"] = _paced(rate_hz, seconds, lambda k: send(emulator, k), stop)

    th = threading.Thread(target=sender)
    base = backend.counters
    seen: list[int] = []
    cpu0 = time.process_time()
    t0 = time.perf_counter()
    th.start()
    while th.is_alive() or time.perf_counter() - t0 < seconds + 0.2:
        fd = backend.fileno()
        if fd is not None:
            select.select([fd], [], [], 0.002)
        for s in backend.poll(time.monotonic_ns()):
            k = index_of(s)
            if k >= 0:
                seen.append(k)
        if not th.is_alive() and seen and seen[-1] == result.get("sent", 0) - 1:
            break
    th.join()
    cpu = time.process_time() - cpu0
    c = backend.counters
    backend.close()
    emulator.close()
    ks = np.array(seen)
    missing = result["sent"] - len(set(seen))
    return {
        "path": name, "rate_hz": rate_hz, "sent": result["sent"], "received": len(seen),
        "missing": missing, "out_of_order": int(np.sum(np.diff(ks) <= 0)) if len(ks) > 1 else 0,
        "gaps_counter": c["gaps"] - base["gaps"], "crc_errors": c["crc_errors"],
        "cpu_pct": 100 * cpu / max(seconds, 1e-9),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seconds", type=float, default=3.0, help="duration of each path run (s)")
    ap.add_argument("--frames", type=int, default=3000, help="frames per decoding measurement")
    ap.add_argument("--chunk", type=int, default=4, help="frames per feed() call")
    ap.add_argument("--messages", action="store_true", help="only the messages' hand-over, encoding and decoding")
    ap.add_argument("--calls", type=int, default=10000, help="calls per message measurement (the best of 7 runs)")
    args = ap.parse_args()
    print_versions()

    print(f"{'message':14s} {'hand-over':>9s} {'encode':>7s} {'both':>6s} {'decode':>7s}  (CPU µs per message)")
    rows = bench_messages(args.calls)
    for name, hand_over_us, encode_us, decode_us in rows:
        print(f"{name:14s} {hand_over_us:9.2f} {encode_us:7.2f} {hand_over_us + encode_us:6.2f} {decode_us:7.2f}")
    published = sum(FIG15_PUBLISHED.values())
    hand_over = sum(FIG15_PUBLISHED[r[0]] * r[1] for r in rows) / published
    encoded = sum(FIG15_PUBLISHED[r[0]] * r[2] for r in rows if r[0] not in FIG15_UNRECORDED) / published
    decoded = sum(FIG15_PUBLISHED[r[0]] * r[3] for r in rows) / published
    print(f"{'fig15 mix':14s} {hand_over:9.2f} {encoded:7.2f} {hand_over + encoded:6.2f} {decoded:7.2f}  "
          f"(per message published: {published}, all handed over, all but {', '.join(FIG15_UNRECORDED)} encoded)")
    if args.messages:
        return
    print()

    print(f"{'decoder':34s} {'bytes':>6s} {'µs/frame':>9s}")
    for name, nbytes, us in bench_decoding(args.frames, args.chunk):
        print(f"{name:34s} {nbytes:6d} {us:9.2f}")

    def tactile_counts(k: int) -> np.ndarray:
        c = np.full((16, 16), 100, dtype=np.uint16)
        c[0, 0], c[0, 1] = k & 0xFFF, k >> 12
        return c

    def tactile_index(s) -> int:
        return int(s.counts[0, 0]) | int(s.counts[0, 1]) << 12

    runs = []
    rdt = RdtUdpServer()
    runs.append(run_path(
        "rdt udp 7 kHz", rdt, f"{rdt.url}?rate_hz=7000",
        lambda e, k: e.send_ft([k / 1e6, 0, 0], [0, 0, 0]) if k >= 0 else e.service(),
        7000.0, args.seconds, lambda s: s.device_seq - 1))
    dsa = Dsacon32Emulator()
    runs.append(run_path(
        "dsacon32 pty 1 kHz", dsa, f"dsacon32://{dsa.path}?fps=1000",
        lambda e, k: e.send_tactile(tactile_counts(max(k, 0))) if k >= 0 else e.service(),
        1000.0, args.seconds, tactile_index))
    m = M1616Emulator()
    runs.append(run_path(
        "m1616 pty 1 kHz", m, f"m1616://{m.path}?rate_hz=1000",
        lambda e, k: e.send_tactile(tactile_counts(k)) if k >= 0 else None,
        1000.0, args.seconds, tactile_index))
    print()
    print(f"{'path':20s} {'rate':>6s} {'sent':>7s} {'recv':>7s} {'missing':>7s} {'ooo':>4s} {'gaps':>5s} {'crc':>4s} {'cpu%':>5s}")
    for r in runs:
        print(f"{r['path']:20s} {r['rate_hz']:6.0f} {r['sent']:7d} {r['received']:7d} {r['missing']:7d} "
              f"{r['out_of_order']:4d} {r['gaps_counter']:5d} {r['crc_errors']:4d} {r['cpu_pct']:5.1f}")


if __name__ == "__main__":
    main()
