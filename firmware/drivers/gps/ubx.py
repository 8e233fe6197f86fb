"""UBX protocol pieces of the flight-stack side: framing, a resynchronising parser, the
configuration messages the driver sends, and decoders of the messages it reads.

Independent of the receiver model's own framing on purpose (the two ends must agree only
through bytes on the wire).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

__all__ = [
    "CLS_ACK",
    "CLS_CFG",
    "CLS_MON",
    "CLS_NAV",
    "ID_ACK_ACK",
    "ID_ACK_NAK",
    "ID_CFG_GNSS",
    "ID_CFG_MSG",
    "ID_CFG_NAV5",
    "ID_CFG_PRT",
    "ID_CFG_RATE",
    "ID_CFG_VALSET",
    "ID_MON_HW",
    "ID_MON_VER",
    "ID_NAV_DOP",
    "ID_NAV_PVT",
    "ID_NAV_STATUS",
    "ID_NAV_SVINFO",
    "MonVer",
    "NavPvt",
    "UbxParser",
    "cfg_gnss",
    "cfg_msg",
    "cfg_nav5",
    "cfg_prt",
    "cfg_rate",
    "cfg_valset_uart1",
    "fletcher8",
    "frame",
]

CLS_NAV, CLS_ACK, CLS_CFG, CLS_MON = 0x01, 0x05, 0x06, 0x0A
ID_ACK_NAK, ID_ACK_ACK = 0x00, 0x01
ID_NAV_STATUS, ID_NAV_DOP, ID_NAV_PVT, ID_NAV_SVINFO = 0x03, 0x04, 0x07, 0x30
ID_CFG_PRT, ID_CFG_MSG, ID_CFG_RATE, ID_CFG_NAV5 = 0x00, 0x01, 0x08, 0x24
ID_CFG_GNSS, ID_CFG_VALSET = 0x3E, 0x8A
ID_MON_VER, ID_MON_HW = 0x04, 0x09

#: The driver's receive buffer for one message; longer announced lengths are garbage.
MAX_PAYLOAD = 512


def fletcher8(data: bytes | bytearray) -> int:
    """UBX checksum as one 16-bit value CK_A | CK_B << 8."""
    ck_a = ck_b = 0
    for x in data:
        ck_a = (ck_a + x) & 0xFF
        ck_b = (ck_b + ck_a) & 0xFF
    return ck_a | (ck_b << 8)


def frame(cls: int, msg_id: int, payload: bytes = b"") -> bytes:
    head = struct.pack("<BBH", cls, msg_id, len(payload)) + payload
    return b"\xb5\x62" + head + struct.pack("<H", fletcher8(head))


class UbxParser:
    """Byte-at-a-time decoder in the shape of PX4's (sync1, sync2, header, payload, ck).

    On a bad checksum or an impossible length the frame is dropped and decoding restarts at
    the next sync byte, so NMEA text or bytes read at the wrong baud rate cost only themselves.
    """

    _SYNC1, _SYNC2, _HEAD, _BODY = range(4)

    def __init__(self) -> None:
        self.bad_checksum = 0
        self.bad_length = 0
        self.frames = 0
        self.reset()

    def reset(self) -> None:
        self._state = self._SYNC1
        self._acc = bytearray()
        self._need = 0

    def feed(self, data: bytes) -> list[tuple[int, int, bytes]]:
        out: list[tuple[int, int, bytes]] = []
        for x in data:
            st = self._state
            if st == self._SYNC1:
                if x == 0xB5:
                    self._state = self._SYNC2
            elif st == self._SYNC2:
                self._state = self._HEAD if x == 0x62 else (self._SYNC2 if x == 0xB5
                                                            else self._SYNC1)
                self._acc = bytearray()
            elif st == self._HEAD:
                self._acc.append(x)
                if len(self._acc) == 4:
                    n = self._acc[2] | (self._acc[3] << 8)
                    if n > MAX_PAYLOAD:
                        self.bad_length += 1
                        self._state = self._SYNC1
                    else:
                        self._need = 4 + n + 2
                        self._state = self._BODY
            else:
                self._acc.append(x)
                if len(self._acc) == self._need:
                    self._state = self._SYNC1
                    body = bytes(self._acc[:-2])
                    if fletcher8(body) != (self._acc[-2] | (self._acc[-1] << 8)):
                        self.bad_checksum += 1
                        continue
                    self.frames += 1
                    out.append((body[0], body[1], body[4:]))
        return out


@dataclass
class NavPvt:
    itow_ms: int
    year: int
    month: int
    day: int
    hour: int
    minute: int
    sec: int
    valid: int
    t_acc_ns: int
    nano_ns: int
    fix_type: int
    flags: int
    flags2: int
    num_sv: int
    lon_e7: int
    lat_e7: int
    height_mm: int
    hmsl_mm: int
    h_acc_mm: int
    v_acc_mm: int
    vel_n_mm_s: int
    vel_e_mm_s: int
    vel_d_mm_s: int
    g_speed_mm_s: int
    head_mot_e5: int
    s_acc_mm_s: int
    head_acc_e5: int
    pdop_e2: int
    head_veh_e5: int = 0

    _FMT = "<IHBBBBBBIiBBBBiiiiIIiiiiiIIH"

    @classmethod
    def decode(cls, p: bytes) -> NavPvt | None:
        """u-blox 8 (92 bytes) or u-blox 7 (84 bytes) NAV-PVT; None for any other length."""
        if len(p) not in (84, 92):
            return None
        fields = struct.unpack_from(cls._FMT, p)
        head_veh = struct.unpack_from("<i", p, 84)[0] if len(p) == 92 else 0
        return cls(*fields, head_veh)


@dataclass
class MonVer:
    sw: str
    hw: str
    extensions: list[str]

    @classmethod
    def decode(cls, p: bytes) -> MonVer | None:
        if len(p) < 40 or (len(p) - 40) % 30:
            return None

        def text(b: bytes) -> str:
            return b.split(b"\0", 1)[0].decode("ascii", "replace")
        exts = [text(p[i:i + 30]) for i in range(40, len(p), 30)]
        return cls(text(p[:30]), text(p[30:40]), exts)


# -- configuration messages -------------------------------------------------------------------

_MODE_8N1 = 0x000008D0
_IN_UBX_RTCM3, _OUT_UBX = 0x0021, 0x0001


def cfg_prt(baud: int) -> bytes:
    """CFG-PRT for UART1 and USB (two blocks, PX4's form): 8N1, UBX+RTCM3 in, UBX out."""
    block = b"".join(struct.pack("<BBHIIHHHH", port, 0, 0, _MODE_8N1, baud, _IN_UBX_RTCM3,
                                 _OUT_UBX, 0, 0) for port in (1, 3))
    return frame(CLS_CFG, ID_CFG_PRT, block)


def cfg_rate(meas_ms: int, nav_rate: int = 1, time_ref: int = 0) -> bytes:
    return frame(CLS_CFG, ID_CFG_RATE, struct.pack("<HHH", meas_ms, nav_rate, time_ref))


def cfg_nav5(dyn_model: int, fix_mode: int = 2) -> bytes:
    """Only dynModel and fixMode are applied (mask 0x0005); the rest is ignored by the chip."""
    payload = struct.pack("<HBB", 0x0005, dyn_model, fix_mode) + bytes(32)
    return frame(CLS_CFG, ID_CFG_NAV5, payload)


def cfg_msg(cls: int, msg_id: int, rate: int) -> bytes:
    return frame(CLS_CFG, ID_CFG_MSG, bytes((cls, msg_id, rate)))


def cfg_gnss(enable_mask: int) -> bytes:
    """CFG-GNSS with the 7 blocks; bit i of ``enable_mask`` enables gnssId i (GPS=bit 0)."""
    blocks = ((0, 8, 16), (1, 1, 3), (2, 4, 8), (3, 8, 16), (4, 0, 8), (5, 0, 3), (6, 8, 14))
    body = bytes((0, 0, 0xFF, len(blocks)))
    for gid, res, mx in blocks:
        body += struct.pack("<BBBBI", gid, res, mx, 0,
                            0x00010000 | (1 if enable_mask >> gid & 1 else 0))
    return frame(CLS_CFG, ID_CFG_GNSS, body)


def cfg_valset_uart1() -> bytes:
    """CFG-VALSET (protocol >= 27) of the UART1 format and protocols, in RAM; an M8 NAKs it."""
    items = ((0x20520002, 1), (0x20520003, 0), (0x20520004, 0), (0x10730001, 1),
             (0x10730002, 0), (0x10740001, 1), (0x10740002, 0))
    body = bytes((0, 1, 0, 0)) + b"".join(struct.pack("<IB", k, v) for k, v in items)
    return frame(CLS_CFG, ID_CFG_VALSET, body)
