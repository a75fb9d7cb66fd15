"""ROS 2 costs (docs/benchmarks.md, "ROS 2: CDR and the Zenoh bridge").

    python tests/bench/bench_ros2.py encode RECORDING.mcap   # CDR encoding: rosbags against mcap-ros2-support
    python tests/bench/bench_ros2.py bridge [--rate 1000] [--seconds 5]

More in docs/modules.md, `tests/bench/bench_ros2.py`.
"""

from __future__ import annotations

import argparse
import os
import socket
import subprocess
import sys
import threading
import time
from collections import defaultdict

import numpy as np
import zmq

from slipstack.messages import Header, Slip, decode, encode
from slipstack.messages.frame import peek_header
from slipstack.messages.ros2 import codec
from slipstack.nodes.recording.bag_io import read_recording
from slipstack.nodes.runtime.transport import make_pub, make_sub


def encode_speed(path: str) -> None:
    from mcap_ros2._dynamic import generate_dynamic, serialize_dynamic

    c = codec()
    by_type: dict[str, list] = defaultdict(list)
    for f in read_recording(path):
        m = decode(f.payload)
        out = c.to_ros(m)[0]
        by_type[out.ros_type].append(out.cdr)
    print(f"{'type':36} {'n':>6} {'rosbags us':>11} {'mcap_ros2 us':>13}  same bytes")
    for ros_type, blobs in sorted(by_type.items()):
        definition = c.definition(ros_type)
        to_dict = generate_dynamic(ros_type, definition)[ros_type]
        encoder = serialize_dynamic(ros_type, definition)[ros_type]
        objs = [c.deserialize(b, ros_type) for b in blobs]
        dicts = [to_dict(b) for b in blobs]
        t = time.process_time()
        ours = [bytes(c.store.serialize_cdr(o, ros_type)) for o in objs]
        rosbags_us = (time.process_time() - t) / len(objs) * 1e6
        t = time.process_time()
        theirs = [bytes(encoder(d)) for d in dicts]
        mcap_us = (time.process_time() - t) / len(objs) * 1e6
        print(f"{ros_type:36} {len(objs):6d} {rosbags_us:11.1f} {mcap_us:13.1f}  {ours == theirs}")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _cpu_s(pid: int) -> float:
    with open(f"/proc/{pid}/stat") as fh:
        fields = fh.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def bridge(rate: float, seconds: float) -> None:
    import zenoh

    from slipstack.lib import rmw_zenoh

    c = codec()
    endpoint = f"ipc:///tmp/bench_ros2_{os.getpid()}.pub"
    pub = make_pub(zmq.Context.instance(), endpoint)
    port = _free_port()
    config = zenoh.Config()
    for key, value in (("listen/endpoints", f'["tcp/127.0.0.1:{port}"]'), ("scouting/multicast/enabled", "false"),
                       ("scouting/gossip/enabled", "false")):
        config.insert_json5(key, value)
    peer = zenoh.open(config)
    zenoh_ms: list[float] = []
    key = rmw_zenoh.topic_key(0, "/slipstack/slip", "slipstack_msgs/msg/Slip", c.type_hash("slipstack_msgs/msg/Slip"))

    def on_sample(sample) -> None:
        now = time.monotonic_ns()
        zenoh_ms.append((now - c.deserialize(sample.payload.to_bytes(), "slipstack_msgs/msg/Slip").trace.pub_ns) / 1e6)

    sub = peer.declare_subscriber(key, on_sample)
    proc = subprocess.Popen([sys.executable, "-m", "slipstack.launch.cli", "run", "zenoh_bridge", "publish:=slip",
                             f"connect:=tcp/127.0.0.1:{port}", "listen:=", "gossip_scouting:=false",
                             "--sub", f"slip={endpoint}"], stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    zmq_sub = make_sub(zmq.Context.instance(), [endpoint], "slip")
    zmq_ms: list[float] = []
    stop = threading.Event()

    def bus_subscriber() -> None:
        while not stop.is_set():
            if zmq_sub.poll(50):
                topic, payload = zmq_sub.recv_multipart()
                zmq_ms.append((time.monotonic_ns() - peek_header(payload).pub_ns) / 1e6)

    reader = threading.Thread(target=bus_subscriber)
    reader.start()
    time.sleep(5.0)  # the bridge starts (rosbags, Zenoh), connects and subscribes
    n = int(rate * seconds)
    verdicts = {"exact": [True, 0.3], "coulomb": [True, 0.2]}
    cpu0 = _cpu_s(proc.pid)
    start = time.monotonic()
    for k in range(n):
        now = time.monotonic_ns()
        slip = Slip(state="stick", margin=0.3, method="exact", verdicts=verdicts, gamma=0.7, f_n=5.0,
                    f_t=np.array([1.0, 0.5]), p_c=np.zeros(2))
        pub.send_multipart([b"slip", encode(slip, Header(now, k, time.monotonic_ns(), {"ft": now}))])
        time.sleep(max(0.0, start + (k + 1) / rate - time.monotonic()))
    time.sleep(1.0)
    cpu = _cpu_s(proc.pid) - cpu0
    stop.set()
    reader.join()
    proc.terminate()
    proc.wait()
    sub.undeclare()
    peer.close()
    with open("/proc/loadavg") as fh:
        load = fh.read().split()[:3]
    print(f"{n} Slip messages at {rate:g} Hz, load average {' '.join(load)}")
    for name, ms in (("ZeroMQ bus (subscriber in this process)", zmq_ms), ("Zenoh via zenoh_bridge (peer here)", zenoh_ms)):
        a = np.array(ms)
        print(f"  {name:42} received {a.size:6d}  latency ms p50 {np.percentile(a, 50):6.3f}  "
              f"p99 {np.percentile(a, 99):6.3f}  max {a.max():7.3f}")
    print(f"  bridge process CPU: {cpu:.2f} s over {seconds + 1:.0f} s ({cpu / (seconds + 1) * 100:.1f} % of a core), "
          f"{cpu / n * 1e6:.0f} us per message")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    verbs = parser.add_subparsers(dest="verb", required=True)
    enc = verbs.add_parser("encode", help="CDR encoding CPU per message: rosbags against mcap-ros2-support")
    enc.add_argument("recording")
    br = verbs.add_parser("bridge", help="latency and CPU: the ZeroMQ bus against Zenoh through the bridge")
    br.add_argument("--rate", type=float, default=1000.0)
    br.add_argument("--seconds", type=float, default=5.0)
    args = parser.parse_args()
    if args.verb == "encode":
        encode_speed(args.recording)
    else:
        bridge(args.rate, args.seconds)


if __name__ == "__main__":
    main()
