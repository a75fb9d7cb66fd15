"""``bag record`` and ``bag play`` run the recorder and player nodes: against a real
ZeroMQ publisher listed in a hand-made graph, in this process."""

from __future__ import annotations

import json
import threading
import time

import numpy as np
import pytest
import zmq

from slipstack.lib.errors import ConfigError
from slipstack.messages import Header, Wrench, decode, encode
from slipstack.nodes.recording.bag_io import RecordingWriter, read_recording
from slipstack.nodes.recording.bag_io import clock_offset_ns as recording_clock_offset_ns
from slipstack.nodes.recording.player import play
from slipstack.nodes.recording.recorder import record


def _graph(run_dir, pub: str) -> None:
    node = {"type": "wrench_source", "pub": pub, "outputs": ["ft/wrench", "diagnostics"]}
    (run_dir / "graph.json").write_text(json.dumps({"nodes": {"src": node}}))


def _publish_until(stop: threading.Event, endpoint: str) -> None:
    sock = zmq.Context.instance().socket(zmq.PUB)
    sock.bind(endpoint)
    seq = 0
    try:
        while not stop.wait(0.002):
            msg = Wrench(force=np.array([0.0, 0.0, -float(seq)]), torque=np.zeros(3))
            sock.send_multipart([b"ft/wrench", encode(msg, Header(seq, seq, seq, {}))])
            seq += 1
    finally:
        sock.close(linger=0)


def test_bag_record_runs_the_recorder_node_until_its_duration(tmp_path, capsys):
    endpoint = f"ipc://{tmp_path}/src.pub"
    _graph(tmp_path, endpoint)
    stop = threading.Event()
    source = threading.Thread(target=_publish_until, args=(stop, endpoint), daemon=True)
    source.start()
    out = tmp_path / "take.mcap"
    try:
        n = record(out, ["ft/wrench"], str(tmp_path), duration_s=0.5)
    finally:
        stop.set()
        source.join(5)
    frames = list(read_recording(out, tolerant=False))  # finished: summary and indexes written
    seqs = [decode(f.payload).header.seq for f in frames]
    assert n == len(frames) > 0 and seqs == sorted(seqs) and {f.topic for f in frames} == {"ft/wrench"}
    assert capsys.readouterr().out.splitlines()[0] == str(out)


def test_bag_record_refuses_an_existing_output_and_keeps_it(tmp_path):
    _graph(tmp_path, f"ipc://{tmp_path}/src.pub")
    existing = tmp_path / "take1.mcap"
    existing.write_bytes(b"precious")
    with pytest.raises(ConfigError, match=r"take1.mcap exists; choose another -o path or delete it"):
        record(existing, None, str(tmp_path), duration_s=0.1)
    assert existing.read_bytes() == b"precious"


def test_bag_play_runs_the_player_node_and_stops_after_the_last_frame(tmp_path):
    rec = tmp_path / "in.mcap"
    with RecordingWriter(rec, wall_minus_monotonic_ns=0) as w:
        for k in range(50):
            msg = Wrench(force=np.array([0.0, 0.0, -1.0]), torque=np.zeros(3))
            w.write("ft/wrench", encode(msg, Header(k * 1_000_000, k, k * 1_000_000, {})), k * 1_000_000)
    # the graph has a recorder: the player waits for its all-topic subscription (this SUB)
    (tmp_path / "graph.json").write_text(json.dumps({"nodes": {"rec": {"type": "recorder", "outputs": []}}}))
    endpoint = f"ipc://{tmp_path}/play.pub"
    sub = zmq.Context.instance().socket(zmq.SUB)
    sub.setsockopt(zmq.SUBSCRIBE, b"")
    sub.connect(endpoint)
    lines: list[str] = []
    try:
        sent = play(str(rec), rate=10.0, endpoint=endpoint, run_dir=str(tmp_path), wait_s=30.0, echo=lines.append)
        got = []
        while sub.poll(2000):
            got.append(decode(sub.recv_multipart()[1]).header.seq)
            if len(got) == 50:
                break
    finally:
        sub.close(linger=0)
    assert sent == 50 and lines[-1] == "played 50 frames (0 loops)"
    assert got == list(range(50))


def test_bag_record_on_another_machine_puts_its_recording_on_the_graphs_time_base(tmp_path):
    """A graph whose nodes on this machine run an hour ahead of its clock (the first
    machine's time base): the recording's clock record maps log times onto that base."""
    endpoint = f"ipc://{tmp_path}/src.pub"
    _graph(tmp_path, endpoint)
    graph = json.loads((tmp_path / "graph.json").read_text())
    offset = 3_600 * 10**9
    graph["machine"] = {"name": "workstation", "hosts": {}, "clock_offset_ns": offset, "peers": {}}
    (tmp_path / "graph.json").write_text(json.dumps(graph))
    out = tmp_path / "take.mcap"
    record(out, ["ft/wrench"], str(tmp_path), duration_s=0.1)
    expected = time.time_ns() - time.monotonic_ns() - offset  # wall time minus the graph's clock
    assert abs(recording_clock_offset_ns(out) - expected) < 10**9  # an hour off without the offset
