"""Graupner HoTT SUMD/SUMH decoder (IO DSM port, 115200 8N1; PX4 2015-03+).

Frame: 0xA8, status (0x01 SUMD, 0x81 SUMD failsafe, 0x00 SUMH), N (2..32), N big-endian words
in 1/8 µs, then a CRC-16/XMODEM over everything before it (SUMD) or, for SUMH, three bytes that
are kept but not checked followed by an 8-bit additive checksum of header..data. The frame
carries its own length and check, so no timing is needed to frame it; a bad byte costs at most
that frame. PX4 outputs µs = word >> 3 and swaps the first four channels into roll, pitch,
throttle, yaw order (outputs 0..3 = SUMD channels 1, 2, 0, 3).
"""

from __future__ import annotations

from collections.abc import Sequence

from ioproc.rc.common import CRC16_1021, RcDecoder, crc16_xmodem

SUMD_HEADER = 0xA8
SUMD_STATUS_LIVE = 0x01
SUMD_STATUS_FAILSAFE = 0x81
SUMH_STATUS = 0x00
SUMD_MIN_CHANNELS = 2
SUMD_MAX_CHANNELS = 32
SUMH_TAIL = 4  # 2 unused CRC bytes + 1 telemetry byte + 1 checksum

_WAIT, _STATUS, _LEN, _DATA, _TAIL = range(5)


def encode_sumd_frame(us: Sequence[int], *, failsafe: bool = False) -> bytes:
    """SUMD frame for the given channel values in µs (wire order, not PX4's output order)."""
    body = bytearray((SUMD_HEADER, SUMD_STATUS_FAILSAFE if failsafe else SUMD_STATUS_LIVE,
                      len(us)))
    for v in us:
        w = (int(v) * 8) & 0xFFFF
        body += bytes((w >> 8, w & 0xFF))
    crc = crc16_xmodem(body)
    return bytes(body) + bytes((crc >> 8, crc & 0xFF))


class SumdDecoder(RcDecoder):
    """Byte-wise SUMD/SUMH parser.

    ``bad_crc`` counts frames whose CRC/checksum failed, ``frame_errors`` headers followed by an
    unknown status or an impossible channel count. ``failsafe`` is the 0x81 status; RSSI is
    reported as 100 like PX4 (SUMD carries none).
    """

    protocol = "sumd"
    min_us = 0
    max_us = 0xFFFF >> 3

    def __init__(self, max_channels: int = SUMD_MAX_CHANNELS) -> None:
        super().__init__()
        self.max_channels = max_channels
        self.status = 0
        self._state = _WAIT
        self._buf = bytearray()
        self._need = 0

    def _restart(self, b: int) -> None:
        """Drop the frame in progress; the offending byte may itself be a header."""
        self._buf.clear()
        if b == SUMD_HEADER:
            self._buf.append(b)
            self._state = _STATUS
        else:
            self._state = _WAIT

    def _feed_byte(self, t_us: int, b: int) -> bool:
        st = self._state
        buf = self._buf
        if st == _WAIT:
            if b == SUMD_HEADER:
                buf.clear()
                buf.append(b)
                self._state = _STATUS
            return False
        if st == _STATUS:
            if b in (SUMD_STATUS_LIVE, SUMD_STATUS_FAILSAFE, SUMH_STATUS):
                buf.append(b)
                self._state = _LEN
            else:
                self.frame_errors += 1
                self._restart(b)
            return False
        if st == _LEN:
            if SUMD_MIN_CHANNELS <= b <= SUMD_MAX_CHANNELS:
                buf.append(b)
                self._need = 3 + 2 * b
                self._state = _DATA
            else:
                self.frame_errors += 1
                self._restart(b)
            return False
        buf.append(b)
        if st == _DATA:
            if len(buf) == self._need:
                self._state = _TAIL
                self._need += SUMH_TAIL if buf[1] == SUMH_STATUS else 2
            return False
        if len(buf) < self._need:
            return False
        self._state = _WAIT
        return self._finish(t_us)

    def _finish(self, t_us: int) -> bool:
        buf = self._buf
        n = buf[2]
        end = 3 + 2 * n
        if buf[1] == SUMH_STATUS:
            ok = (sum(buf[:end]) & 0xFF) == buf[-1]
        else:
            crc = 0
            t = CRC16_1021
            for x in buf[:end]:
                crc = ((crc << 8) & 0xFFFF) ^ t[(crc >> 8) ^ x]
            ok = crc == (buf[end] << 8 | buf[end + 1])
        if not ok:
            self.bad_crc += 1
            return False
        words = [(buf[i] << 8 | buf[i + 1]) for i in range(3, end, 2)]
        src = words + [0] * max(0, 4 - n)
        out = [src[1], src[2], src[0], src[3]] + src[4:]
        raw = out[:min(n, self.max_channels)]
        self.status = buf[1]
        self.failsafe = buf[1] == SUMD_STATUS_FAILSAFE
        self.rssi = 100
        self._publish(t_us, [w >> 3 for w in raw], raw)
        return True
