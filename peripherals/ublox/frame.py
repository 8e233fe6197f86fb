"""UBX framing and NMEA sentences as the receiver's own firmware would do them.

The model keeps its own framing code instead of importing the flight-stack driver's: a shared
helper with a bug would make both ends agree on a wrong frame and the tests would not see it.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Final

__all__ = ["MAX_PAYLOAD", "SYNC1", "SYNC2", "UbxReader", "checksum", "nmea_sentence", "ubx_frame"]

SYNC1: Final = 0xB5
SYNC2: Final = 0x62
#: Longest payload the model's input buffer accepts; a longer length field means the bytes were
#: not a frame (garbage, or another baud rate), so the reader drops it and looks for sync again.
MAX_PAYLOAD: Final = 1024


def checksum(body: bytes | bytearray | memoryview) -> tuple[int, int]:
    """8-bit Fletcher over class, id, length and payload: (CK_A, CK_B)."""
    a = b = 0
    for byte in body:
        a = (a + byte) & 0xFF
        b = (b + a) & 0xFF
    return a, b


def ubx_frame(cls: int, msg_id: int, payload: bytes = b"") -> bytes:
    """A complete frame: sync, class, id, little-endian length, payload, checksum."""
    n = len(payload)
    body = bytes((cls, msg_id, n & 0xFF, n >> 8)) + bytes(payload)
    a, b = checksum(body)
    return bytes((SYNC1, SYNC2)) + body + bytes((a, b))


class UbxReader:
    """Byte-stream UBX parser of the receiver's input port.

    Anything that is not a complete frame with a good checksum is dropped without an answer
    (the receiver's documented behaviour); after a bad frame the search for sync restarts one
    byte after the false sync so that a real frame hidden in garbage is still found.
    """

    def __init__(self) -> None:
        self._buf = bytearray()
        self.frames = 0
        self.bad_checksum = 0
        self.dropped_bytes = 0

    def reset(self) -> None:
        self._buf.clear()

    def feed(self, data: bytes | bytearray) -> Iterator[tuple[int, int, bytes]]:
        """Yield (class, id, payload) for every good frame completed by ``data``."""
        buf = self._buf
        buf += data
        while True:
            start = buf.find(SYNC1)
            if start < 0:
                self.dropped_bytes += len(buf)
                buf.clear()
                return
            if start:
                self.dropped_bytes += start
                del buf[:start]
            if len(buf) < 2:
                return
            if buf[1] != SYNC2:
                self.dropped_bytes += 1
                del buf[:1]
                continue
            if len(buf) < 6:
                return
            n = buf[4] | (buf[5] << 8)
            if n > MAX_PAYLOAD:
                self.dropped_bytes += 1
                del buf[:1]
                continue
            if len(buf) < 8 + n:
                return
            a, b = checksum(memoryview(buf)[2:6 + n])
            if a != buf[6 + n] or b != buf[7 + n]:
                self.bad_checksum += 1
                self.dropped_bytes += 1
                del buf[:1]
                continue
            cls, msg_id, payload = buf[2], buf[3], bytes(buf[6:6 + n])
            del buf[:8 + n]
            self.frames += 1
            yield cls, msg_id, payload


def nmea_sentence(body: str) -> bytes:
    """``$body*CS\\r\\n`` with CS the XOR of the body characters in upper-case hex."""
    cs = 0
    for ch in body.encode("ascii"):
        cs ^= ch
    return f"${body}*{cs:02X}\r\n".encode("ascii")
