"""Declared bounds on message fields: checked on decode, by ``topic pub``, in the
exported schemas; the frame size and socket limits of the transport."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
import zmq

from slipstack.lib.errors import ConfigError, DecodeError
from slipstack.lib.status import SolverStatus
from slipstack.messages import Contact, Cor, Diagnostics, GripCommand, GripState, RigTruth, Slip, TactileFrame, Wrench, decode, encode
from slipstack.messages.codec import MAX_PAYLOAD_BYTES, packb
from slipstack.messages.types import MAX_COUNTERS, MAX_GRIP_FORCE_N, MAX_PITCH_M, MAX_TEXT_LEN, TACTILE_PAIRING
from slipstack.messages.json_schema import json_schema
from slipstack.nodes.recording.bag_io import message_schema
from slipstack.nodes.devices import LinkStatus
from slipstack.nodes.runtime.host import NodeHost
from slipstack.nodes.runtime.node import Node, Output
from slipstack.nodes.tools.topic_pub import build_message
from slipstack.nodes.runtime.transport import make_sub

_HEADER = [10, 0, 11, {}]


def _frame(rows: int, cols: int, n: int, **over) -> bytes:
    """A TactileFrame payload declaring rows × cols with n values per array."""
    body = {"rows": rows, "cols": cols, "pitch_m": 1.25e-3, "pressure_pa": np.zeros(n, np.float32),
            "saturated": np.zeros(n, bool), "dead": np.zeros(n, bool), "device_stamp": -1, "status": "ok"}
    body.update(over)
    return packb(["slipstack/TactileFrame", 1, _HEADER, list(body.values())])


def _payload(cls, **over) -> bytes:
    """``cls``'s default message with fields replaced on the wire (bypassing the constructor)."""
    msg = cls()
    body = [over.get(n, getattr(msg, n)) for n in cls._body_fields]
    return packb([cls.TYPE, cls.VERSION, _HEADER, body])


def test_a_frame_whose_arrays_disagree_with_rows_times_cols_is_rejected_naming_the_field():
    with pytest.raises(DecodeError, match=r"TactileFrame\.pressure_pa: expected rows\*cols = 256 values, got 0"):
        decode(_frame(16, 16, 0))
    with pytest.raises(DecodeError, match=r"TactileFrame\.saturated: expected rows\*cols = 6 values, got 5"):
        decode(_frame(2, 3, 6, saturated=np.zeros(5, bool)))
    assert decode(_frame(2, 3, 6)).pressure_pa.shape == (6,)


def test_the_issue_s_resource_bomb_is_rejected_by_its_declared_size():
    """102 bytes declaring 5000 × 5000 taxels with empty arrays."""
    with pytest.raises(DecodeError, match=r"TactileFrame\.rows: must be >= 1 and <= 256, got 5000"):
        decode(_frame(5000, 5000, 0))
    with pytest.raises(DecodeError, match=r"TactileFrame\.rows: must be >= 1"):
        decode(_frame(0, 16, 0))


def test_a_contact_s_per_taxel_arrays_match_its_pad_and_an_ft_only_contact_has_none():
    with pytest.raises(DecodeError, match=r"Contact\.phi: expected rows\*cols = 4 values, got 3"):
        decode(_payload(Contact, rows=2, cols=2, phi=np.zeros(3), mask=np.zeros(4, bool)))
    ft_only = decode(_payload(Contact, rows=0, cols=0, pitch_m=0.0, phi=np.zeros(0), mask=np.zeros(0, bool)))
    assert ft_only.phi.size == 0


