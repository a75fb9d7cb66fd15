"""Codecs of lib/protocols, the deframer, calibration and back-end URL parsing."""

from __future__ import annotations

import numpy as np
import pytest

from slipstack.lib.calibration import Calibration, load_calibration, save_calibration
from slipstack.lib.errors import ConfigError
from slipstack.lib.protocols import ati_rdt, bota, dsacon32, m1616, robotiq
from slipstack.lib.protocols.framed import FramedFormat, decode_frame, encode_frame
from slipstack.lib.protocols.stream import Deframer
from slipstack.nodes.devices.backends import (
    BotaBackend, Dsacon32Backend, FramedBackend, RdtBackend, RobotiqBackend, backend_from_url,
)

H = bytes.fromhex

# ---------------------------------------------------------------- Robotiq


def test_robotiq_commands_match_protocol_vectors() -> None:
    assert robotiq.START_STREAM_REQUEST == H("09 10 01 9A 00 01 02 02 00 CD CA")
    assert robotiq.START_STREAM_ECHO == H("09 10 01 9A 00 01 21 52")
    assert robotiq.encode_frame([0, 0, 0], [0, 0, 0]) == H("20 4E") + bytes(12) + H("62 AF")


def test_robotiq_frame_scaling_and_round_trip() -> None:
    frame = robotiq.encode_frame([1.0, -2.5, 327.67], [0.001, -0.5, 32.767])
    # Fx = 100 counts = 0x0064, Fy = -250 = 0xFF06 (little-endian on the wire)
    assert frame[2:6] == H("64 00 06 FF")
    d = robotiq.decode_frame(frame)
    np.testing.assert_allclose(d.force_n, [1.0, -2.5, 327.67])
    np.testing.assert_allclose(d.torque_nm, [0.001, -0.5, 32.767])
    clipped = robotiq.decode_frame(robotiq.encode_frame([1e6, 0, 0], [0, 0, -1e6]))
    assert clipped.force_n[0] == 327.67 and clipped.torque_nm[2] == -32.768


def test_robotiq_rejects_corrupt_frames() -> None:
    frame = bytearray(robotiq.encode_frame([1, 2, 3], [0.1, 0.2, 0.3]))
    frame[5] ^= 0x10
    assert robotiq.decode_frame(bytes(frame)) is None
    assert robotiq.decode_frame(bytes(frame[:15])) is None


def test_robotiq_write_request_codec_parses_start_request() -> None:
    (req,) = Deframer(robotiq.WriteRequestCodec()).feed(b"\xff" * 5 + robotiq.START_STREAM_REQUEST)
    assert req == robotiq.WriteRequest(9, 410, (0x0200,))


# ---------------------------------------------------------------- ATI RDT


def test_rdt_request_and_records() -> None:
    assert ati_rdt.encode_request(ati_rdt.Command.REALTIME) == H("12 34 00 02 00 00 00 00")
    assert ati_rdt.decode_request(H("12 34 00 00 00 00 00 0A")) == (0, 10)
    assert ati_rdt.decode_request(H("12 35 00 00 00 00 00 0A")) is None
    rec = ati_rdt.encode_record(1, 7000, 0x80000000, [1_000_000, -2_000_000, 0, 500, -500, 2**31 - 1])
    assert len(rec) == 36 and rec[:4] == H("00 00 00 01") and rec[12:16] == H("00 0F 42 40")
    (r,) = ati_rdt.decode_records(rec)
    assert (r.rdt_sequence, r.ft_sequence, r.status) == (1, 7000, 0x80000000)
    f, t = ati_rdt.to_wrench(r, 1e6, 1e6)
    np.testing.assert_allclose(f, [1.0, -2.0, 0.0])
    np.testing.assert_allclose(t, [5e-4, -5e-4, (2**31 - 1) / 1e6])
    assert [x.rdt_sequence for x in ati_rdt.decode_records(rec + rec)] == [1, 1]
    assert ati_rdt.decode_records(rec[:35]) is None and ati_rdt.decode_records(b"") is None
    # counts round half to even and saturate at the int32 range; a NaN is refused
    rounded = ati_rdt.encode_record(2, 1, 0, np.array([0.5, 1.5, -2.5, 1234.4999, 3e12, -np.inf]))
    assert ati_rdt.decode_records(rounded)[0].counts.tolist() == [0, 2, -2, 1234, 2**31 - 1, -(2**31)]
    with pytest.raises(ValueError):
        ati_rdt.encode_record(3, 1, 0, [0.0, 0.0, float("nan"), 0.0, 0.0, 0.0])


