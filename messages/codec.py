"""MessagePack encoding of slipstack messages.

Wire format of one frame payload (a msgpack array, positional like msgspec's
array-like structs; new fields may only be appended, with defaults)::

    [type_name: str, version: int,
     [stamp_ns, seq, pub_ns, {source_name: stamp_ns}],   # the header
     [field_0, field_1, ...]]                              # the body, declared order

More in docs/modules.md, `messages/codec.py`.
"""

from __future__ import annotations

import functools
import struct
import threading
from typing import Any

import msgpack
import numpy as np

from slipstack.lib.errors import DecodeError

__all__ = [
    "ARRAY_EXT", "ALLOWED_DTYPES", "MAX_PAYLOAD_BYTES", "UNPACK_LIMITS", "pack_array", "array_head", "ext_type",
    "unpack_array", "packb", "unpackb",
]

ARRAY_EXT = 1
MAX_PAYLOAD_BYTES = 2 << 20
"""Largest frame payload, bytes: the largest legal message (a 256×256 ``contact``,
~0.6 MB, or a full diagnostics counter map) with headroom."""
UNPACK_LIMITS = {
    # twice what any declared field allows, so the field's own check names it first
    "max_str_len": 2 * 4 * 4096,  # bytes: the longest text field is 4096 characters of UTF-8
    "max_bin_len": 0,  # messages carry no raw bytes
    "max_array_len": 1024,  # msgpack lists: the body, a header, a verdict
    "max_map_len": 2 * 4096,  # diagnostics counters
    "max_ext_len": 1 << 20,  # an encoded array: 256×256 float64 plus its header
}
"""Limits :func:`unpackb` passes to msgpack: a longer item is an error, not an allocation."""
ALLOWED_DTYPES = frozenset({"<f8", "<f4", "<i8", "<i4", "<u2", "|u1", "|b1"})
_U32 = struct.Struct("<I")


_PACKED_HEADS: dict[tuple[np.dtype, tuple[int, ...]], bytes] = {}
_PACKED_HEADS_MAX = 256


def pack_array(arr: np.ndarray) -> msgpack.ExtType:
    """Encode a numpy array as extension type :data:`ARRAY_EXT` (little-endian, C order)."""
    head = _PACKED_HEADS.get((arr.dtype, arr.shape))  # built once per dtype and shape (a stream carries few)
    if head is None:
        return _pack_array_first(arr)
    return ext_type((ARRAY_EXT, head + arr.tobytes()))  # tobytes: C order, contiguous or not


def _pack_array_first(arr: np.ndarray) -> msgpack.ExtType:
    """:func:`pack_array` of an array whose header is not cached: the dtype checked, the
    header built and kept (bounded) unless the array must be byte-swapped (never cached)."""
    swap = arr.dtype.byteorder == ">"
    code = (arr.dtype.newbyteorder("<") if swap else arr.dtype).str
    if code not in ALLOWED_DTYPES:
        raise TypeError(f"array dtype {arr.dtype} cannot be sent; use one of {sorted(ALLOWED_DTYPES)}")
    head = array_head(code, arr.shape)
    if swap:
        arr = arr.astype(arr.dtype.newbyteorder("<"))
    elif len(_PACKED_HEADS) < _PACKED_HEADS_MAX:
        _PACKED_HEADS[(arr.dtype, arr.shape)] = head
    return ext_type((ARRAY_EXT, head + arr.tobytes()))


def array_head(code: str, shape: tuple[int, ...]) -> bytes:
    """The header of :func:`pack_array`'s extension data for an array of dtype ``code``
    (one of :data:`ALLOWED_DTYPES`) and ``shape``; the raw bytes follow it."""
    return bytes([len(code)]) + code.encode() + bytes([len(shape)]) + b"".join(_U32.pack(n) for n in shape)


ext_type = functools.partial(tuple.__new__, msgpack.ExtType)
"""``ext_type((code, data))`` is ``msgpack.ExtType(code, data)`` without the checks its
constructor runs in Python (~0.2 µs, a third of an array's encoding), for an int code
and bytes data."""


