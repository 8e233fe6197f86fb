"""Payload encoders: a :class:`Solution` as UBX payloads and NMEA sentences.

Layouts follow the reference sheet (sensors.md section 8.6/8.7); every multi-byte field is
little-endian. Values are rounded to the message's units here, at the edge, so the solution
stays in SI units.
"""

from __future__ import annotations

import datetime
import struct
from typing import Final

from peripherals.ublox.frame import nmea_sentence
from peripherals.ublox.solution import NS_PER_S, Solution

__all__ = [
    "EXTENSIONS",
    "HW_VERSION",
    "SW_VERSION",
    "mon_hw",
    "mon_ver",
    "nav_dop",
    "nav_pvt",
    "nav_sat",
    "nav_status",
    "nav_svinfo",
    "nmea_messages",
]

SW_VERSION: Final = "ROM CORE 3.01 (107888)"
HW_VERSION: Final = "00080000"
EXTENSIONS: Final[tuple[str, ...]] = ("FWVER=SPG 3.01", "PROTVER=18.00", "MOD=NEO-M8N-0")

_U4_MAX: Final = 0xFFFFFFFF
_UNIX_EPOCH: Final = datetime.datetime(1970, 1, 1)


def _u4(x: float) -> int:
    return max(0, min(_U4_MAX, round(x)))


def _utc(sol: Solution) -> tuple[datetime.datetime, int]:
    """Calendar time of the solution (integer arithmetic from the fixed start epoch)."""
    s, ns = divmod(sol.utc_ns, NS_PER_S)
    return _UNIX_EPOCH + datetime.timedelta(seconds=s), ns


def nav_pvt(sol: Solution) -> bytes:
    """UBX-NAV-PVT, 92 bytes (u-blox 8 form)."""
    dt, ns = _utc(sol)
    valid = 0x07 if sol.time_valid else 0x00  # validDate, validTime, fullyResolved
    flags = 0x01 if sol.fix_ok else 0x00     # gnssFixOK
    flags2 = 0xE0 if sol.time_valid else 0x00  # confirmedAvai, confirmedDate, confirmedTime
    vn, ve, vd = sol.vel_ned_m_s
    head = sol.heading_deg if sol.fix_ok else 0.0
    p = struct.pack(
        "<IHBBBBBBIiBBBBiiiiIIiiiiiIIH6sihH",
        sol.itow_ms, dt.year, dt.month, dt.day, dt.hour, dt.minute, dt.second, valid,
        _u4(30 if sol.fix_ok else 1e9), ns,
        sol.fix_type, flags, flags2, sol.num_sv,
        round(sol.lon_deg * 1e7), round(sol.lat_deg * 1e7),
        round(sol.height_m * 1e3), round(sol.hmsl_m * 1e3),
        _u4(sol.h_acc_m * 1e3), _u4(sol.v_acc_m * 1e3),
        round(vn * 1e3), round(ve * 1e3), round(vd * 1e3), round(sol.ground_speed_m_s * 1e3),
        round(head * 1e5), _u4(sol.s_acc_m_s * 1e3), _u4(sol.head_acc_deg * 1e5),
        min(9999, round(sol.pdop * 100)), b"\0" * 6, 0, 0, 0)
    assert len(p) == 92
    return p


def nav_dop(sol: Solution) -> bytes:
    """UBX-NAV-DOP, 18 bytes: gDOP, pDOP, tDOP, vDOP, hDOP, nDOP, eDOP in 0.01."""
    def d(x: float) -> int:
        return min(9999, round(x * 100))
    tdop = 0.8 * sol.hdop
    return struct.pack("<I7H", sol.itow_ms, d((sol.pdop ** 2 + tdop ** 2) ** 0.5), d(sol.pdop),
                       d(tdop), d(sol.vdop), d(sol.hdop), d(0.7 * sol.hdop), d(0.7 * sol.hdop))


def nav_status(sol: Solution, msss_ms: int) -> bytes:
    """UBX-NAV-STATUS, 16 bytes."""
    flags = (0x01 if sol.fix_ok else 0) | (0x0C if sol.time_valid else 0)  # gpsFixOk, wkn/towSet
    return struct.pack("<IBBBBII", sol.itow_ms, sol.fix_type, flags, 0, 0, sol.ttff_ms,
                       msss_ms & _U4_MAX)


def nav_svinfo(sol: Solution) -> bytes:
    """UBX-NAV-SVINFO: 8-byte header plus 12 bytes per channel (u-blox 8 global flags 4)."""
    out = [struct.pack("<IBBH", sol.itow_ms, len(sol.sats), 4, 0)]
    for ch, s in enumerate(sol.sats):
        flags = (0x01 if s.used else 0) | 0x0C  # svUsed, orbit info (ephemeris)
        quality = 7 if s.used else (4 if s.cno_dbhz else 0)
        out.append(struct.pack("<BBBBBbhi", ch, s.svid, flags, quality, s.cno_dbhz,
                               s.elev_deg, s.azim_deg, 0))
    return b"".join(out)


