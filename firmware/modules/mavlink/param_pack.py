"""ArduPilot's packed parameter file (``@PARAM/param.pck``, AP_Filesystem_Param), which
ground stations download over MAVLink FTP instead of PARAM_REQUEST_LIST where a vehicle offers
it (see :mod:`firmware.modules.mavlink.ftp`)."""

from __future__ import annotations

import struct
from typing import Any, Final

__all__ = ["PCK_FLOAT", "PCK_INT32", "PCK_MAGIC", "PCK_MAGIC_DEFAULTS", "pack_params"]

#: ArduPilot's packed parameter file: magic without / with defaults
PCK_MAGIC: Final = 0x671B
PCK_MAGIC_DEFAULTS: Final = 0x671C
PCK_INT32: Final = 3
PCK_FLOAT: Final = 4


def pack_params(params: Any, with_defaults: bool) -> bytes:
    """Every parameter in ArduPilot's ``param.pck`` format, in index (name) order.

    Header: magic, count, total (u16 each). A record: type (3 int32, 4 float; bit 4 set when a
    default follows), ``(len(suffix) - 1) << 4 | shared``, the name's suffix after the
    ``shared`` characters it has in common with the previous name, the value, and with
    ``with_defaults`` the default if it differs from the value."""
    out = bytearray()
    prev = b""
    names: list[str] = list(params.names)
    for name in names:
        d = params.defs[name]
        raw = name.encode("ascii")
        shared = 0
        limit = min(len(prev), len(raw) - 1, 15)
        while shared < limit and prev[shared] == raw[shared]:
            shared += 1
        suffix = raw[shared:]
        is_int = d.type == "INT32"
        fmt = "<i" if is_int else "<f"
        value = params.values[name]
        ptype = PCK_INT32 if is_int else PCK_FLOAT
        extra = b""
        if with_defaults and value != d.default:
            ptype |= 0x10
            extra = struct.pack(fmt, d.default)
        out += bytes((ptype, (len(suffix) - 1) << 4 | shared)) + suffix
        out += struct.pack(fmt, value) + extra
        prev = raw
    magic = PCK_MAGIC_DEFAULTS if with_defaults else PCK_MAGIC
    return struct.pack("<HHH", magic, len(names), len(names)) + bytes(out)