def test_rdt_stop_request_and_default_port() -> None:
    # ATI's RDT: command 0x0000 stops streaming; the sensor listens on UDP port 49152
    assert ati_rdt.encode_request(ati_rdt.Command.STOP) == H("12 34 00 00 00 00 00 00")
    assert backend_from_url("rdt://10.0.0.2")._link.address == ("10.0.0.2", 49152)


def _rdt(rdt_sequence: int, ft_sequence: int) -> ati_rdt.RdtRecord:
    return ati_rdt.RdtRecord(rdt_sequence, ft_sequence, 0, np.zeros(6, dtype=np.int64))


def test_rdt_sequences_wrap_at_2_to_the_32_and_a_repeated_record_does_not_follow() -> None:
    last = _rdt(2**32 - 1, 2**32 - 1)
    assert ati_rdt.follows(last, _rdt(0, 0))  # both counters wrap to 0
    assert ati_rdt.follows(last, _rdt(1000, 5))
    assert not ati_rdt.follows(_rdt(1000, 7000), _rdt(1000, 7001))  # the same record number again
    assert ati_rdt.follows(_rdt(1000, 7000), _rdt(1001, 7001))


# ---------------------------------------------------------------- Bota


def test_bota_frame_layout_and_round_trip() -> None:
    frame = bota.encode_frame([1.5, -2, 3], [0.25, 0, -0.5], timestamp_us=123456, status=2, temperature_c=31.5)
    assert len(frame) == 37 and frame[0] == 0xAA and frame[1:3] == H("02 00")
    assert frame[35:] == bota.CRC16_X25(frame[1:35]).to_bytes(2, "little")
    d = bota.decode_frame(frame)
    assert (d.status, d.timestamp_us, d.temperature_c) == (2, 123456, 31.5)
    np.testing.assert_array_equal(d.force_n, [1.5, -2, 3])
    np.testing.assert_array_equal(d.torque_nm, [0.25, 0, -0.5])
    assert bota.BotaStatus(d.status) == bota.BotaStatus.OVER_RANGE
    bad = bytearray(frame)
    bad[20] ^= 1
    assert bota.decode_frame(bytes(bad)) is None


# ---------------------------------------------------------------- DSACON32


def test_dsacon32_commands_match_protocol_vectors() -> None:
    assert dsacon32.encode_configure_acquisition(0, 0) == H("AA AA AA 03 03 00 00 00 00 8D 00")
    assert dsacon32.encode_query_matrix_info(0) == H("AA AA AA 0B 01 00 00 CB FB")
    assert dsacon32.encode_packet(0x01) == H("AA AA AA 01 00 00")  # no CRC without payload
    # start push mode: flags 0xA0 (bit 7 acquire, bit 5 internal trigger), 100 frames/s (u16 LE)
    start = dsacon32.AcquisitionFlags.ACQUIRE | dsacon32.AcquisitionFlags.INTERNAL_TRIGGER
    assert dsacon32.encode_configure_acquisition(start, 100)[:9] == H("AA AA AA 03 03 00 A0 64 00")
    assert backend_from_url("dsacon32:///dev/ttyACM0")._link.baudrate == 115200


