"""The byte format between ``hil fly``'s CAN endpoint (TCP on 127.0.0.1) and the python-can
plug-in: fixed 24-byte records, one per frame, both ways.

Fixed-size records need no framing state, so a reader can never lose sync on a valid stream and
a bad record is one record to count and drop. Layout (little-endian)::

    0  u8   kind      1: a frame from the bus, 2: a frame this client sent went out
                      (its confirmation, with its wire time); client to server: 1 only
    1  u8   flags     bit 0: 29-bit identifier, bit 1: remote frame
    2  u8   dlc       0..8
    3  u8   reserved  0
    4  u32  arbitration id
    8  f64  timestamp (s): the time at the frame's end on the emulated bus, as wall-clock epoch
                      seconds when the emulator is paced, else virtual seconds (ignored from
                      clients: a frame enters the bus when the emulator receives it)
    16 8s   data (remote frames: zeros)
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

__all__ = ["KIND_ECHO", "KIND_FRAME", "RECORD", "WireFrame", "decode", "encode"]

RECORD = struct.Struct("<BBBBId8s")
KIND_FRAME = 1
KIND_ECHO = 2
FLAG_EXT = 1
FLAG_RTR = 2


@dataclass(frozen=True)
class WireFrame:
    kind: int
    arbitration_id: int
    is_extended: bool
    is_remote: bool
    data: bytes          # for a remote frame: dlc zero bytes
    timestamp_s: float = 0.0


def encode(f: WireFrame) -> bytes:
    flags = (FLAG_EXT if f.is_extended else 0) | (FLAG_RTR if f.is_remote else 0)
    return RECORD.pack(f.kind, flags, len(f.data), 0, f.arbitration_id, f.timestamp_s,
                       bytes(f.data).ljust(8, b"\0"))


def decode(buf: bytearray, kinds: tuple[int, ...] = (KIND_FRAME, KIND_ECHO)
           ) -> tuple[list[WireFrame], int]:
    """Take every whole record off the front of ``buf``: (valid frames, records dropped).

    A record is dropped if its kind is not in ``kinds``, it has unknown flags, a DLC over 8,
    an identifier out of range for its format or a timestamp that is not finite."""
    n = len(buf) // RECORD.size
    out: list[WireFrame] = []
    bad = 0
    for i in range(n):
        kind, flags, dlc, _res, aid, ts, data = RECORD.unpack_from(buf, i * RECORD.size)
        ext = bool(flags & FLAG_EXT)
        if (kind not in kinds or flags & ~(FLAG_EXT | FLAG_RTR) or dlc > 8
                or aid > (0x1FFFFFFF if ext else 0x7FF) or ts != ts or ts in (
                    float("inf"), float("-inf"))):
            bad += 1
            continue
        rtr = bool(flags & FLAG_RTR)
        out.append(WireFrame(kind, aid, ext, rtr, bytes(dlc) if rtr else bytes(data[:dlc]), ts))
    del buf[:n * RECORD.size]
    return out, bad
