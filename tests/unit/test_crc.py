"""CRC-16 variants against catalogue check values and the vectors of docs/protocols.md §2."""

from __future__ import annotations

import pytest

from slipstack.lib.protocols.crc import (
    CRC16_CCITT_FALSE, CRC16_DSACON32, CRC16_MODBUS, CRC16_X25, Crc16,
)

CHECK = b"123456789"


@pytest.mark.parametrize(
    "crc, expected",
    [(CRC16_MODBUS, 0x4B37), (CRC16_X25, 0x906E), (CRC16_DSACON32, 0x6EB4), (CRC16_CCITT_FALSE, 0x29B1)],
)
def test_check_values(crc: Crc16, expected: int) -> None:
    assert crc(CHECK) == expected


def _bitwise(data: bytes, poly: int, init: int, refin: bool, xorout: int) -> int:
    """Bit-at-a-time reference (the textbook definition)."""
    c = init
    rpoly = int(f"{poly:016b}"[::-1], 2)
    for b in data:
        if refin:
            c ^= b
            for _ in range(8):
                c = (c >> 1) ^ rpoly if c & 1 else c >> 1
        else:
            c ^= b << 8
            for _ in range(8):
                c = ((c << 1) ^ poly) & 0xFFFF if c & 0x8000 else (c << 1) & 0xFFFF
    return c ^ xorout


@pytest.mark.parametrize("crc", [CRC16_MODBUS, CRC16_X25, CRC16_CCITT_FALSE])
def test_table_matches_bitwise_definition(crc: Crc16) -> None:
    data = bytes(range(256)) + b"slipstack"
    assert crc(data) == _bitwise(data, crc.poly, crc.init, crc.refin, crc.xorout)


@pytest.mark.parametrize(
    "body, crc_bytes",
    [
        ("09 10 01 9A 00 01 02 02 00", "CD CA"),  # Robotiq start-stream request
        ("09 10 01 9A 00 01", "21 52"),  # its echo
        ("20 4E" + " 00" * 12, "62 AF"),  # all-zero stream frame
    ],
)
def test_modbus_vectors(body: str, crc_bytes: str) -> None:
    assert CRC16_MODBUS(bytes.fromhex(body)).to_bytes(2, "little") == bytes.fromhex(crc_bytes)


@pytest.mark.parametrize(
    "covered, crc_bytes",
    [("03 03 00 00 00 00", "8D 00"), ("0B 01 00 00", "CB FB")],  # DSACON32 stop, query matrix 0
)
def test_dsacon32_vectors(covered: str, crc_bytes: str) -> None:
    assert CRC16_DSACON32(bytes.fromhex(covered)).to_bytes(2, "little") == bytes.fromhex(crc_bytes)


def test_dsacon32_is_not_ccitt_false() -> None:
    # the manuals' "CCITT" is a mixed variant; CCITT-FALSE would give other packet CRCs
    assert CRC16_CCITT_FALSE(bytes.fromhex("0B 01 00 00")) != 0xFBCB


def test_chaining_with_init() -> None:
    a, b = b"12345", b"6789"
    assert CRC16_MODBUS(b, init=CRC16_MODBUS(a)) == CRC16_MODBUS(CHECK)


def test_wrong_check_value_is_caught_at_construction() -> None:
    with pytest.raises(ValueError, match="check value"):
        Crc16("bad", poly=0x1021, init=0xFFFF, refin=True, xorout=0, check=0x1234)


def test_the_crcs_run_interpreted():
    """With NUMBA_DISABLE_JIT=1 (the kernels interpreted, e.g. to debug one) every CRC
    still gives its check value: the protocols import and frame alike."""
    import os
    import subprocess
    import sys

    code = ("from slipstack.lib.protocols import crc; "
            "print(sorted(c.name for c in vars(crc).values() if isinstance(c, crc.Crc16)))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env={**os.environ, "NUMBA_DISABLE_JIT": "1"})
    assert done.returncode == 0, done.stderr[-2000:]
    assert "CRC-16/MODBUS" in done.stdout


def test_importing_the_crcs_loads_no_kernel():
    """A process that frames no CRC (an F/T driver on RDT) does not pay numba's import and
    first dispatch (0.5 s of CPU) for the protocols it imports; the check values still hold."""
    import subprocess
    import sys

    code = ("import sys; from slipstack.lib.protocols import bota, dsacon32, framed, robotiq; "
            "print('numba' in sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "False", done.stdout + done.stderr[-2000:]


def test_an_msb_first_crc_other_than_ccitt_matches_the_bitwise_definition() -> None:
    # CRC-16/UMTS (catalogue: poly 0x8005, init 0, refin false, xorout 0, check 0xFEE8): MSB-first
    # like CCITT-FALSE but not binascii's 0x1021, so both of its paths are the table's (short
    # data in Python, long data in the kernel).
    umts = Crc16("CRC-16/UMTS", poly=0x8005, init=0x0000, refin=False, xorout=0x0000, check=0xFEE8)
    for data in (b"slip", bytes(range(256)) + b"slipstack"):
        assert umts(data) == _bitwise(data, 0x8005, 0x0000, False, 0x0000)


def test_a_crc_built_again_equals_the_shipped_one() -> None:
    assert Crc16("CRC-16/MODBUS", poly=0x8005, init=0xFFFF, refin=True, xorout=0x0000, check=0x4B37) == CRC16_MODBUS
    assert CRC16_MODBUS != CRC16_X25
