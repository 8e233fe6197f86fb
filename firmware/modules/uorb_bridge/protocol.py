"""The uORB bridge's wire format: frames of packed uORB messages on a serial byte stream.

One frame (all integers little-endian, as the packed uORB fields are)::

    offset  size  field
    0       2     sync 0xB7 0x1D
    2       2     payload length N (bytes)
    4       4     topic id (0: the link's heartbeat, see Heartbeat)
    8       1     topic instance
    9       1     sequence number (per sender, wraps at 256: lost frames show as gaps)
    10      N     payload: the message's packed fields (the generated class's ``pack()``)
    10+N    2     CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final XOR)
                  over bytes 2 .. 10+N-1 (length to the end of the payload), little-endian

The CRC is ``binascii.crc_hqx(data, 0xFFFF)`` from the standard library (the same CRC as
XMODEM's but with init 0xFFFF; check value of b"123456789" is 0x29B1). A 16-bit CRC over at
most :data:`MAX_PAYLOAD` bytes detects every burst error up to 16 bits and all but ~1/65536 of
the rest, which is what a short serial link between two boards needs; the topic id and the
payload size checked against the definition catch most of what slips through.

The decoder is a stream parser: bytes come in arbitrary chunks (whatever the UART read gave),
frames are found by their sync word and checked by length and CRC, and anything that is not a
frame is skipped one byte at a time, so the parser resynchronises after garbage, a cut frame or
a bit error without losing the frames that follow. Every dropped frame is counted by cause.
"""

from __future__ import annotations

import binascii
import struct
from typing import Final

__all__ = ["CRC_NAME", "DropCounters", "Frame", "FrameDecoder", "HEADER_SIZE",
           "HEARTBEAT_ID", "Heartbeat", "MAX_PAYLOAD", "OVERHEAD", "SYNC", "crc16",
           "encode_frame"]

SYNC: Final = b"\xb7\x1d"
#: sync(2) length(2) topic id(4) instance(1) sequence(1)
HEADER_SIZE: Final = 10
CRC_SIZE: Final = 2
#: bytes a frame adds to its payload
OVERHEAD: Final = HEADER_SIZE + CRC_SIZE
#: the largest payload a frame may carry (so a whole frame fits NuttX's 1024-byte serial TX
#: buffer); a longer length field is garbage, not a frame
MAX_PAYLOAD: Final = 1000
#: the topic id of the heartbeat frame (no topic id derived from a .msg may be 0)
HEARTBEAT_ID: Final = 0
CRC_NAME: Final = "CRC-16/CCITT-FALSE"

