"""The BSON subset PX4 stores parameters in (see ../shared/reference/sensors.md section 9.3).

A document is ``int32 length`` (counting itself and the final 0x00), then elements
``type byte, NUL-terminated name, value``, then ``0x00``. PX4 writes INT32 (0x10) for integer
parameters and DOUBLE (0x01) for floats; it also decodes BOOL, INT64, STRING and BINDATA, and
reads a type byte of 0xFF (erased memory) as "no data". Decoding is strict about lengths:
the bytes decoded must match the length field, as PX4 requires.
"""

from __future__ import annotations

import struct

from mypy_extensions import mypyc_attr

__all__ = ["BsonError", "encode", "decode", "INT32", "DOUBLE"]

DOUBLE, STRING, BINDATA, BOOL, INT32, INT64, END, ERASED = 0x01, 0x02, 0x05, 0x08, 0x10, 0x12, \
    0x00, 0xFF
MAX_NAME = 32


@mypyc_attr(native_class=False)
class BsonError(ValueError):
    pass


def encode(values: dict[str, int | float]) -> bytes:
    """Encode ``{name: value}`` (int -> INT32, float -> DOUBLE) in the given order."""
    out = bytearray(4)
    for name, value in values.items():
        raw = name.encode("ascii")
        if len(raw) >= MAX_NAME or b"\0" in raw:
            raise BsonError(f"parameter name {name!r} too long or not ASCII")
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise BsonError(f"parameter {name}: value {value!r} is neither int nor float")
        if isinstance(value, int):
            out += bytes((INT32,)) + raw + b"\0" + struct.pack("<i", value)
        else:
            out += bytes((DOUBLE,)) + raw + b"\0" + struct.pack("<d", value)
    out.append(END)
    out[0:4] = struct.pack("<i", len(out))
    return bytes(out)


def decode(data: bytes) -> dict[str, int | float | bool | str | bytes] | None:
    """Decode one document; None for erased memory (length or first type byte 0xFF).

    Raises :class:`BsonError` with what and where for anything malformed.
    """
    if len(data) < 5:
        raise BsonError(f"document of {len(data)} bytes is shorter than the minimum 5")
    (length,) = struct.unpack_from("<i", data, 0)
    if length == -1 or data[4] == ERASED:
        return None
    if length < 5 or length > len(data):
        raise BsonError(f"length field {length} does not fit the {len(data)} bytes available")
    out: dict[str, int | float | bool | str | bytes] = {}
    pos = 4
    while True:
        if pos >= length:
            raise BsonError(f"no end-of-document byte within the {length} bytes of the length "
                            f"field")
        kind = data[pos]
        pos += 1
        if kind == END:
            break
        if kind == ERASED:
            return None if not out else out
        end = data.find(b"\0", pos, min(pos + MAX_NAME, length))
        if end < 0:
            raise BsonError(f"element name at offset {pos} not terminated within "
                            f"{MAX_NAME} bytes")
        name = data[pos:end].decode("ascii", "replace")
        pos = end + 1
        try:
            if kind == INT32:
                (value,) = struct.unpack_from("<i", data, pos)
                pos += 4
            elif kind == DOUBLE:
                (value,) = struct.unpack_from("<d", data, pos)
                pos += 8
            elif kind == INT64:
                (value,) = struct.unpack_from("<q", data, pos)
                pos += 8
            elif kind == BOOL:
                value = bool(data[pos])
                pos += 1
            elif kind == STRING:
                (n,) = struct.unpack_from("<i", data, pos)
                value = data[pos + 4:pos + 4 + n].rstrip(b"\0").decode("utf-8", "replace")
                pos += 4 + n
            elif kind == BINDATA:
                (n,) = struct.unpack_from("<i", data, pos)
                value = bytes(data[pos + 5:pos + 5 + n])
                pos += 5 + n
            else:
                raise BsonError(f"element {name!r}: unknown type 0x{kind:02X} at offset "
                                f"{pos - len(name) - 2}")
        except struct.error:
            raise BsonError(f"element {name!r} runs past the end of the data") from None
        if pos > length:
            raise BsonError(f"element {name!r} runs past the length field ({length})")
        out[name] = value
    if pos != length:
        raise BsonError(f"size {length} does not match {pos} bytes decoded")
    return out