def test_dsacon32_a_packet_longer_than_the_codecs_bound_is_rejected() -> None:
    d = Deframer(dsacon32.PacketCodec(max_payload=4))
    assert [p.payload for p in d.feed(dsacon32.encode_packet(0x0B, b"abcd"))] == [b"abcd"]
    assert d.feed(dsacon32.encode_packet(0x0B, b"abcde")) == []  # 6 + 5 + 2 bytes: one over
    assert d.counts.frames == 1 and d.counts.crc_errors == 0


def test_dsacon32_matrix_info_round_trip() -> None:
    info = dsacon32.MatrixInfo(0, 3.4e-3, 3.4e-3, 6, 14)
    (p,) = Deframer(dsacon32.PacketCodec()).feed(dsacon32.encode_matrix_info(info))
    assert p.id == 0x0B and len(p.payload) == 52
    got = dsacon32.decode_matrix_info(p.payload)
    assert (got.cells_x, got.cells_y, got.error) == (6, 14, 0)
    assert got.texel_width_m == pytest.approx(3.4e-3) and got.texel_height_m == pytest.approx(3.4e-3)


@pytest.mark.parametrize("rle", [False, True])
def test_dsacon32_frame_payload_round_trip(rle: bool) -> None:
    counts = np.zeros((14, 6), dtype=np.uint16)
    counts[3:6, 2:4] = 4095
    counts[10, :] = np.arange(6)
    payload = dsacon32.encode_frame_payload(1234, counts, rle=rle)
    frame = dsacon32.decode_frame_payload(payload, 84)
    assert frame.timestamp_ms == 1234
    np.testing.assert_array_equal(frame.counts.reshape(14, 6), counts)
    if rle:
        assert len(payload) < 5 + 2 * 84  # runs of zeros compress
        first = int.from_bytes(payload[5:7], "little")
        assert first == (15 << 12) | 0  # 15 zeros in the first unit
    else:
        assert len(payload) == 5 + 2 * 84
    assert dsacon32.decode_frame_payload(payload, 85) is None  # size disagrees


# ---------------------------------------------------------------- framed / M1616


def test_m1616_layout() -> None:
    counts = np.arange(256, dtype=np.uint16).reshape(16, 16) * 16
    frame = encode_frame(m1616.FORMAT, counts)
    assert len(frame) == 3 + 512 + 4 and frame[:3] == H("AA AB AC")
    assert frame[3:7] == H("00 00 00 10")  # big-endian, row-major: 0, 16
    assert frame[3 + 2 * 17: 3 + 2 * 18] == H("01 10")  # [1, 1] = 17*16 = 0x0110
    np.testing.assert_array_equal(decode_frame(m1616.FORMAT, frame), counts)


@pytest.mark.parametrize("dtype", ["u8", "u16", "u12"])
@pytest.mark.parametrize("endian", ["le", "be"])
@pytest.mark.parametrize("order", ["row", "col"])
@pytest.mark.parametrize("checksum", ["none", "sum8", "crc16", "crc16-ccitt"])
def test_framed_round_trip(dtype: str, endian: str, order: str, checksum: str) -> None:
    fmt = FramedFormat(header=b"\x55\x56", rows=3, cols=5, dtype=dtype, endian=endian, order=order,
                       trailer=1, checksum=checksum)
    counts = (np.arange(15).reshape(3, 5) * 17) % (fmt.max_count + 1)
    frame = encode_frame(fmt, counts)
    assert len(frame) == fmt.length == 2 + 15 * (1 if dtype == "u8" else 2) + 1 + fmt.checksum_length
    np.testing.assert_array_equal(decode_frame(fmt, frame), counts)


