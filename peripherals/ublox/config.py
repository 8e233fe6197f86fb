"""The receiver's configuration and what each CFG message does to it.

A u-blox receiver keeps three copies of its configuration: the one in use, the one saved in
battery-backed RAM/flash (what a reset or CFG-CFG load restores) and the factory default (what
CFG-CFG clear restores). CFG messages change the one in use; an empty payload (or the short
"poll" form) asks for the current value instead. Every CFG message gets exactly one ACK-ACK or
ACK-NAK, except CFG-RST, which the receiver does not acknowledge because it is resetting.

Only the fields the model acts on are interpreted (port baud and protocol masks, message rates,
measurement rate, dynamic model, fix mode); the rest of each payload is kept verbatim so a poll
returns what was written, as the real receiver does.
"""

from __future__ import annotations

import copy
import struct
from dataclasses import dataclass, field
from typing import Final

__all__ = [
    "NMEA_IDS",
    "OUTPUT_MESSAGES",
    "PORT_UART1",
    "PROTO_NMEA",
    "PROTO_RTCM3",
    "PROTO_UBX",
    "CfgResult",
    "ConfigStore",
    "PortConfig",
    "ReceiverConfig",
]

PROTO_UBX: Final = 0x01
PROTO_NMEA: Final = 0x02
PROTO_RTCM2: Final = 0x04
PROTO_RTCM3: Final = 0x20
PORT_DDC, PORT_UART1, PORT_UART2, PORT_USB, PORT_SPI = range(5)
_N_RATE_SLOTS: Final = 6  # I2C, UART1, UART2, USB, SPI, reserved (the CFG-MSG 8-byte form)

#: NMEA standard messages (class 0xF0) by id, in the receiver's output order.
NMEA_IDS: Final = {0x00: "GGA", 0x01: "GLL", 0x02: "GSA", 0x03: "GSV", 0x04: "RMC", 0x05: "VTG"}

#: Periodic outputs the model can produce; CFG-MSG for anything else is NAKed (the model would
#: otherwise accept a rate and then silently never send the message).
OUTPUT_MESSAGES: Final[tuple[tuple[int, int], ...]] = (
    (0x01, 0x03), (0x01, 0x04), (0x01, 0x07), (0x01, 0x30), (0x01, 0x35), (0x0A, 0x09),
    *((0xF0, i) for i in NMEA_IDS),
)

_BAUDS_OK: Final = range(4800, 921_601)
_DYN_MODELS: Final = {0, 2, 3, 4, 5, 6, 7, 8, 9, 10}

# CFG-CFG section bits (clearMask/saveMask/loadMask).
_SEC_IOPORT: Final = 0x01
_SEC_MSGCONF: Final = 0x02
_SEC_NAVCONF: Final = 0x08


@dataclass
class PortConfig:
    """One CFG-PRT block (20 bytes)."""

    port_id: int
    baud: int = 9600
    mode: int = 0x000008D0
    in_mask: int = PROTO_UBX | PROTO_NMEA | PROTO_RTCM2
    out_mask: int = PROTO_UBX | PROTO_NMEA
    flags: int = 0
    tx_ready: int = 0

    def pack(self) -> bytes:
        return struct.pack("<BBHIIHHHH", self.port_id, 0, self.tx_ready, self.mode, self.baud,
                           self.in_mask, self.out_mask, self.flags, 0)

    @classmethod
    def unpack(cls, block: bytes) -> PortConfig:
        port, _r, txr, mode, baud, inm, outm, flags, _r2 = struct.unpack("<BBHIIHHHH", block)
        return cls(port, baud, mode, inm, outm, flags, txr)


def _default_nav5() -> bytes:
    # mask, dynModel 0 (portable), fixMode 3 (auto), fixedAlt, fixedAltVar 1 m^2, minElev 5 deg,
    # drLimit, pDop/tDop 25.0, pAcc 100 m, tAcc 300 m, staticHold, dgnssTimeout 60 s, ...
    return struct.pack("<HBBiIbBHHHHBBBBHHB5s", 0xFFFF, 0, 3, 0, 10000, 5, 0, 250, 250, 100,
                       300, 0, 60, 0, 0, 0, 0, 0, b"\0" * 5)


