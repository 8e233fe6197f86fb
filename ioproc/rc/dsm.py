"""Spektrum DSM2/DSMX satellite decoder as the PX4IO runs it on USART1 (115200 8N1).

A frame is 16 bytes: fades/RSSI, system byte, then seven big-endian servo words. The system
byte is not trusted (external remotes report nothing useful), so the resolution is guessed from
the channel-ID bit patterns, as PX4 does since 2022-04: each frame is decoded both as 10-bit
(ID in bits 15..10) and 11-bit (ID in bits 14..11, X-Plus on ID 12); after 15 frames the mode
whose IDs are duplicate-free, contiguous from 0, at least 5, and each seen often enough wins,
and the channel count is fixed to the number of IDs seen. The learned count is kept when the
guess is cleared, and the frame on which a guess succeeds is checked against the count from
*before* the guess (PX4 passes it by value); with nothing learned yet that frame is rejected as
one drop. ``px4_count_quirk=False`` drops this quirk. It is what makes every PX4 capture report
exactly one extra drop, so it is on by default.

Framing is by silence: when desynchronised a byte starts a frame only after more than 5 ms
without bytes; once in sync every 16 bytes are a frame until a decode fails.

Spektrum IDs 0, 1, 2 (throttle, aileron, elevator) go to output slots 2, 0, 1 (roll, pitch,
throttle, yaw, ...). A receiver with more than 7 channels spreads them over frames; a frame is
output only when every channel of the learned count was refreshed within the last 50 ms.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from ioproc.rc.common import IO_MAX_CHANNELS, RcDecoder, f32, roundf

DSM_FRAME_LEN = 16
DSM_GAP_US = 5000
DSM_GUESS_FRAMES = 15
DSM_GUESS_RESET_US = 1_000_000
DSM_STALE_US = 50_000
DSM_MAX_IDS = 20

_BLANK = -1
_INVALID = -2


def _e14_us(pos11: int) -> int:
    """PX4 before 2020-08 (and ArduPilot): (pos − 1024)·1000/1700 + 1500, C truncation."""
    d = (pos11 - 1024) * 1000
    q = abs(d) // 1700
    return 1500 + (q if d >= 0 else -q)


#: 2021+ PX4: roundf(pos · 0.583f) + 903 (11-bit), roundf(pos · 1.166f) + 903 (10-bit).
DSM11_TO_US: tuple[int, ...] = tuple(roundf(f32(p * f32(0.583))) + 903 for p in range(2048))
DSM10_TO_US: tuple[int, ...] = tuple(roundf(f32(p * f32(1.166))) + 903 for p in range(1024))
DSM11_TO_US_E14: tuple[int, ...] = tuple(_e14_us(p) for p in range(2048))
DSM10_TO_US_E14: tuple[int, ...] = tuple(_e14_us(2 * p) for p in range(1024))

#: Spektrum ID → output slot (throttle, aileron, elevator → 2, 0, 1).
_REMAP = (2, 0, 1) + tuple(range(3, DSM_MAX_IDS))


def decode_word11(w: int) -> tuple[int, int]:
    """(channel ID, 11-bit position) of a 2048-mode word; ID _BLANK or _INVALID otherwise."""
    phase = w >> 15
    cid = (w >> 11) & 0xF
    if cid < 12:
        return cid, w & 0x7FF
    if cid == 12:  # X-Plus: sub-channel in bits 10..9, phase selects the upper four
        return 12 + ((w >> 9) & 3) + (4 if phase else 0), (w & 0x1FF) << 2
    if cid == 15 and phase:
        return _BLANK, 0
    return _INVALID, 0


def decode_word10(w: int) -> tuple[int, int]:
    """(channel ID, 10-bit position) of a 1024-mode word; 0xFFFF is an empty slot."""
    if w == 0xFFFF:
        return _BLANK, 0
    cid = w >> 10
    if cid < DSM_MAX_IDS:
        return cid, w & 0x3FF
    return _INVALID, 0


def dsm_rssi_percent(byte0: int) -> int | None:
    """RSSI from byte 0: negative (signed) = dBm → percent; non-negative = fade count → None."""
    dbm = byte0 - 256 if byte0 & 0x80 else byte0
    if dbm >= 0:
        return None
    if dbm == -128:
        return 0
    arg = 1 + (dbm + 92) * 9 / 50
    if arg <= 1:
        return 0
    return max(0, min(100, roundf(100 * math.log10(arg))))


def dsm_word(cid: int, pos: int, *, bits: int = 11, phase: bool = False) -> int:
    """Servo word for channel ``cid`` (0..11 or 0..19 for 10-bit) at ``pos``."""
    if bits == 10:
        return ((cid & 0x3F) << 10) | (pos & 0x3FF)
    return (0x8000 if phase else 0) | ((cid & 0xF) << 11) | (pos & 0x7FF)


def encode_dsm_frame(words: Sequence[int], *, fades: int = 0, system: int = 0xB2) -> bytes:
    """16-byte frame from up to 7 servo words (missing slots are 0xFFFF)."""
    ws = list(words[:7]) + [0xFFFF] * (7 - min(7, len(words)))
    out = bytearray((fades & 0xFF, system & 0xFF))
    for w in ws:
        out += bytes(((w >> 8) & 0xFF, w & 0xFF))
    return bytes(out)


class _Guess:
    """Per-mode evidence for the resolution guess."""

    __slots__ = ("good", "seen", "union")

    def __init__(self) -> None:
        self.good = 0
        self.union = 0
        self.seen = [0] * DSM_MAX_IDS

    def add(self, ids_mask: int, dup: bool) -> None:
        seen = self.seen
        m = ids_mask
        i = 0
        while m:
            if m & 1:
                seen[i] += 1
            m >>= 1
            i += 1
        if not dup:
            self.good += 1
            self.union |= ids_mask

    def channels(self, samples: int) -> int:
        """Channel count this mode explains, or 0 if its evidence is not convincing."""
        n = self.union.bit_length()
        if self.union != (1 << n) - 1 or n < 5 or self.good <= samples - 5:
            return 0
        if any(self.seen[i] < 4 for i in range(min(n, 12))):
            return 0
        return n


class DsmDecoder(RcDecoder):
    """DSM2/DSMX decoder with PX4's resolution guess, drop counting and channel merging.

    ``frame_errors`` is PX4's frame-drop counter; ``dsm_11bit`` the RC_DSM11 status bit;
    ``rssi`` is a percentage when byte 0 carries dBm (telemetry satellites), else None and
    ``fades`` holds the receiver's fade count (also mirrored into ``lost_frames``).
    ``scaling="e14"`` gives PX4's pre-2020-08 µs formula, which is also ArduPilot's.
    """

    protocol = "dsm"
    min_us = 898
    max_us = 2101

    def __init__(self, *, scaling: str = "px4", px4_count_quirk: bool = True,
                 max_channels: int = IO_MAX_CHANNELS, gap_us: int = DSM_GAP_US) -> None:
        super().__init__()
        if scaling == "px4":
            self._tab11, self._tab10 = DSM11_TO_US, DSM10_TO_US
            self.min_us, self.max_us = 903, 2097
        elif scaling == "e14":
            self._tab11, self._tab10 = DSM11_TO_US_E14, DSM10_TO_US_E14
        else:
            raise ValueError(f"DSM scaling must be 'px4' or 'e14', not {scaling!r}")
        self.px4_count_quirk = px4_count_quirk
        self.max_channels = max_channels
        self.gap_us = gap_us
        self.fades = 0
        self.system = 0
        #: 11 or 10 once the resolution is known, else None.
        self.mode: int | None = None
        #: Channel count learned by the last successful guess (kept when the guess is cleared).
        self.learned_count = 0
        self._buf = bytearray()
        self._sync = False
        self._last_rx_us: int | None = None
        self._last_decode_us: int | None = None
        self._values = [0] * DSM_MAX_IDS
        self._raw = [0] * DSM_MAX_IDS
        self._updated = [0] * DSM_MAX_IDS
        self._reset_guess()

    @property
    def dsm_11bit(self) -> bool:
        return self.mode == 11

    def _reset_guess(self) -> None:
        self.mode = None
        self._samples = 0
        self._g11 = _Guess()
        self._g10 = _Guess()

    def _feed_byte(self, t_us: int, b: int) -> bool:
        buf = self._buf
        if self._sync:
            buf.append(b)
        else:
            last = self._last_rx_us
            if last is not None and t_us - last <= self.gap_us:
                self._last_rx_us = t_us
                return False
            self._sync = True
            buf.clear()
            buf.append(b)
        if len(buf) < DSM_FRAME_LEN:
            self._last_rx_us = t_us
            return False
        ok = self._decode(t_us, buf)
        buf.clear()
        if not ok:
            self._sync = False
            self._last_rx_us = t_us
            return False
        count = self.learned_count
        updated, values = self._updated, self._values
        for i in range(count):
            if values[i] == 0 or t_us - updated[i] > DSM_STALE_US:
                return False  # not all channels fresh yet; PX4 also skips the rx-time update
        n = min(count, self.max_channels)
        self._publish(t_us, values[:n], self._raw[:n])
        self._last_rx_us = t_us
        return True

    def _guess(self, words: list[int]) -> int | None:
        """Add a frame's evidence; the resolution once it is known (also in ``mode``)."""
        self._samples += 1
        for g, dec in ((self._g11, decode_word11), (self._g10, decode_word10)):
            mask = 0
            dup = False
            for w in words:
                cid = dec(w)[0]
                if cid < 0:
                    continue
                bit = 1 << cid
                if mask & bit:
                    dup = True
                mask |= bit
            g.add(mask, dup)
        if self._samples < DSM_GUESS_FRAMES:
            return None
        for mode, g in ((11, self._g11), (10, self._g10)):
            n = g.channels(self._samples)
            if n:
                self.mode = mode
                self.learned_count = n
                return mode
        self._reset_guess()
        return None

    def _decode(self, t_us: int, buf: bytearray) -> bool:
        """Decode one 16-byte frame; False means resynchronise (and maybe a drop)."""
        last = self._last_decode_us
        if last is not None and t_us - last > DSM_GUESS_RESET_US:
            self._reset_guess()
        self._last_decode_us = t_us
        words = [(buf[i] << 8) | buf[i + 1] for i in range(2, DSM_FRAME_LEN, 2)]
        count = self.learned_count
        # The mode goes through a local: after ``self.mode is None`` mypy keeps ``self.mode``
        # narrowed to None across the call that sets it, and mypyc's compiled check of that
        # narrowed type raised TypeError on the guess's frame.
        mode = self.mode
        if mode is None:
            mode = self._guess(words)
            if mode is None:
                return False  # frames used for guessing are not output (and not drops)
            if not self.px4_count_quirk:
                count = self.learned_count
        if mode == 11:
            dec, tab = decode_word11, self._tab11
        else:
            dec, tab = decode_word10, self._tab10
        mask = 0
        got: list[tuple[int, int]] = []
        for w in words:
            cid, pos = dec(w)
            if cid == _BLANK:
                continue
            if cid == _INVALID:
                self.frame_errors += 1
                return False
            bit = 1 << cid
            if cid >= count or mask & bit:
                self.frame_errors += 1
                self._reset_guess()
                return False
            mask |= bit
            got.append((cid, pos))
        values, raw, updated = self._values, self._raw, self._updated
        for cid, pos in got:
            slot = _REMAP[cid]
            values[slot] = tab[pos]
            raw[slot] = pos
            updated[slot] = t_us
        b0 = buf[0]
        self.system = buf[1]
        rssi = dsm_rssi_percent(b0)
        if rssi is None:
            self.fades = b0
            self.lost_frames = b0
        self.rssi = rssi
        return True