@pytest.mark.parametrize(("cls", "field", "value", "why"), [
    (Wrench, "status", "x" * 10_000, "at most 64 characters, got 10000"),
    (Wrench, "status", "bogus", "must be one of"),
    (Wrench, "frame", "moon", "must be one of pad, sensor; got 'moon'"),
    (Slip, "state", "sliding", "must be one of"),
    (Slip, "method", "exact; rm -rf", "must be one of"),
    (Cor, "case", "spin", "must be one of"),
    (GripCommand, "f_n_desired", 1e300, "must be >= 0 and <= 1000, got 1e+300"),
    (GripCommand, "f_n_desired", -5.0, "must be >= 0"),
    (GripCommand, "reason", "r" * 65, "at most 64 characters"),
    (TactileFrame, "pitch_m", -1.0, "must be > 0"),
    (Diagnostics, "last_error", "e" * (MAX_TEXT_LEN + 1), f"at most {MAX_TEXT_LEN} characters"),
    (Diagnostics, "counters", {f"c{i}": i for i in range(MAX_COUNTERS + 1)}, f"at most {MAX_COUNTERS} entries"),
    (Slip, "verdicts", {f"m{i}": [True, 1.0] for i in range(33)}, "at most 32 entries"),
    (Slip, "verdicts", {"k" * 129: [True, 1.0]}, "keys are strings of at most 128 characters"),
])
def test_values_outside_the_declared_bounds_are_rejected_naming_the_field(cls, field, value, why):
    over = {field: value}
    if cls is TactileFrame:
        over |= {"pressure_pa": np.zeros(256, np.float32), "saturated": np.zeros(256, bool), "dead": np.zeros(256, bool)}
    with pytest.raises(DecodeError) as err:
        decode(_payload(cls, **over))
    assert f"{cls.TYPE}.{field}:" in str(err.value) and why in str(err.value)
    assert len(str(err.value)) < 600  # a huge value is never echoed back (the list of choices may be long)


_PAD_ARRAYS = {"pressure_pa": np.zeros(256, np.float32), "saturated": np.zeros(256, bool), "dead": np.zeros(256, bool)}
_NO_PAD = {"rows": 0, "cols": 0, "phi": np.zeros(0), "mask": np.zeros(0, bool)}  # an F/T-only contact


@pytest.mark.parametrize(("cls", "field", "legal", "illegal"), [
    (TactileFrame, "pitch_m", [math.ulp(0.0), MAX_PITCH_M], [0.0, -0.0, math.nextafter(MAX_PITCH_M, math.inf)]),
    (Contact, "pitch_m", [0.0, MAX_PITCH_M], [-math.ulp(0.0), math.nextafter(MAX_PITCH_M, math.inf)]),
    (GripCommand, "f_n_desired", [0.0, MAX_GRIP_FORCE_N], [-math.ulp(0.0), math.nextafter(MAX_GRIP_FORCE_N, math.inf)]),
    (GripState, "f_n_command", [0.0, MAX_GRIP_FORCE_N], [-math.ulp(0.0), math.nextafter(MAX_GRIP_FORCE_N, math.inf)]),
    (GripState, "commanded_by", ["t" * 64], ["t" * 65]),
    (Diagnostics, "node", ["n" * 128], ["n" * 129]),
])
def test_each_bound_admits_its_edge_and_refuses_the_next_float_past_it(cls, field, legal, illegal):
    """The edge values themselves, not far-off ones: > 0 refuses 0, <= 1000 admits 1000."""
    arrays = _PAD_ARRAYS if cls is TactileFrame else _NO_PAD if cls is Contact else {}
    for value in legal:
        assert getattr(decode(_payload(cls, **arrays, **{field: value})), field) == value
    for value in illegal:
        with pytest.raises(DecodeError, match=rf"{cls.TYPE}\.{field}:"):
            decode(_payload(cls, **arrays, **{field: value}))


def _earlier(m: int) -> dict:
    """A contact's fields for ``m`` earlier F/T samples."""
    return {"earlier_samples": m, "earlier_stamp_ns": np.arange(m, dtype=np.int64), "earlier_status": np.zeros(m, np.uint8),
            **{f: np.zeros(m) for f in ("earlier_f_n", "earlier_f_tx", "earlier_f_ty", "earlier_tau")}}


