"""Message validation: each error names the field."""

from __future__ import annotations

import numpy as np
import pytest

from slipstack.lib.errors import DecodeError
from slipstack.messages import Header, TactileFrame, Wrench, decode, encode
from slipstack.messages.codec import packb


def _wrench_body(**over):
    body = {"force": np.array([1.0, 2.0, 3.0]), "torque": np.zeros(3), "frame": "sensor", "device_seq": 7, "status": "ok"}
    body.update(over)
    return packb(["slipstack/Wrench", 1, [10, 2, 11, {}], list(body.values())])


def test_wrench_round_trip_is_compact_and_exact():
    w = Wrench(force=np.array([0.1, -2.5, 9.81]), torque=np.array([1e-3, 0, -1e-3]), header=Header(5, 1, 6, {"ft": 5}))
    payload = encode(w)
    assert len(payload) < 130  # arrays as raw bytes, not lists of floats
    back = decode(payload, Wrench)
    assert np.array_equal(back.force, w.force) and back.header == w.header


@pytest.mark.parametrize(
    ("over", "field", "why"),
    [
        ({"force": np.array([1.0, 2.0])}, "slipstack/Wrench.force", "shape"),
        ({"force": np.array([1.0, np.nan, 0.0])}, "slipstack/Wrench.force", "NaN"),
        ({"torque": [0.0, 0.0, 0.0]}, "slipstack/Wrench.torque", "expected an array"),
        ({"device_seq": 1.5}, "slipstack/Wrench.device_seq", "expected int"),
        ({"status": 3}, "slipstack/Wrench.status", "expected str"),
        ({"force": np.array([1, 2, 3], dtype=np.int32)}, "slipstack/Wrench.force", "dtype"),
    ],
)
def test_bad_fields_are_named(over, field, why):
    with pytest.raises(DecodeError) as err:
        decode(_wrench_body(**over), Wrench)
    assert field in str(err.value) and why in str(err.value)


def test_wrong_type_and_version_are_rejected():
    t = TactileFrame(pressure_pa=np.zeros(4, np.float32), saturated=np.zeros(4, bool), dead=np.zeros(4, bool), rows=2, cols=2)
    with pytest.raises(DecodeError, match="expected 'slipstack/Wrench'"):
        decode(encode(t), Wrench)
    with pytest.raises(DecodeError, match="version"):
        decode(packb(["slipstack/Wrench", 99, [0, 0, 0, {}], []]), Wrench)
    with pytest.raises(DecodeError, match="missing"):
        decode(packb(["slipstack/Wrench", 1, [0, 0, 0, {}], [np.zeros(3)]]), Wrench)


def test_tactile_frame_of_256_taxels_is_about_1_2_kb():
    t = TactileFrame(pressure_pa=np.ones(256, np.float32), saturated=np.zeros(256, bool), dead=np.zeros(256, bool))
    assert 1200 < len(encode(t)) < 1700


@pytest.mark.parametrize("layout", ["big-endian", "strided", "fortran", "reversed"])
def test_an_array_in_any_memory_layout_encodes_as_its_little_endian_c_order_copy(layout):
    """The encoder caches each array's extension header by dtype and shape: an array whose bytes
    are not little-endian C order must still travel as exactly those values."""
    values = np.arange(12, dtype="<f8").reshape(3, 4) * 0.5 - 1.0
    given = {"big-endian": values.astype(">f8"), "strided": np.arange(24.0).reshape(3, 8)[:, ::2] * 0.5 - 1.0,
             "fortran": np.asfortranarray(values), "reversed": values[:, ::-1]}[layout]
    expected = packb(np.ascontiguousarray(given, dtype="<f8"))
    packb(values)  # the header of (<f8, (3, 4)) is cached before the odd layout is packed
    assert packb(given) == expected
    back = decode(_wrench_body(force=given[0, :3]), Wrench)
    assert np.array_equal(back.force, np.asarray(given[0, :3], dtype="<f8"))


def test_an_array_of_a_dtype_that_cannot_be_sent_is_refused_every_time():
    for _ in range(2):  # a refused dtype is never cached as sendable
        with pytest.raises(TypeError, match="cannot be sent"):
            packb(np.zeros(3, dtype=np.complex128))


def _as_the_nodes_publish_them() -> list:
    """One message of each type of the stack, with the value types its node gives it (a
    ``str`` enumeration member for a slip state, verdicts as lists, integer counters)."""
    from slipstack.lib.status import SlipState
    from slipstack.messages import Contact, Cor, Diagnostics, GripCommand, RigTruth, Slip

    mask = np.arange(256) % 3 == 0
    return [
        Wrench(force=np.array([0.1, 0.0, -2.7]), torque=np.zeros(3), frame="pad", device_seq=4, status="ok"),
        TactileFrame(pressure_pa=np.full(256, 2e4, np.float32), saturated=np.zeros(256, bool), dead=np.zeros(256, bool)),
        Contact(phi=np.where(mask, 0.01, 0.0), f_n=2.7, f_t=np.array([0.1, 0.0]), cop=np.zeros(2), area_m2=1e-4, mask=mask),
        Cor(case="rotation", p_c=np.array([1e-3, 0.0]), gamma=float("inf"), residual=1e-9, status="converged"),
        Slip(state=SlipState.STICK, margin=0.98, method="exact", verdicts={"exact": [True, 0.98], "coulomb": [False, 1]},
             f_t=np.zeros(2), p_c=np.zeros(2)),
        GripCommand(f_n_desired=3.5, law="tactile14", reason="slip"),
        RigTruth(x=1e-5, cor=np.zeros(2), load_f_t=np.array([0.1, 0.0]), f_n_applied=2.7),
        Diagnostics(node="fusion", counters={"in.ft/wrench.received": 12, "handler.p50_us": 40.5}),
    ]