def test_framed_column_major_and_checks() -> None:
    fmt = FramedFormat(header=b"\xff", rows=2, cols=3, dtype="u8", order="col", checksum="sum8")
    frame = encode_frame(fmt, np.array([[1, 2, 3], [4, 5, 6]]))
    assert frame == b"\xff" + bytes([1, 4, 2, 5, 3, 6]) + bytes([(0xFF + 21) & 0xFF])
    assert decode_frame(fmt, frame[:-1] + b"\x00") is None
    ccitt = FramedFormat(header=b"\x31", rows=2, cols=4, dtype="u8", checksum="crc16-ccitt")
    # the CRC over "12345678" + "9"... checked against the catalogue value of "123456789"
    assert encode_frame(ccitt, np.frombuffer(b"23456789", np.uint8).reshape(2, 4))[-2:] == bytes.fromhex("29B1")
    u12 = FramedFormat(header=b"\x01", rows=1, cols=2, dtype="u12", endian="le")
    assert decode_frame(u12, b"\x01\xff\x0f\x00\x10") is None  # 0x1000 > 4095
    with pytest.raises(ConfigError, match="header"):
        FramedFormat(header=b"", rows=1, cols=1)
    with pytest.raises(ConfigError, match="dtype"):
        FramedFormat(header=b"a", rows=1, cols=1, dtype="f32")  # type: ignore[arg-type]


# ---------------------------------------------------------------- deframer


def test_deframer_byte_by_byte_and_garbage_counts() -> None:
    frames = [robotiq.encode_frame([i, 0, 0], [0, 0, 0]) for i in range(3)]
    stream = b"\x20" + frames[0] + b"\x00\x4e\x20\x4e\x01" + frames[1] + frames[2] + b"\x20"
    d = Deframer(robotiq.StreamCodec())
    out = [f for b in stream for f in d.feed(bytes([b]))]
    assert [f.force_n[0] for f in out] == [0, 1, 2]
    # garbage: 1 + 5 bytes, the false "20 4E" candidate failed its CRC once; last 0x20 pending
    assert (d.counts.frames, d.counts.crc_errors, d.counts.rejected_bytes, d.pending) == (3, 1, 6, 1)


def test_deframer_recovers_frame_behind_truncated_frame() -> None:
    f1 = bota.encode_frame([1, 1, 1], [0, 0, 0], timestamp_us=1)
    f2 = bota.encode_frame([2, 2, 2], [0, 0, 0], timestamp_us=2)
    d = Deframer(bota.StreamCodec())
    out = d.feed(f1[:20] + f2)
    assert [f.timestamp_us for f in out] == [2]
    assert d.counts.rejected_bytes == 20


def test_deframer_waits_for_a_header_split_across_reads_behind_a_frame() -> None:
    """A read that ends inside the next packet's 6-byte header (the length is in bytes 4-5)
    keeps the partial header for the next read: nothing rejected, no packet lost."""
    first = dsacon32.encode_query_matrix_info(0)
    second = dsacon32.encode_query_matrix_info(1)
    d = Deframer(dsacon32.PacketCodec(allow_empty=False))
    assert [p.payload for p in d.feed(first + second[:4])] == [b"\x00"]
    assert d.pending == 4
    assert [p.payload for p in d.feed(second[4:])] == [b"\x01"]
    assert (d.counts.frames, d.counts.crc_errors, d.counts.rejected_bytes, d.pending) == (2, 0, 0, 0)


# ---------------------------------------------------------------- calibration


def _cal(**kw) -> Calibration:
    return Calibration(counts=[0, 100, 1100], pressure_pa=[0.0, 1000.0, 6000.0], **kw)


def test_calibration_interpolates_and_flags() -> None:
    cal = _cal(gain=[1.0, 2.0, 1.0, 1.0], dead=[3], saturation_counts=1000)
    out = cal.apply(np.array([[50, 50], [1000, 2000]]))
    # 50 -> 500 Pa; gain 2: 100 -> 1000 Pa; 1000 -> 1000 + 900/1000*5000 = 5500 Pa; dead -> 0
    np.testing.assert_allclose(out.pressure_pa, [[500.0, 1000.0], [5500.0, 0.0]])
    np.testing.assert_array_equal(out.saturated, [[False, False], [True, True]])
    np.testing.assert_array_equal(out.dead, [[False, False], [False, True]])