def test_the_size_limits_are_the_wire_contracts_numbers():
    """Written as numbers, not as the constants: recordings and the nodes of another machine are
    written to 4096 characters of text, 4096 counters, 63 earlier samples and a 0.1 m pitch; each
    limit passes, one more is refused."""
    assert decode(_payload(TactileFrame, **_PAD_ARRAYS, pitch_m=0.1)).pitch_m == 0.1
    with pytest.raises(DecodeError, match=r"TactileFrame\.pitch_m:"):
        decode(_payload(TactileFrame, **_PAD_ARRAYS, pitch_m=math.nextafter(0.1, 1.0)))
    assert len(decode(_payload(Diagnostics, status="s" * 4096)).status) == 4096
    assert len(decode(_payload(Diagnostics, counters={f"c{i}": 1.0 for i in range(4096)})).counters) == 4096
    assert decode(_payload(Contact, **_NO_PAD, **_earlier(63))).earlier_f_n.shape == (63,)
    for cls, over in [(Diagnostics, {"status": "s" * 4097}), (Diagnostics, {"last_error": "e" * 4097}),
                      (Diagnostics, {"counters": {f"c{i}": 1.0 for i in range(4097)}}), (Contact, {**_NO_PAD, **_earlier(64)})]:
        with pytest.raises(DecodeError, match=rf"{cls.TYPE}\."):
            decode(_payload(cls, **over))


def test_a_message_published_with_only_some_fields_carries_no_load_and_no_device_time():
    """What `topic pub` builds from a partial mapping: the fields left out are no load (0 N,
    0 N·m, no area, no pairing offset) and no device clock (-1), never a made-up value."""
    contact = build_message(Contact, {"rows": 0, "cols": 0})  # an F/T-only contact, every load left out
    assert build_message(Contact, {"phi": [0.0] * 256, "mask": [False] * 256}).has_tactile  # the default pad's, paired
    assert (contact.f_n, contact.tau, *contact.f_t, contact.area_m2, contact.pair_offset_ns) == (0.0,) * 5 + (0,)
    pad = {"rows": 1, "cols": 1, "pressure_pa": [0.0], "saturated": [False], "dead": [False]}
    assert build_message(TactileFrame, pad).device_stamp == -1
    cor = build_message(Cor, {"case": "none"})
    assert (cor.torque_capacity, cor.load_torque, cor.gamma, cor.iterations, cor.residual, cor.converged) == (0.0,) * 5 + (False,)
    slip = build_message(Slip, {"state": "no-contact"})
    assert (slip.margin, slip.gamma, slip.f_n, slip.tau, *slip.f_t, slip.p_c_valid) == (0.0,) * 6 + (False,)
    assert build_message(GripCommand, {"law": "manual"}).f_n_desired == 0.0
    assert build_message(GripState, {"mode": "initial"}).f_n_command == 0.0
    truth = build_message(RigTruth, {})
    assert (truth.x, truth.y, truth.theta, truth.vx, truth.vy, truth.omega, truth.slip_distance_m, truth.slip_angle_rad,
            truth.f_n_applied, truth.f_n_command, truth.sliding_fraction, truth.load_tau) == (0.0,) * 12
    assert not truth.gross_slip and not truth.cor_valid


def test_a_load_no_friction_can_hold_crosses_the_wire():
    """gamma = +inf (docs: a load no friction can hold), its margin 1 - gamma = -inf and a
    solver's residual of +inf decode as sent; NaN stays refused."""
    slip = decode(_payload(Slip, gamma=math.inf, margin=-math.inf))
    assert (slip.gamma, slip.margin) == (math.inf, -math.inf)
    cor = decode(_payload(Cor, gamma=math.inf, residual=math.inf))
    assert (cor.gamma, cor.residual) == (math.inf, math.inf)
    with pytest.raises(DecodeError, match=r"Slip\.gamma:"):
        decode(_payload(Slip, gamma=math.nan))


def test_a_string_without_a_limit_of_its_own_holds_256_characters():
    """Wrench.frame declares only its choices: the default limit applies, 256 characters."""
    with pytest.raises(DecodeError, match="must be one of"):
        decode(_payload(Wrench, frame="f" * 256))
    with pytest.raises(DecodeError, match="at most 256 characters, got 257"):
        decode(_payload(Wrench, frame="f" * 257))


def test_a_refused_string_is_quoted_whole_up_to_40_characters():
    for n, shown in [(40, repr("f" * 40)), (41, repr("f" * 40) + "… (41 characters)")]:
        with pytest.raises(DecodeError) as err:
            decode(_payload(Wrench, frame="f" * n))
        assert str(err.value).endswith(f"got {shown}")


