"""Yuneec ST24 decoder (IO DSM port, 115200 8N1; PX4 2014-10+).

Packet: 0x55 0x55, LEN (counts TYPE, DATA and CRC; ≤ 66), TYPE, DATA, CRC-8 (poly 0x07, init
0) over LEN..DATA. Types 0 and 1 carry 12 or 24 channels after a 16-bit counter, an RSSI byte
and a lost-packet count; channels are 12-bit, two per three bytes. Type 2 (transmitter GPS) is
ignored and any other type is counted in ``unknown_packets``, as PX4 returns an error code for
it. Scaling (PX4 2016-08+): µs = (uint16)(v · (1/3.f) + 0.5f) + 832, so 500..3500 → 999..1999;
``scaling="e14"`` gives the earlier (uint16)(v · 1000/4096 + 0.5) + 999.
"""

from __future__ import annotations

from collections.abc import Sequence

from ioproc.rc.common import CRC8_07, RcDecoder, crc8_07, f32

ST24_STX = 0x55
ST24_MAX_LEN = 66
ST24_TYPE_CH12 = 0
ST24_TYPE_CH24 = 1
ST24_TYPE_GPS = 2

_THIRD = f32(1 / 3)
#: 12-bit raw → µs, float32 arithmetic as in PX4 2016-08+.
ST24_TO_US: tuple[int, ...] = tuple(int(f32(f32(v * _THIRD) + 0.5)) + 832 for v in range(4096))
ST24_TO_US_E14: tuple[int, ...] = tuple(int(v * 1000 / 4096 + 0.5) + 999 for v in range(4096))

_SYNC1, _SYNC2, _LEN, _BODY = range(4)


def encode_st24_frame(raw: Sequence[int], *, rssi: int = 200, lost: int = 0,
                      counter: int = 0) -> bytes:
    """ST24 channel packet (12 or 24 channels of 12-bit raw values)."""
    n = 12 if len(raw) <= 12 else 24
    vals = list(raw[:n]) + [2000] * (n - min(n, len(raw)))
    data = bytearray((counter & 0xFF, (counter >> 8) & 0xFF, rssi & 0xFF, lost & 0xFF))
    for a, b in zip(vals[0::2], vals[1::2]):
        data += bytes(((a >> 4) & 0xFF, ((a & 0xF) << 4) | ((b >> 8) & 0xF), b & 0xFF))
    body = bytes((len(data) + 2, ST24_TYPE_CH12 if n == 12 else ST24_TYPE_CH24)) + data
    return bytes((ST24_STX, ST24_STX)) + body + bytes((crc8_07(body),))


class St24Decoder(RcDecoder):
    """Byte-wise ST24 parser.

    ``rssi`` is the packet RSSI scaled to percent (raw·100/255), ``lost_count`` the packet's
    lost-frame count (the IO only uses packets where it is 0) and ``lost_frames`` its sum.
    """

    protocol = "st24"
    min_us = 832
    max_us = 2197

    def __init__(self, *, scaling: str = "px4", max_channels: int = 24) -> None:
        super().__init__()
        if scaling == "px4":
            self._tab = ST24_TO_US
        elif scaling == "e14":
            self._tab = ST24_TO_US_E14
            self.min_us, self.max_us = 999, 1999
        else:
            raise ValueError(f"ST24 scaling must be 'px4' or 'e14', not {scaling!r}")
        self.max_channels = max_channels
        self.rssi_raw = 0
        self.lost_count = 0
        self.counter = 0
        self.unknown_packets = 0
        self.gps_packets = 0
        self._state = _SYNC1
        self._buf = bytearray()
        self._len = 0

    def _feed_byte(self, t_us: int, b: int) -> bool:
        st = self._state
        if st == _SYNC1:
            if b == ST24_STX:
                self._state = _SYNC2
            return False
        if st == _SYNC2:
            self._state = _LEN if b == ST24_STX else _SYNC1
            return False
        if st == _LEN:
            if 2 <= b <= ST24_MAX_LEN:
                self._len = b
                self._buf = bytearray((b,))
                self._state = _BODY
            else:
                self.frame_errors += 1
                self._state = _SYNC2 if b == ST24_STX else _SYNC1
            return False
        buf = self._buf
        buf.append(b)
        if len(buf) <= self._len:
            return False
        self._state = _SYNC1
        crc = 0
        t = CRC8_07
        for x in buf[:-1]:
            crc = t[crc ^ x]
        if crc != buf[-1]:
            self.bad_crc += 1
            return False
        return self._packet(t_us, buf)

    def _packet(self, t_us: int, buf: bytearray) -> bool:
        ptype = buf[1]
        if ptype == ST24_TYPE_GPS:
            self.gps_packets += 1
            return False
        if ptype not in (ST24_TYPE_CH12, ST24_TYPE_CH24):
            self.unknown_packets += 1
            return False
        n = 12 if ptype == ST24_TYPE_CH12 else 24
        data = buf[2:-1]
        if len(data) < 4 + n * 3 // 2:
            self.frame_errors += 1
            return False
        self.counter = data[0] | data[1] << 8
        self.rssi_raw = data[2]
        self.lost_count = data[3]
        self.lost_frames += data[3]
        self.rssi = data[2] * 100 // 255
        raw: list[int] = []
        for i in range(4, 4 + n * 3 // 2, 3):
            b0, b1, b2 = data[i], data[i + 1], data[i + 2]
            raw.append(b0 << 4 | b1 >> 4)
            raw.append((b1 & 0x0F) << 8 | b2)
        raw = raw[:self.max_channels]
        tab = self._tab
        self._publish(t_us, [tab[v] for v in raw], raw)
        return True