def nav_sat(sol: Solution) -> bytes:
    """UBX-NAV-SAT (version 1): 8-byte header plus 12 bytes per satellite."""
    out = [struct.pack("<IBBH", sol.itow_ms, 1, len(sol.sats), 0)]
    for s in sol.sats:
        quality = 7 if s.used else (4 if s.cno_dbhz else 0)
        flags = quality | (0x08 if s.used else 0) | (1 << 4)  # qualityInd, svUsed, healthy
        out.append(struct.pack("<BBBbhhI", s.gnss_id, s.svid, s.cno_dbhz, s.elev_deg,
                               s.azim_deg, 0, flags))
    return b"".join(out)


def mon_hw(sol: Solution) -> bytes:
    """UBX-MON-HW, 60 bytes: noise level, AGC count, antenna status, jamming indicator."""
    p = struct.pack("<IIIIHHBBBBI17sBHIII", 0, 0, 0, 0, min(0xFFFF, sol.noise_per_ms),
                    min(8191, sol.agc_cnt), 2, 1, 0x01, 0, 0, bytes(range(17)), sol.jam_ind,
                    0, 0, 0, 0)
    assert len(p) == 60
    return p


def mon_ver() -> bytes:
    """UBX-MON-VER: sw (30), hw (10) and extension strings (30 each), NUL padded."""
    def pad(s: str, n: int) -> bytes:
        return s.encode("ascii")[:n - 1].ljust(n, b"\0")
    return pad(SW_VERSION, 30) + pad(HW_VERSION, 10) + b"".join(pad(e, 30) for e in EXTENSIONS)


# -- NMEA -------------------------------------------------------------------------------------

def _lat(deg: float) -> str:
    a = abs(deg)
    d = int(a)
    return f"{d:02d}{(a - d) * 60:08.5f},{'N' if deg >= 0 else 'S'}"


def _lon(deg: float) -> str:
    a = abs(deg)
    d = int(a)
    return f"{d:03d}{(a - d) * 60:08.5f},{'E' if deg >= 0 else 'W'}"


def _hms(sol: Solution) -> str:
    dt, ns = _utc(sol)
    return f"{dt.hour:02d}{dt.minute:02d}{dt.second:02d}.{ns // 10_000_000:02d}"


def nmea_messages(sol: Solution, msg_id: int) -> list[bytes]:
    """The sentence(s) of one NMEA message id (0 GGA .. 5 VTG) for this epoch."""
    ok = sol.fix_ok
    t = _hms(sol) if sol.time_valid else ""
    pos = f"{_lat(sol.lat_deg)},{_lon(sol.lon_deg)}" if ok else ",,,"
    knots = sol.ground_speed_m_s * 1.943844
    course = f"{sol.heading_deg:.2f}" if ok else ""
    mode = "A" if ok else "N"
    if msg_id == 0x00:  # GGA
        alt = f"{sol.hmsl_m:.1f},M,{sol.height_m - sol.hmsl_m:.1f},M" if ok else ",,,"
        hdop = f"{sol.hdop:.2f}" if ok else "99.99"
        return [nmea_sentence(f"GNGGA,{t},{pos},{1 if ok else 0},{sol.num_sv:02d},{hdop},"
                              f"{alt},,")]
    if msg_id == 0x01:  # GLL
        return [nmea_sentence(f"GNGLL,{pos},{t},{'A' if ok else 'V'},{mode}")]
    if msg_id == 0x02:  # GSA
        used = [f"{s.svid:02d}" for s in sol.sats if s.used][:12]
        used += [""] * (12 - len(used))
        return [nmea_sentence(f"GNGSA,A,{sol.fix_type if ok else 1},{','.join(used)},"
                              f"{sol.pdop:.2f},{sol.hdop:.2f},{sol.vdop:.2f}")]
    if msg_id == 0x03:  # GSV, four satellites per sentence
        sats = sol.sats
        n = max(1, (len(sats) + 3) // 4)
        out = []
        for i in range(n):
            parts = [f"GPGSV,{n},{i + 1},{len(sats):02d}"]
            for s in sats[4 * i:4 * i + 4]:
                cno = f"{s.cno_dbhz:02d}" if s.cno_dbhz else ""
                parts.append(f"{s.svid:02d},{s.elev_deg:02d},{s.azim_deg:03d},{cno}")
            out.append(nmea_sentence(",".join(parts)))
        return out
    if msg_id == 0x04:  # RMC
        dt, _ = _utc(sol)
        date = f"{dt.day:02d}{dt.month:02d}{dt.year % 100:02d}" if sol.time_valid else ""
        return [nmea_sentence(f"GNRMC,{t},{'A' if ok else 'V'},{pos},{knots:.3f},{course},"
                              f"{date},,,{mode}")]
    if msg_id == 0x05:  # VTG
        return [nmea_sentence(f"GNVTG,{course},T,,M,{knots:.3f},N,{knots * 1.852:.3f},K,"
                              f"{mode}")]
    return []