@pytest.mark.parametrize("msg", _as_the_nodes_publish_them(), ids=lambda m: m.TYPE)
def test_a_message_as_its_node_publishes_it_passes_the_one_pass_accept_test_and_decodes_the_same(msg):
    """The generated accept test (messages/generated.py) must take what the nodes publish (else every
    message goes the slow field-by-field way), and a frame decoded on that path equals the original."""
    assert type(msg)._accept(msg.__dict__)
    back = decode(encode(msg), type(msg))
    assert type(back)._accept(back.__dict__)
    for name in msg._body_fields:
        a, b = getattr(msg, name), getattr(back, name)
        assert np.array_equal(a, b) if isinstance(a, np.ndarray) else a == b, name


def test_a_message_that_cannot_be_encoded_leaves_the_next_frame_intact():
    """Each thread reuses one packer: a frame refused half-way must not leave bytes in it."""
    import msgpack

    from slipstack.messages.codec import pack_array

    good = Wrench(force=np.array([1.0, 2.0, 3.0]), torque=np.zeros(3), header=Header(5, 1, 6, {"ft": 5}))
    bad = Wrench(force=np.array([1.0, 2.0, 3.0]), torque=np.zeros(3, np.complex128))
    huge = Wrench(force=np.zeros(3), torque=np.zeros(3), device_seq=2**70)
    with pytest.raises(TypeError, match="cannot be sent"):
        encode(bad)
    with pytest.raises(TypeError, match="cannot encode int"):  # beyond 64 bits: msgpack hands it to the fallback
        encode(huge)
    expected = msgpack.packb(["slipstack/Wrench", 1, [5, 1, 6, {"ft": 5}],
                              [pack_array(good.force), pack_array(good.torque), "sensor", -1, "ok"]], use_bin_type=True)
    assert encode(good) == expected
    large = TactileFrame(rows=256, cols=256, pressure_pa=np.ones(65536, np.float32), saturated=np.zeros(65536, bool),
                         dead=np.zeros(65536, bool))
    assert decode(encode(large), TactileFrame).pressure_pa.sum() == 65536  # a large frame: its packer is let go
    assert encode(good) == expected


def test_threads_encoding_at_once_each_get_their_own_frames():
    import threading

    msgs = [Wrench(force=np.full(3, float(k)), torque=np.zeros(3), device_seq=k) for k in range(4)]
    expected = [encode(m) for m in msgs]
    wrong = []

    def encode_many(k: int) -> None:
        for _ in range(3000):
            if encode(msgs[k]) != expected[k]:
                wrong.append(k)

    threads = [threading.Thread(target=encode_many, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not wrong


def test_a_message_is_built_as_its_dataclass_declares_it():
    """Message types store their fields through the instance dict (messages/generated.py compile_init): same
    signature, defaults and fresh default factories as the dataclass ``__init__``, still frozen."""
    import dataclasses

    from slipstack.messages import Contact, GripCommand, registry

    for cls in registry.values():
        built = cls()
        for f in dataclasses.fields(cls):
            want = f.default if f.default is not dataclasses.MISSING else f.default_factory()
            got = getattr(built, f.name)
            assert (np.array_equal(got, want) and got.dtype == want.dtype) if isinstance(want, np.ndarray) else got == want
    a, b = Contact(), Contact()
    assert a.phi is not b.phi and a.header is not b.header and a.header.sources is not b.header.sources
    g = GripCommand(2.0, "law")
    assert (g.f_n_desired, g.law, g.reason) == (2.0, "law", "nominal")
    assert dataclasses.replace(g, reason="slip") == GripCommand(f_n_desired=2.0, law="law", reason="slip")
    with pytest.raises(dataclasses.FrozenInstanceError):
        g.law = "other"
    with pytest.raises(TypeError):
        GripCommand(1.0, "a", "b", Header())  # the header is keyword-only
    with pytest.raises(TypeError):
        GripCommand(force=1.0)


def test_a_large_frame_that_cannot_be_encoded_leaves_no_grown_buffer_behind():
    """A thread's packer whose buffer a large frame grew is let go even when that frame's
    encoding fails half-way (after its 32 MB array, on a value it cannot encode): the
    thread keeps none of the ~64 MB the buffer grew to."""
    import gc
    import tracemalloc

    from slipstack.messages.codec import packb

    large = np.zeros(4_000_000)  # 32 MB
    packb([1])  # this thread's packer exists before the measurement
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        with pytest.raises(TypeError, match="cannot encode object"):
            packb([large, object()])
        gc.collect()
        held = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert held < 1_000_000, f"{held / 1e6:.1f} MB kept after a failed large frame"
    assert packb([1.5, "z"]) == b"\x92\xcb?\xf8\x00\x00\x00\x00\x00\x00\xa1z"  # the next frame starts clean
