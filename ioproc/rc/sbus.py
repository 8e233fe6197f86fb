"""Futaba S.BUS / S.BUS2 decoder as the PX4IO runs it on USART3 (100 kbit/s 8E2, inverted).

A frame is 25 bytes: header 0x0F, 16 channels × 11 bits packed LSB-first in bytes 1..22, a
flags byte (ch17, ch18, frame lost, failsafe) and an end byte (0x00 for S.BUS, 0x04/0x14/0x24/
0x34 cycling for S.BUS2). The line has no other framing, so the parser relies on the silence
between frames: a partial frame older than ``gap_us`` is discarded. 3 ms is PX4's value from
2014 to 2022-08 (the default here); 4 ms afterwards (:data:`SBUS_GAP_US_2022`).

The byte-wise state machine follows PX4 2015-12+ (the one the R7008SB capture expectations were
produced with): wait for 0x0F, collect 25 bytes, accept only a known end byte, on a rejected
frame go back to waiting for a 0x0F, and after each good frame wait for a fresh 0x0F so S.BUS2
telemetry slot bytes between frames are skipped. E14 did not check the end byte;
``check_end_byte=False`` gives that behaviour. The reference also describes an "offset
recovery" (restart from a later 0x0F inside the rejected 25 bytes); the recorded R7008SB
expectations (80 frames, not 81) show PX4 does not recover that way, so it is off by default
(``offset_recovery=True`` enables it).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

from ioproc.rc.common import IO_MAX_CHANNELS, RcDecoder

SBUS_FRAME_LEN: Final = 25
SBUS_HEADER: Final = 0x0F
#: End bytes PX4 (2015-12+) accepts: S.BUS1 and the four S.BUS2 slot markers.
SBUS_END_BYTES: Final = frozenset((0x00, 0x04, 0x14, 0x24, 0x34))
SBUS_GAP_US_E14: Final = 3000
SBUS_GAP_US_2022: Final = 4000

FLAG_CH17: Final = 0x01
FLAG_CH18: Final = 0x02
FLAG_FRAME_LOST: Final = 0x04
FLAG_FAILSAFE: Final = 0x08

#: PX4 µs for the digital channels 17/18.
SBUS_DIGITAL_ON_US: Final = 1998
SBUS_DIGITAL_OFF_US: Final = 998

#: raw → µs, PX4: (uint16)(raw·0.625f + 0.5f) + 874 (0.625 is exact in float, so this is exact).
SBUS_RAW_TO_US: Final[tuple[int, ...]] = tuple(int(r * 0.625 + 0.5) + 874 for r in range(2048))


def sbus_raw_to_us(raw: int) -> int:
    """PX4's S.BUS scaling (raw 200 → 999 µs, 1800 → 1999 µs)."""
    return SBUS_RAW_TO_US[raw & 0x7FF]


def sbus_raw_to_us_ardupilot(raw: int) -> int:
    """ArduPilot's integer S.BUS scaling (offset 875): 1 µs above PX4 at many points."""
    return raw * 1000 // 1600 + 875


def sbus_us_to_raw(us: int) -> int:
    """Inverse of PX4's scaling (what the IO's S.BUS output does), clamped to 11 bits."""
    return max(0, min(2047, round((us - 874) / 0.625)))


def encode_sbus_frame(raw: Sequence[int], *, ch17: bool = False, ch18: bool = False,
                      frame_lost: bool = False, failsafe: bool = False,
                      end: int = 0x00) -> bytes:
    """Build a 25-byte frame from up to 16 raw 11-bit positions (missing ones are 1024).

    Used by receiver models and tests; the inverse of the decoder's unpacking.
    """
    vals = list(raw[:16]) + [1024] * (16 - min(16, len(raw)))
    packed = 0
    for k, v in enumerate(vals):
        packed |= (int(v) & 0x7FF) << (11 * k)
    flags = ((FLAG_CH17 if ch17 else 0) | (FLAG_CH18 if ch18 else 0)
             | (FLAG_FRAME_LOST if frame_lost else 0) | (FLAG_FAILSAFE if failsafe else 0))
    return bytes((SBUS_HEADER,)) + packed.to_bytes(22, "little") + bytes((flags, end & 0xFF))