_HEAD: Final = struct.Struct("<2sHIBB")
_CRC: Final = struct.Struct("<H")


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE of ``data`` (poly 0x1021, init 0xFFFF)."""
    return binascii.crc_hqx(data, 0xFFFF)


def encode_frame(topic_id: int, instance: int, seq: int, payload: bytes) -> bytes:
    """One frame carrying ``payload`` (raises ValueError on values that do not fit)."""
    n = len(payload)
    if n > MAX_PAYLOAD:
        raise ValueError(f"uorb_bridge: payload of {n} bytes exceeds {MAX_PAYLOAD}")
    if not 0 <= topic_id <= 0xFFFFFFFF or not 0 <= instance <= 0xFF:
        raise ValueError(f"uorb_bridge: topic id {topic_id} / instance {instance} out of range")
    head = _HEAD.pack(SYNC, n, topic_id, instance, seq & 0xFF)
    body = head[2:] + payload
    return SYNC + body + _CRC.pack(binascii.crc_hqx(body, 0xFFFF))


class Heartbeat:
    """The heartbeat's payload: the sender's own counters, so each side can see the other's
    view of the link (frames it sent and received, and dropped, and its uptime)."""

    __slots__ = ("uptime_us", "tx_frames", "rx_frames", "rx_dropped", "tx_dropped")
    _S: Final = struct.Struct("<QIIII")
    SIZE: Final = _S.size

    def __init__(self, uptime_us: int = 0, tx_frames: int = 0, rx_frames: int = 0,
                 rx_dropped: int = 0, tx_dropped: int = 0) -> None:
        self.uptime_us = uptime_us
        self.tx_frames = tx_frames
        self.rx_frames = rx_frames
        self.rx_dropped = rx_dropped
        self.tx_dropped = tx_dropped

    def pack(self) -> bytes:
        m = 0xFFFFFFFF
        return self._S.pack(self.uptime_us & 0xFFFFFFFFFFFFFFFF, self.tx_frames & m,
                            self.rx_frames & m, self.rx_dropped & m, self.tx_dropped & m)

    @classmethod
    def unpack(cls, data: bytes) -> Heartbeat:
        return cls(*cls._S.unpack(data))


class Frame:
    """A frame that passed the CRC, the id and the size checks."""

    __slots__ = ("topic_id", "instance", "seq", "payload")

    def __init__(self, topic_id: int, instance: int, seq: int, payload: bytes) -> None:
        self.topic_id = topic_id
        self.instance = instance
        self.seq = seq
        self.payload = payload

    def __repr__(self) -> str:
        return (f"Frame(id=0x{self.topic_id:08x}, instance={self.instance}, seq={self.seq}, "
                f"{len(self.payload)} bytes)")


class DropCounters:
    """What the decoder threw away, by cause (all only grow)."""

    __slots__ = ("crc", "truncated", "unknown_id", "bad_size", "garbage_bytes", "lost")

    def __init__(self) -> None:
        #: frames whose CRC did not match (bit errors, or a frame cut short by another's sync
        #: when no valid frame could be found inside it)
        self.crc = 0
        #: frames cut short: a valid frame starts inside their claimed length, or the stream
        #: went quiet in the middle of one (:meth:`FrameDecoder.flush`)
        self.truncated = 0
        #: valid frames of a topic id this side does not know (another .msg definition)
        self.unknown_id = 0
        #: valid frames whose payload size differs from the known definition's
        self.bad_size = 0
        #: bytes skipped while looking for a sync word (not counted as frames)
        self.garbage_bytes = 0
        #: frames missing by the sender's sequence numbers while the link was up (never
        #: arrived, or dropped here); a gap is counted modulo 256
        self.lost = 0

    @property
    def frames(self) -> int:
        """Frames dropped (the byte and sequence counts excluded)."""
        return self.crc + self.truncated + self.unknown_id + self.bad_size


class FrameDecoder:
    """Stream parser: :meth:`feed` bytes, get the good frames back; drops counted in
    :attr:`drops`.

    ``sizes`` maps every known topic id to its payload size; the heartbeat's id is always
    known. Frames of other ids and of other sizes are dropped and counted, after their CRC
    passed (so they are whole frames of another definition, not noise).
    """

    def __init__(self, sizes: dict[int, int]) -> None:
        self.sizes: dict[int, int] = dict(sizes)
        self.sizes[HEARTBEAT_ID] = Heartbeat.SIZE
        self.drops = DropCounters()
        self.frames = 0
        self.bytes = 0
        self._buf = bytearray()
        self._last_seq = -1

    @property
    def pending(self) -> int:
        """Bytes held back: the start of a frame still arriving."""
        return len(self._buf)

    def flush(self) -> None:
        """The stream went quiet: what is held back is a frame cut short (counted as
        truncated if it began with a sync word) or garbage."""
        buf = self._buf
        if buf:
            if buf[:2] == SYNC or buf == SYNC[:1]:
                self.drops.truncated += 1
            else:
                self.drops.garbage_bytes += len(buf)
            buf.clear()

    def feed(self, data: bytes) -> list[Frame]:
        """Parse ``data`` (appended to what was held back); return the frames completed."""
        self.bytes += len(data)
        buf = self._buf
        buf += data
        out: list[Frame] = []
        drops = self.drops
        pos = 0
        n = len(buf)
        while True:
            i = buf.find(SYNC, pos)
            if i < 0:
                # keep a trailing first sync byte: the second may come in the next chunk
                keep = n - 1 if n > pos and buf[n - 1] == SYNC[0] else n
                drops.garbage_bytes += keep - pos
                pos = keep
                break
            drops.garbage_bytes += i - pos
            pos = i
            if n - pos < HEADER_SIZE:
                break
            _, length, tid, inst, seq = _HEAD.unpack_from(buf, pos)
            if length > MAX_PAYLOAD:
                drops.garbage_bytes += 1       # not a frame's header: look further
                pos += 1
                continue
            end = pos + HEADER_SIZE + length + CRC_SIZE
            if end > n:
                # the rest has not arrived yet, unless a whole good frame already begins
                # inside: then this one was cut short, and waiting would hold that one back
                if self._frame_inside(buf, pos + 1, n) == 1:
                    drops.truncated += 1
                    pos += 1
                    continue
                break
            body = bytes(buf[pos + 2:end - CRC_SIZE])
            (crc,) = _CRC.unpack_from(buf, end - CRC_SIZE)
            if binascii.crc_hqx(body, 0xFFFF) != crc:
                inside = self._frame_inside(buf, pos + 1, end)
                if inside < 0:
                    break                      # a frame starts inside: wait for its end
                if inside:
                    drops.truncated += 1
                else:
                    drops.crc += 1
                pos += 1                       # resynchronise on the next sync word
                continue
            pos = end
            self._note_seq(seq)
            size = self.sizes.get(tid)
            if size is None:
                drops.unknown_id += 1
                continue
            if size != length:
                drops.bad_size += 1
                continue
            self.frames += 1
            out.append(Frame(tid, inst, seq, body[HEADER_SIZE - 2:]))
        if pos:
            del buf[:pos]
        return out

    def forget_sequence(self) -> None:
        """The link was lost: the next frame starts a new count (the outage itself is the
        link's loss, not frames lost while it was up)."""
        self._last_seq = -1

    def _note_seq(self, seq: int) -> None:
        if self._last_seq >= 0:
            self.drops.lost += (seq - self._last_seq - 1) & 0xFF
        self._last_seq = seq

    @staticmethod
    def _frame_inside(buf: bytearray, start: int, end: int) -> int:
        """1 if a whole frame with a good CRC begins in ``buf[start:end]`` (then the frame
        that claimed those bytes was cut short: its sender stopped or bytes were lost), 0 if
        none does, -1 if one may but has not fully arrived yet."""
        n = len(buf)
        undecided = False
        i = buf.find(SYNC, start, end)
        while i >= 0:
            if n - i < HEADER_SIZE:
                undecided = True
            else:
                length = buf[i + 2] | (buf[i + 3] << 8)
                e = i + HEADER_SIZE + length + CRC_SIZE
                if length <= MAX_PAYLOAD:
                    if e > n:
                        undecided = True
                    else:
                        crc = buf[e - 2] | (buf[e - 1] << 8)
                        if binascii.crc_hqx(bytes(buf[i + 2:e - 2]), 0xFFFF) == crc:
                            return 1
            i = buf.find(SYNC, i + 1, end)
        return -1 if undecided else 0