def test_the_full_check_admits_every_edge_the_fast_test_admits():
    """An int where a float is declared fails the generated fast test (strict about types);
    the full check then converts it, and must admit the other fields at their edges."""
    slip = decode(_payload(Slip, margin=1, verdicts={"v" * 128: [True, 0.5]}))
    assert type(slip.margin) is float and slip.margin == 1.0 and list(slip.verdicts["v" * 128]) == [True, 0.5]
    grip = decode(_payload(GripState, f_n_command=5, commanded_by="t" * 64))
    assert type(grip.f_n_command) is float and grip.commanded_by == "t" * 64


def test_a_10_mb_string_is_refused_by_the_decoder_without_echoing_it():
    with pytest.raises(DecodeError) as err:
        decode(_payload(Wrench, status="x" * 10_000_000))
    assert len(str(err.value)) < 300


def test_every_status_the_code_produces_is_accepted():
    produced = ["ok", "taring", "device-status 0x0002", "device-status 0x8000ffff",
                *(s.value for s in LinkStatus), *(s.value for s in SolverStatus),
                *(f"tactile_{p}" for p in TACTILE_PAIRING if p != "ok")]  # the slip detector's, tactile_off too
    for status in produced:
        assert decode(_payload(Wrench, status=status)).status == status
        assert decode(_payload(Slip, status=status)).status == status


def test_header_stamps_and_sources_are_bounded():
    for header, why in [([-1, 0, 0, {}], "stamp_ns: must be within"), ([0, 2**63, 0, {}], "seq: must be within"),
                        ([0, 0, 0, {f"s{i}": 1 for i in range(33)}], "sources: at most 32 entries"),
                        ([0, 0, 0, {"s": -5}], "sources: expected a map")]:
        with pytest.raises(DecodeError, match=why):
            decode(packb(["slipstack/GripCommand", 1, header, [1.0, "", "nominal"]]))


def test_oversized_msgpack_items_are_refused_before_they_are_built():
    with pytest.raises(DecodeError, match="not a valid MessagePack frame"):
        decode(packb(["slipstack/GripCommand", 1, _HEADER, [1.0, "", "nominal", [None] * 100_000]]))


def test_topic_pub_refuses_values_outside_the_bounds_naming_the_field():
    for values, why in [({"f_n_desired": 1e300}, "f_n_desired: must be"), ({"f_n_desired": -5}, "f_n_desired"),
                        ({"status": "bogus"}, "Wrench.status"), ({"frame": "moon"}, "Wrench.frame"),
                        ({"pressure_pa": [1, 2, 3]}, "TactileFrame.pressure_pa: expected rows*cols = 256 values, got 3"),
                        ({"pitch_m": -1, "pressure_pa": [0] * 256, "saturated": [0] * 256, "dead": [0] * 256},
                         "TactileFrame.pitch_m")]:
        cls = GripCommand if "f_n_desired" in values else TactileFrame if "pressure_pa" in values else Wrench
        with pytest.raises(ConfigError, match=why.replace("*", r"\*")):
            build_message(cls, values)
    assert build_message(GripCommand, {"f_n_desired": 12.0, "law": "manual"}).f_n_desired == 12.0


def test_exported_schemas_carry_the_bounds():
    grip = json_schema(GripCommand)["properties"]["f_n_desired"]
    assert grip["minimum"] == 0.0 and grip["maximum"] == 1000.0
    assert json_schema(Wrench)["properties"]["frame"]["enum"] == ["sensor", "pad"]
    assert json_schema(Wrench)["properties"]["status"]["maxLength"] == 64
    assert json_schema(Diagnostics)["properties"]["counters"]["maxProperties"] == MAX_COUNTERS
    rows = {r["name"]: r for r in message_schema(TactileFrame)["fields"]}
    assert rows["rows"]["bounds"] == {"minimum": 1, "maximum": 256}
    assert rows["pressure_pa"]["shape"] == ["rows*cols"]


def test_the_largest_legal_frames_fit_the_transport_limit_with_headroom():
    n = 256 * 256
    biggest = [
        Contact(rows=256, cols=256, phi=np.ones(n), mask=np.ones(n, bool)),
        TactileFrame(rows=256, cols=256, pressure_pa=np.ones(n, np.float32), saturated=np.ones(n, bool),
                     dead=np.ones(n, bool), status="device-status 0x8000ffff"),
        Diagnostics(node="n" * 128, status="s" * MAX_TEXT_LEN, last_error="é" * MAX_TEXT_LEN,
                    counters={f"{'k' * 120}{i:05d}": 1.5 for i in range(MAX_COUNTERS)}),
    ]
    for msg in biggest:
        payload = encode(msg)
        assert len(payload) < 0.5 * MAX_PAYLOAD_BYTES, type(msg).__name__
        decode(payload)


