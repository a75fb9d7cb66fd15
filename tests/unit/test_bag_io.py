"""Recordings: MCAP round trip, crash tolerance, info numbers, export, replay, playback."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest
from mcap.reader import make_reader

from slipstack.messages import Diagnostics, Header, Wrench, decode, encode
from slipstack.nodes.recording.bag_io import (
    MESSAGE_ENCODING, SCHEMA_ENCODING, RecordingError, RecordingWriter,
    FLOAT_ATOL, FLOAT_RTOL, match_outputs, message_schema, read_recording, recording_info, replay_into, same_output,
    same_value,
)
from slipstack.nodes.demo import Relay, WrenchSource
from slipstack.nodes.recording.export import export_recording
from slipstack.nodes.runtime.inprocess import InProcessExecutor
from slipstack.nodes.recording.player import Playback, Player, PlayerParams

WALL0 = 1_700_000_000_000_000_000  # a wall-clock epoch for log times (ns)
OFFSET = WALL0 - 5_000_000_000     # wall − monotonic of the fake host: monotonic starts at 5 s


def wrench(seq: int, stamp: int, fx: float = 0.0) -> bytes:
    return encode(Wrench(force=np.array([fx, 0.0, 10.0]), torque=np.zeros(3), device_seq=seq,
                         header=Header(stamp, seq, stamp + 1000, {})))


def write_wrenches(path, n: int, *, period_ns: int = 1_000_000, flush_period_s: float = 0.1,
                   close: bool = True) -> RecordingWriter:
    """n wrenches at 1 kHz (monotonic stamps from 5 s), received 50 µs after their stamp."""
    w = RecordingWriter(path, chunk_size=1 << 30, flush_period_s=flush_period_s, wall_minus_monotonic_ns=OFFSET)
    for k in range(n):
        stamp = 5_000_000_000 + k * period_ns
        w.write("ft/wrench", wrench(k, stamp, fx=0.001 * k), stamp + OFFSET + 50_000)
    if close:
        w.close()
    return w


def test_round_trip_keeps_bytes_times_and_sequence(tmp_path):
    path = tmp_path / "a.mcap"
    payloads = [("ft/wrench", wrench(k, 100 + k)) for k in range(5)]
    diag = encode(Diagnostics(node="relay", counters={"x": 1}, header=Header(7, 3, 8, {})))
    with RecordingWriter(path) as w:
        for k, (t, p) in enumerate(payloads):
            w.write(t, p, WALL0 + k)
        w.write("diagnostics", diag, WALL0 + 10)
        w.write("junk", b"\xc1not msgpack", WALL0 + 11)
    frames = list(read_recording(path, tolerant=False))
    assert [(f.topic, f.payload, f.log_time_ns) for f in frames] == (
        [(t, p, WALL0 + k) for k, (t, p) in enumerate(payloads)]
        + [("diagnostics", diag, WALL0 + 10), ("junk", b"\xc1not msgpack", WALL0 + 11)]
    )
    assert [(f.publish_time_ns, f.sequence) for f in frames[:5]] == [(100 + k + 1000, k) for k in range(5)]
    assert [f.topic for f in read_recording(path, ["diagnostics"])] == ["diagnostics"]
    # The file is a normal indexed MCAP: the official reader sees schema, channel and encodings.
    with open(path, "rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics.message_count == 7
        schema, channel, _ = next(reader.iter_messages(topics=["ft/wrench"]))
    assert (schema.encoding, channel.message_encoding) == (SCHEMA_ENCODING, MESSAGE_ENCODING)
    assert channel.metadata == {"type": "slipstack/Wrench", "version": "1"}
    doc = json.loads(schema.data)
    assert doc == message_schema(Wrench)
    assert doc["fields"][0] == {"name": "force", "type": "array", "dtype": "<f8", "shape": [3], "units": "N"}
    assert doc["fields"][2] == {"name": "frame", "type": "str", "bounds": {"enum": ["sensor", "pad"]}, "units": ""}


def test_chunks_close_by_age(tmp_path):
    path = tmp_path / "b.mcap"
    write_wrenches(path, 1000)  # 1 ms apart, flush every 0.1 s: chunks end at 100, 201, …, 908, close
    info = recording_info(path)
    assert info.finished and info.chunk_count == 10 and info.message_count == 1000


def test_kill_loses_only_the_open_chunk(tmp_path):
    path = tmp_path / "c.mcap"
    w = write_wrenches(path, 1000, close=False)  # as after kill -9: no summary, no footer
    snapshot = tmp_path / "killed.mcap"
    shutil.copyfile(path, snapshot)
    frames = list(read_recording(snapshot))
    assert [decode(f.payload).header.seq for f in frames] == list(range(909))  # 9 chunks of 101
    info = recording_info(snapshot)
    assert (info.finished, info.chunk_count, info.message_count) == (False, 9, 909)
    with pytest.raises(RecordingError, match="unfinished"):
        list(read_recording(snapshot, tolerant=False))
    w.close()


@pytest.mark.parametrize("cut_fraction", [0.05, 0.33, 0.5, 0.77, 0.97])
def test_torn_file_reads_a_gapless_prefix(tmp_path, cut_fraction):
    path = tmp_path / "d.mcap"
    write_wrenches(path, 1000)
    data = path.read_bytes()
    torn = tmp_path / "torn.mcap"
    torn.write_bytes(data[: int(len(data) * cut_fraction)])
    seqs = [decode(f.payload).header.seq for f in read_recording(torn)]
    assert seqs == list(range(len(seqs)))          # a prefix, nothing out of order or invented
    assert len(seqs) in {0, *range(101, 1000, 101), 1000}  # whole chunks only (9 × 101, then 91)
    assert not recording_info(torn).finished


def test_info_counts_rates_and_gaps(tmp_path):
    w = RecordingWriter(tmp_path / "f.mcap", wall_minus_monotonic_ns=OFFSET)
    for k in range(1001):
        if k not in (10, 11, 12):
            w.write("ft/wrench", wrench(k, k * 1_000_000), WALL0 + k * 1_000_000)
    for k in range(3):  # two nodes' diagnostics interleaved: separate counters, no gaps
        for node in ("a", "b"):
            w.write("diagnostics", encode(Diagnostics(node=node, header=Header(k, k, k, {}))), WALL0 + k)
    w.close()
    info = recording_info(tmp_path / "f.mcap")
    t = info.topics["ft/wrench"]
    assert (t.count, t.seq_gaps, t.first_seq, t.last_seq) == (998, 3, 0, 1000)
    assert t.rate_hz == pytest.approx(997 / 1.0)
    assert t.types == ("slipstack/Wrench",)
    assert info.topics["diagnostics"].seq_gaps == 0 and info.topics["diagnostics"].count == 6
    assert info.message_count == 1004 and info.duration_s == pytest.approx(1.0)
    assert info.size_bytes == (tmp_path / "f.mcap").stat().st_size


def test_export_json_lists_and_infinities(tmp_path):
    from slipstack.messages import Cor

    path = tmp_path / "g.mcap"
    cor = Cor(case="rotation", p_c=np.array([1e-3, -2e-3]), gamma=float("inf"), header=Header(5, 0, 6, {"c": 4}))
    with RecordingWriter(path) as w:
        w.write("cor", encode(cor), WALL0)
        w.write("junk", b"\x01\x02", WALL0 + 1)
    assert export_recording(path, tmp_path / "g.jsonl", "jsonl") == 1
    line = json.loads((tmp_path / "g.jsonl").read_text())
    assert line["topic"] == "cor" and line["type"] == "slipstack/Cor" and line["log_time_ns"] == WALL0
    assert line["message"]["p_c"] == [1e-3, -2e-3] and line["message"]["gamma"] == "inf"
    # no clock metadata: the offset is estimated as min(log time - pub_ns) = WALL0 - 6
    wall = divmod(5 + WALL0 - 6, 10**9)
    assert line["message"]["header"] == {"stamp_ns": 5, "seq": 0, "pub_ns": 6, "sources": {"c": 4},
                                         "stamp": {"sec": wall[0], "nsec": wall[1]}}
    assert export_recording(path, tmp_path / "g.json.mcap", "mcap-json") == 1
    with open(tmp_path / "g.json.mcap", "rb") as fh:
        schema, channel, msg = next(make_reader(fh).iter_messages())
    assert (schema.encoding, channel.message_encoding) == ("jsonschema", "json")
    assert json.loads(msg.data) == line["message"]
    assert json.loads(schema.data)["properties"]["p_c"]["type"] == "array"


def _live_run(tmp_path, n: int = 300):
    """The demo source → relay in an executor standing in for the live graph, recorded."""
    ex = InProcessExecutor([WrenchSource(), Relay()], start_ns=5_000_000_000)
    ex.run(until_ns=5_000_000_000 + n * 1_000_000)
    path = tmp_path / "live.mcap"
    with RecordingWriter(path, wall_minus_monotonic_ns=OFFSET) as w:
        for t, topic, payload in ex.raw[20:]:  # the recorder joined late: starts mid-stream
            w.write(topic, payload, t + OFFSET + 30_000)
    return path, ex.published["ft/relayed"][20:]


def test_replay_into_reproduces_recorded_outputs(tmp_path):
    path, _ = _live_run(tmp_path)
    recorded = [decode(f.payload) for f in read_recording(path, ["ft/relayed"])]
    for timing in ("receive", "stamp"):
        out = replay_into(Relay(), path, timing=timing)
        result = match_outputs(recorded, out["ft/relayed"])
        assert result.mismatches == [] and result.matched >= len(recorded) - 1, (timing, result)


def test_same_output_names_the_difference():
    a = Wrench(force=np.array([1.0, 2.0, 3.0]), torque=np.zeros(3), header=Header(1, 0, 2, {"w": 1}))
    assert same_output(a, Wrench(force=a.force, torque=a.torque, header=Header(1, 5, 99, {"w": 1}))) is None
    assert same_output(a, Wrench(force=a.force + [0, 0, 1e-6], torque=a.torque, header=a.header)) == "force"
    assert same_output(a, Wrench(force=a.force, torque=a.torque, header=Header(2, 0, 2, {"w": 1}))).startswith(
        "header.stamp_ns")
    assert same_output(a, Wrench(force=a.force, torque=a.torque, status="stale", header=a.header)).startswith("status")
    assert "header.seq" in same_output(a, Wrench(force=a.force, torque=a.torque, header=Header(1, 1, 2, {"w": 1})),
                                       check_seq=True)


def test_same_value_compares_floats_within_the_stated_tolerance_and_the_rest_exactly():
    """A replay on another CPU differs in the last bits of its floats (docs/portability.md §1)."""
    x = 0.01033215058729231  # a COR coordinate (m) as two machines computed it (issue 27)
    assert same_value(x, 0.010332150587292033) and same_value(x, x * (1 + 0.9 * FLOAT_RTOL))
    assert not same_value(x, x * (1 + 2 * FLOAT_RTOL)) and not same_value(1.0, 1.0 + 1e-8)
    assert same_value(1e-17, -3e-18) and not same_value(0.0, 2 * FLOAT_ATOL)  # cancelled to ~0: the floor
    assert same_value(math.nan, math.nan) and not same_value(math.nan, 0.0) and not same_value(math.inf, 1e308)
    assert not same_value(3, 4) and not same_value("stick", "slip") and not same_value(True, False)
    assert same_value(np.float32([1e4, 0.0]), np.float32([1e4 + 2 ** -9, 0.0]))  # float32: 1 ulp of 1e4
    assert not same_value(np.float32([1e4]), np.float32([1e4 + 0.1]))
    assert not same_value(np.array([1.0]), np.array([1.0], dtype=np.float32))  # dtype and shape exact
    assert not same_value(np.array([1, 2]), np.array([1, 3])) and not same_value(np.zeros(2), np.zeros(3))
    assert same_value({"a": (True, 0.5)}, {"a": (True, 0.5 + 1e-17)}) and not same_value({"a": 1}, {"b": 1})
    assert not same_value({"a": (True, 0.5)}, {"a": (False, 0.5)})


def test_playback_timing_rate_and_loop(tmp_path):
    path = tmp_path / "p.mcap"
    write_wrenches(path, 3, period_ns=10_000_000)  # frames received at 0, 10, 20 ms
    frames = list(read_recording(path))
    pb = Playback(frames, rate=2.0)
    assert len(pb.due(1_000)) == 1 and pb.next_due_ns() == 1_000 + 5_000_000
    assert pb.due(1_000 + 4_999_999) == []
    assert len(pb.due(1_000 + 10_000_000)) == 2 and pb.done
    looping = Playback(frames, loop=True)
    assert len(looping.due(0)) == 1
    assert len(looping.due(20_000_000)) == 3 and looping.passes == 1  # the next pass starts at once
    assert len(looping.due(30_000_000)) == 1 and not looping.done


def test_player_node_feeds_a_relay_in_process(tmp_path):
    path = tmp_path / "q.mcap"
    write_wrenches(path, 50)
    player = Player(PlayerParams(path=str(path), restamp=True))
    assert set(player.outputs) == {"ft/wrench"}
    ex = InProcessExecutor([player, Relay()], start_ns=0)
    ex.run(until_ns=60_000_000)
    relayed = ex.published["ft/relayed"]
    assert len(relayed) == 50
    # restamped: the first frame (received 50 µs after its stamp) is stamped 50 µs before the
    # first timer tick at 1 ms; spacing stays 1 ms; seq and bodies unchanged.
    assert [m.header.stamp_ns for m in relayed] == [950_000 + k * 1_000_000 for k in range(50)]
    assert [m.device_seq for m in relayed] == list(range(50))
    plain = InProcessExecutor([Player(PlayerParams(path=str(path))), Relay()])
    plain.run(until_ns=60_000_000)
    assert [m.header.stamp_ns for m in plain.published["ft/relayed"]] == [5_000_000_000 + k * 1_000_000 for k in range(50)]


def test_a_corrupt_chunk_costs_only_its_own_messages(tmp_path):
    """A finished file with one damaged chunk is read past it through its index."""
    path = tmp_path / "e.mcap"
    write_wrenches(path, 1000)  # 10 chunks: 9 of 101 messages, then 91
    with open(path, "rb") as fh:
        third = sorted(make_reader(fh).get_summary().chunk_indexes, key=lambda c: c.chunk_start_offset)[2]
    data = bytearray(path.read_bytes())
    middle = third.chunk_start_offset + third.chunk_length // 2
    data[middle:middle + 16] = bytes(16)
    damaged = tmp_path / "damaged.mcap"
    damaged.write_bytes(bytes(data))
    seqs = [decode(f.payload).header.seq for f in read_recording(damaged)]
    assert seqs == [*range(202), *range(303, 1000)]
    info = recording_info(damaged)
    assert info.message_count == 1000 - 101 and "1 chunk(s) skipped as damaged" in info.damage


@pytest.mark.parametrize("content", [b"", b"hello, not a recording\n"])
def test_an_empty_or_text_file_is_not_a_recording(tmp_path, content):
    path = tmp_path / "x.mcap"
    path.write_bytes(content)
    with pytest.raises(RecordingError, match="empty|not an MCAP recording"):
        recording_info(path)