def _default_gnss() -> bytes:
    blocks = [(0, 8, 16, 0x00010001), (1, 1, 3, 0x00010001), (2, 4, 8, 0x00010000),
              (3, 8, 16, 0x00010000), (4, 0, 8, 0x00010000), (5, 0, 3, 0x00010001),
              (6, 8, 14, 0x00010001)]
    out = bytes((0, 32, 32, len(blocks)))
    for gnss_id, res, mx, flags in blocks:
        out += struct.pack("<BBBBI", gnss_id, res, mx, 0, flags)
    return out


@dataclass
class ReceiverConfig:
    """Everything a CFG message can change; factory defaults of an M8 module."""

    ports: dict[int, PortConfig] = field(default_factory=dict)
    msg_rates: dict[tuple[int, int], list[int]] = field(default_factory=dict)
    meas_rate_ms: int = 1000
    nav_rate: int = 1
    time_ref: int = 1
    nav5: bytes = field(default_factory=_default_nav5)
    gnss: bytes = field(default_factory=_default_gnss)

    @classmethod
    def factory(cls, baud: int = 9600) -> ReceiverConfig:
        cfg = cls()
        for port in (PORT_DDC, PORT_UART1, PORT_UART2, PORT_USB, PORT_SPI):
            cfg.ports[port] = PortConfig(port, baud if port in (PORT_UART1, PORT_UART2) else 0)
        for key in OUTPUT_MESSAGES:
            on = 1 if key[0] == 0xF0 else 0
            cfg.msg_rates[key] = [on] * 5 + [0]
        return cfg

    def rate(self, key: tuple[int, int], port: int) -> int:
        return self.msg_rates.get(key, [0] * _N_RATE_SLOTS)[port]

    @property
    def dyn_model(self) -> int:
        return self.nav5[2]

    @property
    def fix_mode(self) -> int:
        return self.nav5[3]


@dataclass
class CfgResult:
    """What the receiver answers: ACK-ACK (``ack`` True) or ACK-NAK (False), and for a poll the
    payload of the CFG message to send back first (the receiver answers a poll with the message
    and then acknowledges it)."""

    ack: bool | None
    reply: bytes | None = None