def test_calibration_toml_round_trip(tmp_path) -> None:
    cal = _cal(gain=[1.0, 0.5], dead=[1], saturation_counts=4095)
    save_calibration(cal, tmp_path / "cal.toml")
    back = load_calibration(tmp_path / "cal.toml")
    np.testing.assert_array_equal(back.counts, cal.counts)
    np.testing.assert_array_equal(back.pressure_pa, cal.pressure_pa)
    np.testing.assert_array_equal(back.gain, cal.gain)
    assert list(back.dead) == [1] and back.saturation_counts == 4095


@pytest.mark.parametrize(
    "text, message",
    [
        ("counts = [0, 0]\npressure_pa = [0, 1]", "strictly increasing"),
        ("counts = [0, 1]\npressure_pa = [1, 0]", "monotone"),
        ("counts = [0, 1]", "pressure_pa"),
        ("counts = [0, 1]\npressure_pa = [0, 1]\ngian = [1]", "unknown keys"),
        ("counts = [0, 1", "not valid TOML"),
    ],
)
def test_calibration_rejects_bad_files(text: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        Calibration.from_toml(text)


def test_calibration_check_size() -> None:
    with pytest.raises(ConfigError, match="gain has 2"):
        _cal(gain=[1, 1]).check_size(256)
    with pytest.raises(ConfigError, match="dead index 300"):
        _cal(dead=[300]).check_size(256)


# ---------------------------------------------------------------- URLs


def test_backend_urls() -> None:
    b = backend_from_url("rdt://10.0.0.2?cpf=1000000&cpt=1000")
    assert isinstance(b, RdtBackend) and b.counts_per_torque == 1000 and b.kind == "ft"
    assert b.stale_after_s == pytest.approx(2.5e-3)  # 2.5 periods at 7 kHz (0.36 ms) is below the floor
    assert backend_from_url("bota:///dev/ttyUSB1").stale_after_s == pytest.approx(2.5 / 200)  # 2.5 periods
    r = backend_from_url("robotiq:///dev/ttyUSB0?stop_ms=20&stale_ms=40")
    assert isinstance(r, RobotiqBackend) and r.stale_after_s == pytest.approx(0.04)
    assert isinstance(backend_from_url("bota:///dev/ttyUSB1"), BotaBackend)
    d = backend_from_url("dsacon32:///dev/ttyACM0?fps=100&rle=1")
    assert isinstance(d, Dsacon32Backend) and d.rate_hz == 100 and d.rle
    m = backend_from_url("m1616:///dev/ttyUSB2")
    assert isinstance(m, FramedBackend) and m.format == m1616.FORMAT and m.kind == "tactile"
    f = backend_from_url("framed:///dev/pts/9?rows=8&cols=4&header=a5 5a&dtype=u12&checksum=crc16&rate_hz=1000")
    assert f.format == FramedFormat(header=b"\xa5\x5a", rows=8, cols=4, dtype="u12", checksum="crc16")


@pytest.mark.parametrize(
    "url, message",
    [
        ("usb:///dev/x", "unknown scheme"),
        ("robotiq://dev/ttyUSB0", "absolute path"),
        ("robotiq:///dev/ttyUSB0?baudrate=9600", r"\?baudrate=9600: baudrate: unknown key; known here: .*baud,"),
        ("rdt://host?cpf=abc", r"rdt://host\?cpf=abc: cpf: must be a number, got 'abc'"),
        ("rdt://host?cpt=0", "cpt: must be > 0.0, got '0'"),
        ("rdt://host?rate_hz=inf", "rate_hz: must be finite"),
        ("dsacon32:///dev/x?rle=maybe", "rle: must be true or false, got 'maybe'"),
        ("framed:///dev/x?header=zz", "header: must be hex digits"),
        ("rdt://", "needs a host"),
        ("framed:///dev/x?rows=4", "header"),
        ("dsacon32:///dev/x?fps=0", "fps"),
    ],
)
def test_backend_url_errors(url: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        backend_from_url(url)