_HEADER_CACHE: dict[bytes, tuple[np.dtype, tuple[int, ...], int, int]] = {}
_HEADER_CACHE_MAX = 256


def _parse_array_header(data: bytes) -> tuple[int, np.dtype, tuple[int, ...], int, int]:
    """``(data offset, dtype, shape, count, nbytes)`` of an encoded array; checked once per
    distinct header and then cached (a stream carries few distinct headers)."""
    try:
        n = data[0]
        off = 2 + n + 4 * data[1 + n]
    except IndexError:
        raise DecodeError("array: truncated header") from None
    head = data[:off]
    hit = _HEADER_CACHE.get(head)
    if hit is not None:
        return (off, *hit)
    try:
        code = data[1 : 1 + n].decode("ascii")
        ndim = data[1 + n]
        shape = tuple(_U32.unpack_from(data, 2 + n + 4 * k)[0] for k in range(ndim))
    except (IndexError, UnicodeDecodeError, struct.error) as exc:
        raise DecodeError(f"array: truncated or corrupt header ({exc})") from None
    if code not in ALLOWED_DTYPES:
        raise DecodeError(f"array: dtype {code!r} is not allowed")
    dtype = np.dtype(code)
    count = int(np.prod(shape, dtype=np.int64)) if shape else 1
    entry = (dtype, shape, count, count * dtype.itemsize)
    if len(_HEADER_CACHE) < _HEADER_CACHE_MAX:
        _HEADER_CACHE[head] = entry
    return (off, *entry)


def unpack_array(data: bytes) -> np.ndarray:
    """Decode :func:`pack_array` output; raises :class:`DecodeError` on any inconsistency."""
    off, dtype, shape, count, nbytes = _parse_array_header(data)
    if len(data) - off != nbytes:
        raise DecodeError(f"array: {len(data) - off} data bytes do not match shape {shape} of {dtype.str}")
    arr = np.frombuffer(data, dtype, count, off)  # positional: numpy parses keywords slowly (~0.4 µs)
    return arr if len(shape) == 1 else arr.reshape(shape)


def _default(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return pack_array(obj)
    if isinstance(obj, np.generic):
        return obj.item()
    raise TypeError(f"cannot encode {type(obj).__name__}")


def _ext_hook(code: int, data: bytes) -> Any:
    if code != ARRAY_EXT:
        raise DecodeError(f"unknown msgpack extension type {code}")
    return unpack_array(data)


_thread = threading.local()  # each thread's packer, reused by packb
_PACKER_KEPT_BYTES = 256 * 1024
"""A packer whose last output was longer is dropped, so that no thread keeps a buffer
grown by one large frame (msgpack's own initial buffer is this size)."""


def packb(obj: Any) -> bytes:
    """Encode a tree of builtins and numpy arrays to MessagePack bytes.

    Each thread reuses one packer (``msgpack.packb`` builds one per call, ~0.4 µs); a
    failed call lets it go (its buffer may have grown before the failure), so the next
    starts clean, and no call re-enters it (its only callback, ``_default``, packs
    nothing itself).
    """
    try:
        packer = _thread.packer
    except AttributeError:  # this thread's first frame, or the first after a large or failed one
        packer = _thread.packer = msgpack.Packer(default=_default, use_bin_type=True)
    try:
        payload = packer.pack(obj)
    except BaseException:
        del _thread.packer
        raise
    if len(payload) > _PACKER_KEPT_BYTES:
        del _thread.packer
    return payload


def unpackb(payload: bytes) -> Any:
    """Decode MessagePack bytes; any failure becomes :class:`DecodeError`."""
    try:
        return msgpack.unpackb(
            payload, ext_hook=_ext_hook, raw=False, strict_map_key=True, use_list=True, **UNPACK_LIMITS
        )
    except DecodeError:
        raise
    except Exception as exc:  # msgpack raises a zoo of types on garbage
        raise DecodeError(f"payload: not a valid MessagePack frame ({type(exc).__name__}: {exc})") from None
