"""Table-driven CRC-16 with the parameters of the device protocols (docs/protocols.md).

One implementation, parameterised in the Rocksoft/Williams style (polynomial,
initial value, bit order, final XOR) plus one extra switch that the DSACON32 needs:

More in docs/modules.md, `lib/protocols/crc.py`.
"""

from __future__ import annotations

import binascii
import functools
from dataclasses import dataclass, field

import numpy as np

__all__ = [
    "Crc16",
    "compile_kernels",
    "CRC16_MODBUS",
    "CRC16_X25",
    "CRC16_DSACON32",
    "CRC16_CCITT_FALSE",
]


def _reflect16(value: int) -> int:
    return int(f"{value:016b}"[::-1], 2)


def _make_table(poly: int, reflected_table: bool) -> tuple[int, ...]:
    table = []
    if reflected_table:
        rpoly = _reflect16(poly)
        for i in range(256):
            c = i
            for _ in range(8):
                c = (c >> 1) ^ rpoly if c & 1 else c >> 1
            table.append(c)
    else:
        for i in range(256):
            c = i << 8
            for _ in range(8):
                c = ((c << 1) ^ poly) & 0xFFFF if c & 0x8000 else (c << 1) & 0xFFFF
            table.append(c)
    return tuple(table)


def _table_crc(data: np.ndarray, table: np.ndarray, crc: int, reflected_update: bool) -> int:
    """The register after *data* (uint8) from *crc*, one table step per byte (module docstring)."""
    for byte in data:
        b = int(byte)  # interpreted (NUMBA_DISABLE_JIT=1), numpy's uint8 would take crc's width
        if reflected_update:
            crc = (crc >> 8) ^ table[(crc ^ b) & 0xFF]
        else:
            crc = ((crc << 8) & 0xFFFF) ^ table[((crc >> 8) ^ b) & 0xFF]
    return crc


KERNEL_FROM_BYTES = 16
"""Shorter data (a request, a constant built at import) takes the loop in Python: about as fast
as the kernel's call there, and it needs no kernel."""


@functools.cache
def _kernel():
    """:func:`_table_crc` compiled by numba (or loaded from its cache), once per process."""
    from numba import njit

    from slipstack.lib.weber import JIT

    return njit(**JIT)(_table_crc)


@dataclass(frozen=True)
class Crc16:
    """A CRC-16 algorithm; call it on bytes to get the CRC as an int in [0, 0xFFFF].

    Parameters
    ----------
    name: label used in messages.
    poly: generator polynomial in normal (MSB-first) notation, e.g. 0x1021.
    init: register value before the first byte.
    refin: reflected (LSB-first, right-shifting) register update.
    xorout: XOR applied to the register after the last byte.
    check: expected CRC of ``b"123456789"``; verified at construction.
    reflected_table: build the table reflected; ``None`` means "same as refin"
        (every Rocksoft-model CRC); DSACON32 uses ``refin=True, reflected_table=False``.
    """

    name: str
    poly: int
    init: int
    refin: bool
    xorout: int
    check: int
    reflected_table: bool | None = None
    _table: np.ndarray = field(init=False, repr=False, compare=False)
    _table_tuple: tuple[int, ...] = field(init=False, repr=False, compare=False)
    _hqx: bool = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        refl = self.refin if self.reflected_table is None else self.reflected_table
        object.__setattr__(self, "_table_tuple", _make_table(self.poly, refl))
        object.__setattr__(self, "_table", np.array(self._table_tuple, dtype=np.int64))
        # binascii.crc_hqx is the MSB-first 0x1021 CRC in C: use it where it applies
        object.__setattr__(self, "_hqx", self.poly == 0x1021 and not self.refin and not refl)
        got = self(b"123456789")  # shorter than KERNEL_FROM_BYTES: no kernel at import
        if got != self.check:  # a wrong table is a programming error, caught at import
            raise ValueError(f"{self.name}: check value {got:#06x} != {self.check:#06x}")

    def __call__(self, data: bytes | bytearray | memoryview, init: int | None = None) -> int:
        """CRC of *data*; *init* overrides the initial register (for chaining)."""
        c = self.init if init is None else init
        if self._hqx:
            return binascii.crc_hqx(data, c) ^ self.xorout
        if len(data) < KERNEL_FROM_BYTES:
            return _table_crc(bytes(data), self._table_tuple, c, self.refin) ^ self.xorout
        return int(_kernel()(np.frombuffer(data, dtype=np.uint8), self._table, c, self.refin)) ^ self.xorout


#: Modbus RTU (Robotiq FT 300); transmitted little-endian.
CRC16_MODBUS = Crc16("CRC-16/MODBUS", poly=0x8005, init=0xFFFF, refin=True, xorout=0x0000, check=0x4B37)
#: X-25 (Bota serial sensors); transmitted little-endian.
CRC16_X25 = Crc16("CRC-16/X-25", poly=0x1021, init=0xFFFF, refin=True, xorout=0xFFFF, check=0x906E)
#: Weiss DSACON32: MSB-first CCITT table, reflected update, no final XOR; little-endian.
CRC16_DSACON32 = Crc16(
    "CRC-16/DSACON32", poly=0x1021, init=0xFFFF, refin=True, xorout=0x0000, check=0x6EB4,
    reflected_table=False,
)
#: CCITT-FALSE (offered by the generic ``framed`` format).
CRC16_CCITT_FALSE = Crc16("CRC-16/CCITT-FALSE", poly=0x1021, init=0xFFFF, refin=False, xorout=0x0000, check=0x29B1)


def compile_kernels() -> None:
    """Load the CRC kernel for every CRC here (compiled once into numba's cache): a node that
    frames CRCs calls this before it reports ready, so its first frame runs at full speed."""
    data = np.frombuffer(b"123456789" * 4, dtype=np.uint8)
    for crc in (CRC16_MODBUS, CRC16_X25, CRC16_DSACON32):
        if _kernel()(data, crc._table, crc.init, crc.refin) != _table_crc(data, crc._table, crc.init, crc.refin):
            raise ValueError(f"{crc.name}: the compiled kernel disagrees with the loop in Python")
