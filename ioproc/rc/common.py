"""Shared pieces of the IO's RC decoders: the byte-decoder base class, float32 helpers, CRCs.

The decoders model what the PX4IO firmware runs on its UARTs: bytes arrive one by one (or in
DMA batches) with a timestamp from the caller's virtual clock, and framing depends on those
timestamps. Nothing here reads a clock of its own, so a replay is deterministic.

Several PX4 scalings are computed in C ``float`` (IEEE single). To give the same µs values as
the firmware at every input, the lookup tables below are built by rounding each intermediate
to float32 exactly as the C expressions do.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable
from typing import Final

from mypy_extensions import mypyc_attr

_F32: Final = struct.Struct("<f")

#: Output slots the IO's RAW_RC page holds (PX4IO_RC_INPUT_CHANNELS).
IO_MAX_CHANNELS: Final = 18


def f32(x: float) -> float:
    """Round a Python float to the nearest IEEE single, like a C ``float`` assignment."""
    return _F32.unpack(_F32.pack(x))[0]


def roundf(x: float) -> int:
    """C ``roundf``/``lround``: round half away from zero."""
    return math.floor(x + 0.5) if x >= 0 else -math.floor(-x + 0.5)


def _crc8_table(poly: int) -> tuple[int, ...]:
    table = []
    for i in range(256):
        c = i
        for _ in range(8):
            c = ((c << 1) ^ poly) & 0xFF if c & 0x80 else (c << 1) & 0xFF
        table.append(c)
    return tuple(table)


def _crc16_table(poly: int) -> tuple[int, ...]:
    table = []
    for i in range(256):
        c = i << 8
        for _ in range(8):
            c = ((c << 1) ^ poly) & 0xFFFF if c & 0x8000 else (c << 1) & 0xFFFF
        table.append(c)
    return tuple(table)


CRC8_07: Final = _crc8_table(0x07)
CRC16_1021: Final = _crc16_table(0x1021)


def crc8_07(data: Iterable[int], crc: int = 0) -> int:
    """CRC-8, polynomial 0x07, init 0, MSB first (ST24; same as the FMU-IO link CRC)."""
    t = CRC8_07
    for b in data:
        crc = t[crc ^ b]
    return crc


def crc16_xmodem(data: Iterable[int], crc: int = 0) -> int:
    """CRC-16/XMODEM: polynomial 0x1021, init 0, no reflection (SUMD)."""
    t = CRC16_1021
    for b in data:
        crc = ((crc << 8) & 0xFFFF) ^ t[(crc >> 8) ^ b]
    return crc


@mypyc_attr(allow_interpreted_subclasses=True)
class RcDecoder:
    """Base of the byte-stream decoders (S.BUS, DSM, SUMD, ST24).

    Subclasses implement :meth:`_feed_byte`; :meth:`feed` and :meth:`feed_byte` do the generic
    work so a UART model can hand over a DMA batch (one timestamp for all of its bytes, which is
    how the IO's 1 ms DMA poll delivers them) or single bytes with their own arrival times.

    State every decoder keeps (the IO copies these into its RAW_RC page):

    ``channels``
        µs values of the last complete frame, PX4's scaling, already in PX4's output order.
    ``raw_channels``
        the protocol's raw positions in the same order (for other scalings, e.g. ArduPilot's).
    ``channel_count``, ``failsafe``, ``frame_lost``, ``rssi`` (percent or None if unknown),
    ``frames`` (frames output), ``frame_errors`` (PX4's drop counter where PX4 keeps one),
    ``bad_crc``, ``lost_frames`` (RF frames the receiver says it lost), ``last_frame_us``.
    """

    #: Protocol name (used by :class:`ioproc.rc.RcInput` and in reports).
    protocol = "?"
    #: Smallest and largest µs value the decoder can ever output (checked by the fuzz tests).
    min_us = 0
    max_us = 0xFFFF

    def __init__(self) -> None:
        self.channels: list[int] = []
        self.raw_channels: list[int] = []
        self.channel_count = 0
        self.failsafe = False
        self.frame_lost = False
        self.rssi: int | None = None
        self.frames = 0
        self.frame_errors = 0
        self.bad_crc = 0
        self.lost_frames = 0
        self.last_frame_us: int | None = None

    def feed(self, t_us: int, data: bytes | bytearray | Iterable[int]) -> bool:
        """Feed bytes received together at ``t_us``; True if at least one frame completed."""
        fb = self._feed_byte
        new = False
        for b in data:
            if fb(t_us, b & 0xFF):
                new = True
        return new

    def feed_byte(self, t_us: int, b: int) -> bool:
        """Feed one byte received at ``t_us``; True if it completed a frame."""
        return self._feed_byte(t_us, b & 0xFF)

    def _feed_byte(self, t_us: int, b: int) -> bool:  # pragma: no cover - abstract
        raise NotImplementedError

    def _publish(self, t_us: int, channels: list[int], raw: list[int]) -> None:
        self.channels = channels
        self.raw_channels = raw
        self.channel_count = len(channels)
        self.frames += 1
        self.last_frame_us = t_us