class ConfigStore:
    """Current, saved and factory configurations, and the CFG message handlers."""

    def __init__(self, baud: int = 9600) -> None:
        self.factory = ReceiverConfig.factory(baud)
        self.saved = copy.deepcopy(self.factory)
        self.current = copy.deepcopy(self.factory)
        self._handlers = {0x00: self._prt, 0x01: self._msg, 0x08: self._rate, 0x24: self._nav5,
                          0x3E: self._gnss, 0x09: self._cfg}

    def handle(self, msg_id: int, payload: bytes, port: int) -> CfgResult:
        """Apply (or answer a poll of) one CFG message received on ``port``."""
        handler = self._handlers.get(msg_id)
        if handler is None:  # CFG-VALSET and friends (protocol >= 27), unknown ids
            return CfgResult(False)
        return handler(payload, port)

    def reload(self) -> None:
        """What a reset does: the saved configuration becomes the current one."""
        self.current = copy.deepcopy(self.saved)

    # -- handlers, one per CFG id -----------------------------------------------------------

    def _prt(self, p: bytes, port: int) -> CfgResult:
        cur = self.current
        if len(p) in (0, 1):
            pid = p[0] if p else port
            pc = cur.ports.get(pid)
            return CfgResult(True, pc.pack()) if pc is not None else CfgResult(False)
        if len(p) % 20 or len(p) > 40:
            return CfgResult(False)
        blocks = [PortConfig.unpack(p[i:i + 20]) for i in range(0, len(p), 20)]
        for b in blocks:
            if b.port_id not in cur.ports:
                return CfgResult(False)
            if b.port_id in (PORT_UART1, PORT_UART2) and b.baud not in _BAUDS_OK:
                return CfgResult(False)
        for b in blocks:
            if b.port_id not in (PORT_UART1, PORT_UART2):
                b.baud = 0
            cur.ports[b.port_id] = b
        return CfgResult(True)

    def _msg(self, p: bytes, port: int) -> CfgResult:
        if len(p) < 2:
            return CfgResult(False)
        key = (p[0], p[1])
        rates = self.current.msg_rates.get(key)
        if rates is None:
            return CfgResult(False)
        if len(p) == 2:
            return CfgResult(True, bytes(p[:2]) + bytes(rates))
        if len(p) == 3:
            rates[port] = p[2]
        elif len(p) == 8:
            rates[:] = list(p[2:8])
        else:
            return CfgResult(False)
        return CfgResult(True)

    def _rate(self, p: bytes, port: int) -> CfgResult:
        cur = self.current
        if not p:
            return CfgResult(True, struct.pack("<HHH", cur.meas_rate_ms, cur.nav_rate,
                                               cur.time_ref))
        if len(p) != 6:
            return CfgResult(False)
        meas, nav, ref = struct.unpack("<HHH", p)
        if meas < 25 or not 1 <= nav <= 127 or ref > 4:
            return CfgResult(False)
        cur.meas_rate_ms, cur.nav_rate, cur.time_ref = meas, nav, ref
        return CfgResult(True)

    def _nav5(self, p: bytes, port: int) -> CfgResult:
        cur = self.current
        if not p:
            return CfgResult(True, cur.nav5)
        if len(p) != 36:
            return CfgResult(False)
        mask = p[0] | (p[1] << 8)
        if mask & 0x0001 and p[2] not in _DYN_MODELS:
            return CfgResult(False)
        if mask & 0x0004 and p[3] not in (1, 2, 3):
            return CfgResult(False)
        new = bytearray(cur.nav5)
        # (mask bit, byte range) of each settable group, in the order of the payload.
        for bit, lo, hi in ((0x0001, 2, 3), (0x0004, 3, 4), (0x0008, 4, 12), (0x0002, 12, 13),
                            (0x0010, 13, 14), (0x0020, 14, 18), (0x0040, 18, 22),
                            (0x0080, 22, 23), (0x0200, 28, 30), (0x0100, 23, 24),
                            (0x0400, 24, 26), (0x8000, 30, 31)):
            if mask & bit:
                new[lo:hi] = p[lo:hi]
        cur.nav5 = bytes(new)
        return CfgResult(True)

    def _gnss(self, p: bytes, port: int) -> CfgResult:
        cur = self.current
        if not p:
            return CfgResult(True, cur.gnss)
        if len(p) < 4 or p[0] != 0 or len(p) != 4 + 8 * p[3]:
            return CfgResult(False)
        blocks = {cur.gnss[4 + 8 * i]: cur.gnss[4 + 8 * i:12 + 8 * i]
                  for i in range(cur.gnss[3])}
        for i in range(p[3]):
            blk = p[4 + 8 * i:12 + 8 * i]
            if blk[0] > 6:
                return CfgResult(False)
            blocks[blk[0]] = blk
        cur.gnss = bytes((0, cur.gnss[1], p[2] or cur.gnss[2], len(blocks))) + b"".join(
            blocks[k] for k in sorted(blocks))
        return CfgResult(True)

    def _cfg(self, p: bytes, port: int) -> CfgResult:
        if len(p) not in (12, 13):
            return CfgResult(False)
        clear, save, load = struct.unpack("<III", p[:12])
        for mask, src_name, dst_name in ((clear, "factory", "saved"), (save, "current", "saved"),
                                         (load, "saved", "current")):
            if mask:
                self._copy_sections(mask, getattr(self, src_name), getattr(self, dst_name))
        return CfgResult(True)

    @staticmethod
    def _copy_sections(mask: int, src: ReceiverConfig, dst: ReceiverConfig) -> None:
        if mask & _SEC_IOPORT:
            dst.ports = copy.deepcopy(src.ports)
        if mask & _SEC_MSGCONF:
            dst.msg_rates = copy.deepcopy(src.msg_rates)
        if mask & _SEC_NAVCONF:
            dst.meas_rate_ms, dst.nav_rate, dst.time_ref = (src.meas_rate_ms, src.nav_rate,
                                                            src.time_ref)
            dst.nav5, dst.gnss = src.nav5, src.gnss
