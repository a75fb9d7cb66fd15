"""Tools on a machine other than the first stamp on the graph's time base: ``topic pub``
and ``bag play --restamp`` against a hand-made graph whose nodes on this machine run an
hour ahead of its monotonic clock (the first machine's clock, nodes/runtime/time_base.py).
Real sockets: the test binds the injection endpoint a node would."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time

import numpy as np
import zmq

from slipstack.messages import Header, Wrench, decode, encode
from slipstack.nodes.recording.bag_io import RecordingWriter
from slipstack.nodes.recording.player import play

HOUR_NS = 3_600 * 10**9
SECOND_NS = 10**9


def _graph_an_hour_ahead(run_dir, inject: str) -> None:
    """A graph on machine ``workstation`` whose clock is an hour ahead of ours; node ``sink`` takes
    ``ft/wrench`` injected at ``inject``."""
    sink = {"type": "sink", "pub": f"ipc://{run_dir}/sink.pub", "inputs": {"ft/wrench": Wrench.TYPE},
            "outputs": {"diagnostics": "slipstack/Diagnostics"}, "inject": {"ft/wrench": inject}, "restarts": 0}
    graph = {"nodes": {"sink": sink},
             "machine": {"name": "workstation", "hosts": {}, "clock_offset_ns": HOUR_NS, "peers": {}}}
    (run_dir / "graph.json").write_text(json.dumps(graph))


class _InjectedStamp(threading.Thread):
    """A node's injection socket: binds ``endpoint``, keeps polling (as a node's loop does: a bound
    SUB takes in a connecting tool only when used) until the first frame; its stamp in :attr:`stamp`."""

    def __init__(self, endpoint: str) -> None:
        super().__init__(daemon=True)
        self.endpoint = endpoint
        self.stamp: int | None = None
        self.bound = threading.Event()
        self.start()
        assert self.bound.wait(10)

    def run(self) -> None:
        sock = zmq.Context.instance().socket(zmq.SUB)
        sock.setsockopt(zmq.LINGER, 0)
        sock.setsockopt(zmq.SUBSCRIBE, b"ft/wrench")
        sock.bind(self.endpoint)
        self.bound.set()
        try:
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline and self.stamp is None:
                if sock.poll(50):
                    self.stamp = decode(sock.recv_multipart()[1]).header.stamp_ns
        finally:
            sock.close()


def test_topic_pub_on_another_machine_stamps_on_the_graphs_time_base(tmp_path):
    inject = f"ipc://{tmp_path}/sink.in"
    _graph_an_hour_ahead(tmp_path, inject)
    node = _InjectedStamp(inject)
    pub = subprocess.run([sys.executable, "-m", "slipstack.launch.cli", "topic", "pub", "ft/wrench",
                          "{force: [0.0, 0.0, -1.0]}", "--once", "--run-dir", str(tmp_path), "--wait", "30"],
                         capture_output=True, text=True, timeout=90)
    assert pub.returncode == 0 and "joined" not in pub.stderr, pub.stderr
    node.join(60)
    assert node.stamp is not None and abs(node.stamp - (time.monotonic_ns() + HOUR_NS)) < 60 * SECOND_NS  # an hour off on this machine's clock


def test_bag_play_restamp_on_another_machine_stamps_on_the_graphs_time_base(tmp_path):
    recording = tmp_path / "take.mcap"
    with RecordingWriter(recording, wall_minus_monotonic_ns=0) as writer:  # recorded long ago, elsewhere
        for k in range(5):
            msg = encode(Wrench(force=np.array([0.0, 0.0, -1.0]), torque=np.zeros(3)), Header(k, k, k, {}))
            writer.write("ft/wrench", msg, k * 1_000_000)
    inject = f"ipc://{tmp_path}/sink.in"
    _graph_an_hour_ahead(tmp_path, inject)
    node = _InjectedStamp(inject)
    assert play(str(recording), restamp_stamps=True, run_dir=str(tmp_path), wait_s=30.0, echo=lambda line: None) == 5
    node.join(60)
    assert node.stamp is not None and abs(node.stamp - (time.monotonic_ns() + HOUR_NS)) < 60 * SECOND_NS