class _Counting(Node):
    name = "counting"


class _Publishing(Node):
    name = "publishing"
    outputs = {"out": Output("diagnostics", Diagnostics)}


def test_diagnostics_stay_within_their_bounds_whatever_a_node_counts_or_says():
    host = NodeHost(_Counting(), lambda: 1, lambda topic, payload: None)
    for i in range(MAX_COUNTERS + 500):
        host.count(f"device.thing{i}")
    host.set_status("error", "d" * 100_000)
    host.last_error = "e" * 100_000
    diag = decode(host.diagnostics(), Diagnostics)
    assert len(diag.counters) <= MAX_COUNTERS and diag.counters["counters.overflow"] >= 500
    assert len(diag.status) <= MAX_TEXT_LEN and len(diag.last_error) <= MAX_TEXT_LEN


def test_a_bound_subscriber_drops_a_peer_that_sends_an_oversized_frame_and_keeps_the_others():
    """ZeroMQ's maximum message size on an injection-style socket (bound SUB): a
    3 MB frame never reaches the node, the sender is cut off, other peers go on."""
    ctx = zmq.Context.instance()
    sub = make_sub(ctx, [], "t")
    port = sub.bind_to_random_port("tcp://127.0.0.1")
    peers = []
    try:
        for _ in range(2):
            peer = ctx.socket(zmq.XPUB)
            peer.setsockopt(zmq.LINGER, 0)
            peer.connect(f"tcp://127.0.0.1:{port}")
            deadline = time.monotonic() + 10
            while not peer.poll(10) and time.monotonic() < deadline:
                sub.poll(0)  # a socket attaches its new peers (and sends them its subscriptions) when used
            assert peer.recv() == b"\x01t"
            peers.append(peer)
        bad, good = peers
        bad.send_multipart([b"t", b"x" * (3 << 20)])
        got: list[bytes] = []
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline and b"good" not in got:
            bad.send_multipart([b"t", b"bad"])
            good.send_multipart([b"t", b"good"])
            if sub.poll(50):
                got.append(sub.recv_multipart()[1])
        assert b"good" in got
        assert all(len(p) <= MAX_PAYLOAD_BYTES for p in got)
    finally:
        for sock in (sub, *peers):
            sock.close()


def test_a_node_never_publishes_a_frame_over_the_transport_limit():
    sent = []
    host = NodeHost(_Publishing(), lambda: 1, lambda topic, payload: sent.append(payload))
    n = 256 * 256
    host.publish("out", Diagnostics(counters={}, last_error="x"), stamp_ns=1)
    host.publish("out", Diagnostics(counters={f"{'k' * 120}{i:05d}": 1.5 for i in range(3 * n)}), stamp_ns=2)
    assert len(sent) == 1
    assert host.counters["out.diagnostics.oversized"] == 1
    assert "diagnostics: a frame of" in host.last_error and "not sent" in host.last_error


def test_the_unpackers_own_limits_are_their_documented_numbers():
    """msgpack's limits (docs: twice what a field allows, so the field's check names it first),
    written as numbers: 2 * 4 * 4096 bytes of text, no raw bytes, lists of 1024, maps of
    2 * 4096; one more is a DecodeError before any field is looked at. The frame: 2 MiB."""
    from slipstack.messages.codec import unpackb

    assert MAX_PAYLOAD_BYTES == 2 * 1024 * 1024
    fits = [packb("s" * 32768), packb(list(range(1024))), packb({f"k{i}": 0 for i in range(8192)})]
    assert [len(x) for x in map(unpackb, fits)] == [32768, 1024, 8192]
    for over in (packb("s" * 32769), packb(b"x"), packb(list(range(1025))), packb({f"k{i}": 0 for i in range(8193)})):
        with pytest.raises(DecodeError, match="payload: not a valid MessagePack frame"):
            unpackb(over)
