"""Fuzzing the u-blox receive path of the GPS driver: UBX and NMEA streams, random and mutated."""

from __future__ import annotations

import math
import struct

from hypothesis import given
from hypothesis import strategies as st

from board.kernel import Kernel
from board.uart import Uart, UartConfig
from firmware.drivers.gps import GpsDriver
from firmware.drivers.gps import ubx
from firmware.platform import Platform
from firmware.platform.uorb import Subscription
from tests.fuzzing import fuzz


def _nav_pvt(lat_e7: int = 473_977_418, lon_e7: int = 85_455_939, flags: int = 0x01,
             valid: int = 0x07, month: int = 11, size: int = 92) -> bytes:
    body = struct.pack(ubx.NavPvt._FMT, 1000, 2026, month, 22, 12, 0, 0, valid, 50, 0, 3,
                       flags, 0, 12, lon_e7, lat_e7, 500_000, 488_000, 900, 1500, 100, -200,
                       30, 224, 0, 200, 1_000_000, 120)
    payload = body.ljust(84, b"\0") + struct.pack("<ihH", 0, 0, 0)  # headVeh, magDec, magAcc
    return ubx.frame(ubx.CLS_NAV, ubx.ID_NAV_PVT, payload[:size])


VALID = [
    _nav_pvt(), _nav_pvt(lat_e7=-900_000_000, lon_e7=1_800_000_000, flags=0xC3, size=84),
    _nav_pvt(valid=0x07, month=0), _nav_pvt(lat_e7=-(2 ** 31), lon_e7=2 ** 31 - 1),
    ubx.frame(ubx.CLS_MON, ubx.ID_MON_VER, b"ROM CORE 3.01\0".ljust(30, b"\0") +
              b"00080000\0\0" + b"PROTVER=18.00".ljust(30, b"\0")),
    ubx.frame(ubx.CLS_NAV, ubx.ID_NAV_DOP, bytes(range(18))),
    ubx.frame(ubx.CLS_MON, ubx.ID_MON_HW, bytes(range(60))),
    ubx.frame(ubx.CLS_ACK, ubx.ID_ACK_ACK, bytes((ubx.CLS_CFG, ubx.ID_CFG_PRT))),
    b"$GNRMC,120000.00,A,4723.86451,N,00833.00000,E,0.004,,221126,,,A*6B\r\n",
    b"$GNGGA,120000.00,4723.86451,N,00833.00000,E,1,12,0.9,488.0,M,47.0,M,,*4F\r\n",
]


@st.composite
def streams(draw: st.DrawFn) -> bytes:
    """Random bytes, or real frames with bit flips, cuts, inserted sync bytes and splices."""
    if draw(st.integers(0, 3)) == 0:
        return draw(st.binary(max_size=400))
    buf = bytearray(b"".join(draw(st.lists(st.sampled_from(VALID), min_size=1, max_size=8))))
    for _ in range(draw(st.integers(0, 6))):
        i = draw(st.integers(0, len(buf)))
        op = draw(st.sampled_from(["flip", "cut", "sync", "junk"]))
        if op == "flip" and i < len(buf):
            buf[i] ^= 1 << draw(st.integers(0, 7))
        elif op == "cut":
            del buf[i:i + draw(st.integers(1, 40))]
        elif op == "sync":
            buf[i:i] = b"\xb5\x62" + draw(st.binary(max_size=6))
        else:
            buf[i:i] = draw(st.binary(max_size=20))
    return bytes(buf)


def _valid_pvts(data: bytes) -> int:
    """How many checksum-valid NAV-PVT frames of a decodable length the stream holds."""
    n = 0
    for i in range(len(data) - 7):
        if data[i:i + 4] != b"\xb5\x62\x01\x07":
            continue
        size = data[i + 4] | data[i + 5] << 8
        end = i + 6 + size + 2
        if size in (84, 92) and end <= len(data) and ubx.fletcher8(data[i + 2:end - 2]) == (
                data[end - 2] | data[end - 1] << 8):
            n += 1
    return n


@fuzz(examples=300)
@given(streams(), st.integers(1, 64))
def test_any_stream_publishes_only_checksummed_finite_fixes(data: bytes, chunk: int) -> None:
    """Invariant: feeding any bytes, in any chunking, to the configured driver's UBX parser
    and message handler never raises; sensor_gps is published only for checksum-valid NAV-PVT
    frames, and every published value is finite with latitude and longitude as e7 integers in
    the int32 range."""
    k = Kernel("fmu")
    p = Platform(k)
    drv = GpsDriver(p, Uart(k, "ttyS3", UartConfig(115200)))
    drv.configured = True
    sub = Subscription(p.orb, "sensor_gps")
    published = []
    for i in range(0, len(data), chunk):
        for cls, msg_id, payload in drv.parser.feed(data[i:i + chunk]):
            drv._on_message(cls, msg_id, payload)
            if sub.updated():
                published.append(sub.copy())
    assert drv.publish_count == len(published) <= _valid_pvts(data)
    for m in published:
        assert -(2 ** 31) <= m.lat < 2 ** 31 and -(2 ** 31) <= m.lon < 2 ** 31
        for name in ("latitude_deg", "longitude_deg", "altitude_msl_m", "eph", "epv",
                     "vel_m_s", "vel_n_m_s", "vel_e_m_s", "vel_d_m_s", "cog_rad"):
            assert math.isfinite(getattr(m, name)), name
