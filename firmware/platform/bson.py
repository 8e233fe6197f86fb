"""The BSON subset PX4 stores parameters in (see ../shared/reference/sensors.md section 9.3).

A document is ``int32 length`` (counting itself and the final 0x00), then elements
``type byte, NUL-terminated name, value``, then ``0x00``. PX4 writes INT32 (0x10) for integer
parameters and DOUBLE (0x01) for floats; it also decodes BOOL, INT64, STRING and BINDATA, and
reads a type byte of 0xFF (erased memory) as "no data". Decoding is strict about lengths:
the bytes decoded must match the length field, as PX4 requires.
"""

from __future__ import annotations

import struct
from typing import Final

__all__ = ["BsonError", "encode", "decode", "INT32", "DOUBLE", "INT32_MIN", "INT32_MAX"]

DOUBLE, STRING, BINDATA, BOOL, INT32, INT64, END, ERASED = 0x01, 0x02, 0x05, 0x08, 0x10, 0x12, \
    0x00, 0xFF
MAX_NAME = 32
#: The range of an INT32 element, and of an INT32 parameter (params.py imports these; so may
#: any module that needs the C int32_t limits).
INT32_MIN: Final = -0x80000000
INT32_MAX: Final = 0x7FFFFFFF

_I32 = struct.Struct("<i")
_FIXED: dict[int, struct.Struct] = {INT32: _I32, DOUBLE: struct.Struct("<d"),
                                    INT64: struct.Struct("<q"), BOOL: struct.Struct("<?")}


class BsonError(ValueError):
    """A document that cannot be encoded or decoded; the message says what and where."""


def encode(values: dict[str, int | float]) -> bytes:
    """Encode ``{name: value}`` (int -> INT32, float -> DOUBLE) in the given order."""
    out = bytearray(4)
    for name, value in values.items():
        if not name.isascii() or "\0" in name or len(name) >= MAX_NAME:
            raise BsonError(f"parameter name {name!r} too long or not ASCII")
        raw = name.encode("ascii")
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise BsonError(f"parameter {name}: value {value!r} is neither int nor float")
        if isinstance(value, int):
            if not INT32_MIN <= value <= INT32_MAX:
                raise BsonError(f"parameter {name}: {value} is outside the int32 range")
            out += bytes((INT32,)) + raw + b"\0" + struct.pack("<i", value)
        else:
            out += bytes((DOUBLE,)) + raw + b"\0" + struct.pack("<d", value)
    out.append(END)
    out[0:4] = struct.pack("<i", len(out))
    return bytes(out)


def decode(data: bytes) -> dict[str, int | float | bool | str | bytes] | None:
    """Decode one document; None for erased memory (length or first type byte 0xFF).

    Every length and offset is checked against the document before it is used, so any byte
    string either decodes or raises :class:`BsonError` (the only error) saying what and where;
    each element moves strictly forward, so decoding ends after at most ``len(data)`` steps.
    """
    data = bytes(data)
    if len(data) < 5:
        raise BsonError(f"document of {len(data)} bytes is shorter than the minimum 5")
    (length,) = _I32.unpack_from(data, 0)
    if length == -1 or data[4] == ERASED:
        return None
    if length < 5 or length > len(data):
        raise BsonError(f"length field {length} does not fit the {len(data)} bytes available")
    end_of_elements = length - 1  # the last byte is the end-of-document 0x00
    out: dict[str, int | float | bool | str | bytes] = {}
    pos = 4
    while True:
        if pos > end_of_elements:
            raise BsonError(f"no end-of-document byte within the {length} bytes of the length "
                            f"field")
        kind = data[pos]
        pos += 1
        if kind == END:
            break
        if kind == ERASED:
            return out or None
        start = pos - 1
        nul = data.find(b"\0", pos, min(pos + MAX_NAME, end_of_elements))
        if nul < 0:
            raise BsonError(f"element name at offset {pos} not terminated within "
                            f"{min(MAX_NAME, end_of_elements - pos)} bytes")
        name = data[pos:nul].decode("ascii", "replace")
        pos = nul + 1
        value, pos = _value(data, kind, name, start, pos, end_of_elements)
        out[name] = value
    if pos != length:
        raise BsonError(f"size {length} does not match {pos} bytes decoded")
    return out


def _value(data: bytes, kind: int, name: str, start: int, pos: int, limit: int
           ) -> tuple[int | float | bool | str | bytes, int]:
    """The value of element ``name`` (type byte at ``start``) at ``pos`` and the offset after
    it; every byte of it must lie before ``limit``, the document's end-of-document byte."""

    def need(n: int, what: str) -> None:
        if n < 0 or pos + n > limit:
            raise BsonError(f"element {name!r} at offset {start}: {what} of {n} bytes runs "
                            f"past the end of the document (offset {limit})")

    fixed = _FIXED.get(kind)
    if fixed is not None:
        need(fixed.size, "value")
        if kind == BOOL:
            return data[pos] != 0, pos + 1
        return fixed.unpack_from(data, pos)[0], pos + fixed.size
    if kind == STRING:  # int32 length counting the terminating NUL, then the bytes
        need(4, "length")
        (n,) = _I32.unpack_from(data, pos)
        if n < 1:
            raise BsonError(f"element {name!r} at offset {start}: string length {n} "
                            f"(at least 1, the terminating NUL)")
        pos += 4
        need(n, "string")
        return data[pos:pos + n].rstrip(b"\0").decode("utf-8", "replace"), pos + n
    if kind == BINDATA:  # int32 length, a subtype byte, then the bytes
        need(5, "length and subtype")
        (n,) = _I32.unpack_from(data, pos)
        if n < 0:
            raise BsonError(f"element {name!r} at offset {start}: negative binary length {n}")
        pos += 5
        need(n, "binary data")
        return data[pos:pos + n], pos + n
    raise BsonError(f"element {name!r}: unknown type 0x{kind:02X} at offset {start}")