class SbusDecoder(RcDecoder):
    """Byte-wise S.BUS/S.BUS2 parser with PX4's scaling and flag handling.

    ``frame_errors`` counts frames PX4 rejects (unknown end byte) plus partial frames cut off by
    a gap; PX4's own drop counter ignores end-byte rejects, which ``bad_end_bytes`` and
    ``partial_frames`` let a caller separate. ``lost_frames`` counts frames that carried the
    receiver's frame-lost flag. ``rssi`` follows PX4 2015+ without an RSSI ADC: 100, or 50 while
    the frame-lost or failsafe flag is set.
    """

    protocol = "sbus"
    min_us = 874
    max_us = 2153

    def __init__(self, gap_us: int = SBUS_GAP_US_E14, *, check_end_byte: bool = True,
                 offset_recovery: bool = False, max_channels: int = IO_MAX_CHANNELS,
                 e14_ch18_bug: bool = False) -> None:
        super().__init__()
        self.offset_recovery = offset_recovery
        self.gap_us = gap_us
        self.check_end_byte = check_end_byte
        #: 18 with the IO's buffer (digital channels reported), else 16.
        self.num_channels = 18 if max_channels >= 18 else 16
        #: E14 reported channel 18 "on" as 2998 µs; off by default.
        self._ch18_on = 2998 if e14_ch18_bug else SBUS_DIGITAL_ON_US
        if e14_ch18_bug:
            self.max_us = 2998
        self.flags = 0
        self.end_byte = 0
        self.bad_end_bytes = 0
        self.partial_frames = 0
        self._buf = bytearray()
        self._last_rx_us: int | None = None

    def _feed_byte(self, t_us: int, b: int) -> bool:
        buf = self._buf
        last = self._last_rx_us
        self._last_rx_us = t_us
        if buf and last is not None and t_us - last > self.gap_us:
            # Silence in the middle of a frame: the rest of it was lost on the line.
            self.partial_frames += 1
            self.frame_errors += 1
            buf.clear()
        if not buf:
            if b == SBUS_HEADER:
                buf.append(b)
            return False
        buf.append(b)
        if len(buf) < SBUS_FRAME_LEN:
            return False
        end = buf[24]
        if self.check_end_byte and end not in SBUS_END_BYTES:
            self.bad_end_bytes += 1
            self.frame_errors += 1
            # Offset recovery: the real frame may start at a later 0x0F we swallowed.
            i = buf.find(SBUS_HEADER, 1) if self.offset_recovery else -1
            if i < 0:
                buf.clear()
            else:
                del buf[:i]
            return False
        self._decode(t_us, buf)
        buf.clear()
        return True

    def _decode(self, t_us: int, buf: bytearray) -> None:
        p = int.from_bytes(buf[1:23], "little")
        raw = [(p >> s) & 0x7FF for s in range(0, 176, 11)]
        tab = SBUS_RAW_TO_US
        us = [tab[r] for r in raw]
        flags = buf[23]
        if self.num_channels == 18:
            us.append(SBUS_DIGITAL_ON_US if flags & FLAG_CH17 else SBUS_DIGITAL_OFF_US)
            us.append(self._ch18_on if flags & FLAG_CH18 else SBUS_DIGITAL_OFF_US)
            raw.append(flags & FLAG_CH17)
            raw.append((flags & FLAG_CH18) >> 1)
        self.flags = flags
        self.end_byte = buf[24]
        self.failsafe = bool(flags & FLAG_FAILSAFE)
        self.frame_lost = bool(flags & FLAG_FRAME_LOST)
        if self.frame_lost:
            self.lost_frames += 1
        self.rssi = 50 if flags & (FLAG_FRAME_LOST | FLAG_FAILSAFE) else 100
        self._publish(t_us, us, raw)

    @property
    def frame_drop(self) -> bool:
        """PX4's ``sbus_frame_drop``: set by the frame-lost flag and also by failsafe."""
        return bool(self.flags & (FLAG_FRAME_LOST | FLAG_FAILSAFE))
