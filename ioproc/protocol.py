"""The PX4IO FMU <-> IO serial protocol: packet layout, CRC-8, codes, and both ends' helpers.

One declarative layout (:data:`LAYOUT`) describes the packet; the same object packs and unpacks,
so the FMU driver's encoder and the IO's decoder cannot drift apart (the idea of ``construct``).

Facts: ``io-and-rc.md`` §1.2-§1.6 (layout, codes, CRC-8 poly 0x07, transaction rules). The era
is a single explicit choice (:data:`ERA`); only E14 (protocol version 4, mixer on the IO) exists
today, and every era-dependent table elsewhere in ``ioproc`` is keyed by :class:`Era`.

The IO side is :func:`handle_request`: bytes of one received burst in, reply bytes (or ``None``
for "no reply") out. It never raises on bad input, because the real IO answers garbage with a
CORRUPT packet or silence, and a Python exception escaping the IO's "interrupt handler" would
be a behaviour the hardware does not have.
"""

from __future__ import annotations

import logging
import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum, IntEnum, IntFlag
from typing import Final, Protocol

from mypy_extensions import mypyc_attr


class Era(str, Enum):
    """Firmware era (io-and-rc.md "Firmware eras"). FMU and IO must agree on one."""

    E14 = "E14"  # protocol 4, mixer on IO, RC override on IO, SETUP_ARMING layout A


#: The era this emulator implements. Change only together with the era-keyed tables.
ERA: Final[Era] = Era.E14

#: PX4IO_PROTOCOL_VERSION reported in CONFIG register 0, per era.
PROTOCOL_VERSION: dict[Era, int] = {Era.E14: 4}

# --- limits (§1.2) ---------------------------------------------------------------------------
PKT_MAX_REGS: Final = 32  #: register words a packet buffer holds on both sides
PKT_HEADER_SIZE: Final = 4  #: count_code, crc, page, offset
PKT_MAX_SIZE: Final = PKT_HEADER_SIZE + 2 * PKT_MAX_REGS  #: 68 bytes, the IO's RX DMA buffer
MAX_TRANSFER_LEN: Final = 64  #: PX4IO_MAX_TRANSFER_LEN, reported in CONFIG reg 3
FMU_MAX_REGS_PER_CALL: Final = (MAX_TRANSFER_LEN - 2) // 2  #: 31: what the FMU driver sends at most
PKT_CODE_MASK: Final = 0xC0
PKT_COUNT_MASK: Final = 0x3F
FMU_WRITE_PADDING: Final = 0x55AA  #: what the FMU leaves in unused buffer slots (§1.7)

#: Reply timeout and attempts of the FMU driver (§1.7), for the driver that imports this module.
FMU_REPLY_TIMEOUT_US: Final = 10_000
FMU_ATTEMPTS: Final = 3


class RequestCode(IntEnum):
    """Bits 7..6 of byte 0 in an FMU -> IO packet (§1.3)."""

    READ = 0x00
    WRITE = 0x40


class ReplyCode(IntEnum):
    """Bits 7..6 of byte 0 in an IO -> FMU packet (§1.3). 0xC0 is never sent."""

    SUCCESS = 0x00
    CORRUPT = 0x40
    ERROR = 0x80


#: (page, offset) the IO puts in a CORRUPT reply: CRC failure vs. unusable request code (§1.5).
CORRUPT_CRC_PAGE_OFFSET = (0xFF, 0xFF)
CORRUPT_CODE_PAGE_OFFSET = (0xFF, 0xFE)


# --- CRC-8 (§1.4) ----------------------------------------------------------------------------
def _make_crc8_table(poly: int = 0x07) -> tuple[int, ...]:
    """Build T[i] = CRC-8 of the single byte i; equals the table shipped in protocol.h."""
    table = []
    for i in range(256):
        c = i
        for _ in range(8):
            c = ((c << 1) ^ poly) & 0xFF if c & 0x80 else (c << 1) & 0xFF
        table.append(c)
    return tuple(table)


CRC8_TABLE: Final[tuple[int, ...]] = _make_crc8_table()


def crc8(data: bytes | bytearray | memoryview, crc: int = 0) -> int:
    """CRC-8, poly 0x07, init 0, no reflection, no final XOR ("123456789" -> 0xF4)."""
    table = CRC8_TABLE
    for b in data:
        crc = table[crc ^ b]
    return crc


# --- the layout --------------------------------------------------------------------------------
@dataclass(frozen=True)
class Packet:
    """A decoded packet, either direction. ``code`` is the raw 2-bit code (0x00/0x40/0x80/0xC0)."""

    code: int
    page: int
    offset: int
    regs: tuple[int, ...]
    crc: int = 0

    @property
    def count(self) -> int:
        return len(self.regs)


class PacketLayout:
    """Declarative packet description: header fields, then N register words.

    ``header`` lists (field, struct format) in wire order and must name ``count_code``, the
    CRC field, ``page`` and ``offset``; ``count_code`` packs the 2-bit code and 6-bit register
    count; ``crc_field`` is zeroed while the CRC is computed over the whole packet. Both
    :meth:`pack` and :meth:`unpack` are derived from these fields; everything derived is worked
    out once here (a px4io transaction packs and unpacks two packets, hundreds per second).
    """

    def __init__(self, header: tuple[tuple[str, str], ...] = (
            ("count_code", "B"), ("crc", "B"), ("page", "B"), ("offset", "B")),
            byte_order: str = "<", reg_format: str = "H", crc_field: str = "crc",
            code_mask: int = PKT_CODE_MASK, count_mask: int = PKT_COUNT_MASK) -> None:
        self.header = header
        self.byte_order = byte_order
        self.reg_format = reg_format
        self.crc_field = crc_field
        self.code_mask = code_mask
        self.count_mask = count_mask
        self.names: tuple[str, ...] = tuple(n for n, _ in header)
        missing = {"count_code", crc_field, "page", "offset"} - set(self.names)
        if missing:
            raise ValueError(f"packet header lacks {sorted(missing)}")
        head = "".join(f for _, f in header)
        self.header_struct = struct.Struct(byte_order + head)
        self.header_size: int = self.header_struct.size
        self.reg_size: int = struct.calcsize(byte_order + reg_format)
        self.crc_index: int = self.names.index(crc_field)
        #: Pre-built Struct for every possible register count (one per transaction).
        self.reg_structs: tuple[struct.Struct, ...] = tuple(
            struct.Struct(f"{byte_order}{n}{reg_format}") for n in range(count_mask + 1))
        #: Header and registers in one Struct per count: a packet is one ``pack`` call.
        self._packet_structs: tuple[struct.Struct, ...] = tuple(
            struct.Struct(f"{byte_order}{head}{n}{reg_format}") for n in range(count_mask + 1))
        #: Positions of count_code, crc, page and offset among the header fields.
        names = self.names
        self._i_count = names.index("count_code")
        self._i_page = names.index("page")
        self._i_offset = names.index("offset")
        self._n_header = len(names)

    def __repr__(self) -> str:
        return (f"PacketLayout(header={self.header!r}, byte_order={self.byte_order!r}, "
                f"reg_format={self.reg_format!r})")

    def size(self, count: int) -> int:
        """Bytes on the wire for ``count`` register words."""
        return self.header_size + self.reg_size * count

    def pack(self, code: int, page: int, offset: int, regs: Sequence[int]) -> bytes:
        """Encode a packet and fill in its CRC. Raises ValueError on out-of-range fields."""
        n = len(regs)
        if n > self.count_mask:
            raise ValueError(f"{n} registers do not fit the {self.count_mask}-count field")
        if code & ~self.code_mask or not 0 <= page <= 0xFF or not 0 <= offset <= 0xFF:
            raise ValueError(f"bad header code=0x{code:02X} page={page} offset={offset}")
        fields = [0] * self._n_header  # the CRC field stays 0 while the CRC is computed
        fields[self._i_count] = code | n
        fields[self._i_page] = page
        fields[self._i_offset] = offset
        fields.extend(regs)
        try:
            buf = bytearray(self._packet_structs[n].pack(*fields))
        except struct.error as exc:
            raise ValueError(f"register values must be uint16: {exc}") from None
        buf[self.crc_index] = crc8(buf)
        return bytes(buf)

    def unpack(self, data: bytes | bytearray | memoryview) -> tuple[Packet, bool]:
        """Decode ``data`` (exactly header + N words) -> (packet, crc_ok). Raises on short data."""
        hs = self.header_size
        if len(data) < hs:
            raise LengthError(f"packet of {len(data)} bytes is shorter than the {hs}-byte header")
        head = self.header_struct.unpack_from(data, 0)
        count_code = head[self._i_count]
        n = count_code & self.count_mask
        need = hs + self.reg_size * n
        if len(data) < need:
            raise LengthError(f"packet of {len(data)} bytes, header announces {n} regs "
                              f"({need} bytes)")
        regs = self.reg_structs[n].unpack_from(data, hs)
        check = bytearray(data[:need])
        check[self.crc_index] = 0
        crc = head[self.crc_index]
        pkt = Packet(count_code & self.code_mask, head[self._i_page], head[self._i_offset], regs,
                     crc)
        return pkt, crc8(check) == crc


#: The one PX4IO packet layout (§1.2).
LAYOUT: Final = PacketLayout()


# --- errors the FMU side sees ------------------------------------------------------------------
@mypyc_attr(native_class=False)
class ProtocolError(Exception):
    """A reply the FMU driver cannot use; the driver counts it and retries (§1.7)."""


@mypyc_attr(native_class=False)
class LengthError(ProtocolError):
    """Fewer bytes than the header (or the header's count) requires."""


@mypyc_attr(native_class=False)
class CrcError(ProtocolError):
    """The reply's CRC-8 does not match its contents."""


@mypyc_attr(native_class=False)
class BadCodeError(ProtocolError):
    """Reply code 0xC0, which the IO never sends."""


# --- register pages, registers and bits (the protocol.h part; values per §2) ----------------
class PageNo(IntEnum):
    """E14 page numbers (108 is DISARMED_PWM only in E14; E19 moved it to 109)."""

    CONFIG = 0
    STATUS = 1
    ACTUATORS = 2
    SERVOS = 3
    RAW_RC_INPUT = 4
    RC_INPUT = 5
    RAW_ADC_INPUT = 6
    PWM_INFO = 7
    SETUP = 50
    CONTROLS = 51
    MIXERLOAD = 52
    RC_CONFIG = 53
    DIRECT_PWM = 54
    FAILSAFE_PWM = 55
    SENSORS = 56  # defined in protocol.h, not implemented: any access answers ERROR
    CONTROL_MIN_PWM = 106
    CONTROL_MAX_PWM = 107
    DISARMED_PWM = 108
    TEST = 127


class Config(IntEnum):
    PROTOCOL_VERSION = 0
    HARDWARE_VERSION = 1
    BOOTLOADER_VERSION = 2
    MAX_TRANSFER = 3
    CONTROL_COUNT = 4
    ACTUATOR_COUNT = 5
    RC_INPUT_COUNT = 6
    ADC_INPUT_COUNT = 7
    RELAY_COUNT = 8


class Status(IntEnum):
    FREEMEM = 0
    CPULOAD = 1
    FLAGS = 2
    ALARMS = 3
    VBATT = 4
    IBATT = 5
    VSERVO = 6
    VRSSI = 7
    PRSSI = 8


class StatusFlags(IntFlag):
    """STATUS_FLAGS, protocol 4 (E14/E19) bit layout."""

    OUTPUTS_ARMED = 0x0001
    OVERRIDE = 0x0002
    RC_OK = 0x0004
    RC_PPM = 0x0008
    RC_DSM = 0x0010
    RC_SBUS = 0x0020
    FMU_OK = 0x0040
    RAW_PWM = 0x0080
    MIXER_OK = 0x0100
    ARM_SYNC = 0x0200
    INIT_OK = 0x0400
    FAILSAFE = 0x0800
    SAFETY_OFF = 0x1000
    FMU_INITIALIZED = 0x2000
    RC_ST24 = 0x4000
    RC_SUMD = 0x8000


class Alarms(IntFlag):
    """STATUS_ALARMS, protocol 4: latched, a write clears the bits written as 1."""

    VBATT_LOW = 0x01
    TEMPERATURE = 0x02
    SERVO_CURRENT = 0x04
    ACC_CURRENT = 0x08
    FMU_LOST = 0x10
    RC_LOST = 0x20
    PWM_ERROR = 0x40
    VSERVO_FAULT = 0x80


class RawRc(IntEnum):
    COUNT = 0
    FLAGS = 1
    NRSSI = 2
    DATA = 3
    FRAME_COUNT = 4
    LOST_FRAME_COUNT = 5
    BASE = 6  # channel 1; channels 1..18 at 6..23


class RawRcFlags(IntFlag):
    FRAME_DROP = 0x01
    FAILSAFE = 0x02
    RC_DSM11 = 0x04
    MAPPING_OK = 0x08
    RC_OK = 0x10


class RcInput(IntEnum):
    VALID = 0
    BASE = 1  # control 0 (roll); controls 0..8 at 1..9


class Setup(IntEnum):
    """SETUP registers, E14. Reg 12 reads the CRC high word; a write to it is FORCE_SAFETY_OFF."""

    FEATURES = 0
    ARMING = 1
    PWM_RATES = 2
    PWM_DEFAULTRATE = 3
    PWM_ALTRATE = 4
    RELAYS_PAD = 5
    VSERVO_SCALE = 6
    DSM = 7
    RESERVED_8 = 8
    SET_DEBUG = 9
    REBOOT_BL = 10
    CRC = 11
    CRC_HIGH = 12
    FORCE_SAFETY_OFF = 12
    RC_THR_FAILSAFE_US = 13
    FORCE_SAFETY_ON = 14  # write-only, beyond the readable page length (14)


class Features(IntFlag):
    SBUS1_OUT = 0x01
    SBUS2_OUT = 0x02
    PWM_RSSI = 0x04
    ADC_RSSI = 0x08


class ArmingA(IntFlag):
    """SETUP_ARMING layout A (E14, 2013-11 ... 2019-08)."""

    IO_ARM_OK = 0x001
    FMU_ARMED = 0x002
    MANUAL_OVERRIDE_OK = 0x004
    FAILSAFE_CUSTOM = 0x008
    INAIR_RESTART_OK = 0x010
    ALWAYS_PWM_ENABLE = 0x020
    RC_HANDLING_DISABLED = 0x040
    LOCKDOWN = 0x080
    FORCE_FAILSAFE = 0x100
    TERMINATION_FAILSAFE = 0x200
    OVERRIDE_IMMEDIATE = 0x400


#: SETUP_ARMING bit layout per era; ``Arming`` is the one of :data:`ERA`.
ARMING_LAYOUT: Final[dict[Era, type[IntFlag]]] = {Era.E14: ArmingA}
Arming = ArmingA


class RcConfig(IntEnum):
    MIN = 0
    CENTER = 1
    MAX = 2
    DEADZONE = 3
    ASSIGNMENT = 4
    OPTIONS = 5


RC_CONFIG_STRIDE: Final = 6
RC_INPUT_CHANNELS: Final = 18
RC_OPTIONS_ENABLED: Final = 0x01
RC_OPTIONS_REVERSE: Final = 0x02
RC_ASSIGN_MODESWITCH: Final = 100
RC_ASSIGN_UNASSIGNED: Final = 255
CONTROL_GROUPS: Final = 4
CONTROL_CHANNELS: Final = 8
SERVO_COUNT: Final = 8
REBOOT_BL_MAGIC: Final = 14662
FORCE_SAFETY_MAGIC: Final = 22027
REBOOT_DELAY_US: Final = 100_000
PWM_IGNORE_THIS_CHANNEL: Final = 0xFFFF



# --- FMU-side helpers ------------------------------------------------------------------------
@dataclass(frozen=True)
class Reply:
    """A decoded IO reply. ``code`` is SUCCESS, CORRUPT (retry) or ERROR (fail, no retry)."""

    code: ReplyCode
    page: int
    offset: int
    values: tuple[int, ...]

    @property
    def ok(self) -> bool:
        return self.code is ReplyCode.SUCCESS


def encode_read(page: int, offset: int, count: int, padding: int = 0) -> bytes:
    """READ request for ``count`` registers; carries ``count`` padding words (§1.5, quirk 1)."""
    if not 0 <= count <= PKT_MAX_REGS:
        raise ValueError(f"read count {count} outside 0..{PKT_MAX_REGS}")
    return LAYOUT.pack(RequestCode.READ, page, offset, (padding,) * count)


def encode_write(page: int, offset: int, values: Sequence[int]) -> bytes:
    """WRITE request carrying ``values`` (uint16 each, at most 32)."""
    if len(values) > PKT_MAX_REGS:
        raise ValueError(f"write of {len(values)} registers exceeds {PKT_MAX_REGS}")
    return LAYOUT.pack(RequestCode.WRITE, page, offset, values)


def decode_reply(packet: bytes | bytearray | memoryview) -> Reply:
    """Decode an IO reply; raise :class:`ProtocolError` subclasses for unusable bytes.

    Bytes beyond 4+2N are ignored (the FMU's DMA sees only what it expects).
    """
    pkt, crc_ok = LAYOUT.unpack(packet)
    if not crc_ok:
        want = crc8(bytes((packet[0], 0)) + bytes(packet[2:LAYOUT.size(pkt.count)]))
        raise CrcError(f"reply CRC 0x{pkt.crc:02X}, computed 0x{want:02X} "
                       f"(page {pkt.page}, offset {pkt.offset})")
    if pkt.code == 0xC0:
        raise BadCodeError(f"reply code 0xC0 (page {pkt.page}, offset {pkt.offset})")
    return Reply(ReplyCode(pkt.code), pkt.page, pkt.offset, pkt.regs)


# --- value conventions (§2.1) ------------------------------------------------------------------
def reg_to_signed(value: int) -> int:
    """uint16 register -> int16."""
    return value - 0x10000 if value & 0x8000 else value


def signed_to_reg(value: int) -> int:
    """int16 (wrapping like a C cast) -> uint16 register."""
    return value & 0xFFFF


def float_to_reg(value: float) -> int:
    """E14 FLOAT_TO_REG: (int16)(f * 10000), C truncation toward zero, then as uint16."""
    if math.isnan(value):  # NaN: the C cast is undefined; ARM's VCVT gives 0
        return 0
    v = int(value * 10000.0)
    return max(-32768, min(32767, v)) & 0xFFFF


def reg_to_float(value: int) -> float:
    """REG_TO_FLOAT: (int16)reg / 10000."""
    return reg_to_signed(value) / 10000.0


# --- IO side ---------------------------------------------------------------------------------
class PageStore(Protocol):
    """What the request handler needs from the IO's register pages (see ``ioproc.pages``)."""

    def read(self, page: int, offset: int) -> Sequence[int] | None:
        """Registers from ``offset`` to the end of ``page``, or None (unknown page/offset)."""

    def write(self, page: int, offset: int, values: Sequence[int], now_us: int) -> bool:
        """Apply a write in order; False if a register refused (earlier ones stay applied)."""


_log = logging.getLogger(__name__)
_CORRUPT_CRC: Final = LAYOUT.pack(ReplyCode.CORRUPT, *CORRUPT_CRC_PAGE_OFFSET, ())
_CORRUPT_CODE: Final = LAYOUT.pack(ReplyCode.CORRUPT, *CORRUPT_CODE_PAGE_OFFSET, ())


def handle_request(packet: bytes | bytearray | memoryview, store: PageStore,
                   now_us: int) -> bytes | None:
    """IO side of one transaction: the bytes of one received burst -> reply bytes or None.

    Mirrors the IO's serial interrupt (§1.5, §1.6): a burst shorter than its header announces
    gets no reply; a full 68-byte DMA buffer is processed even if the count says more (the CRC
    then covers bytes the IO does not have, so it fails -> CORRUPT); bytes past 4+2N are ignored.
    """
    n_rx = len(packet)
    if n_rx < 1:
        return None
    count = packet[0] & PKT_COUNT_MASK
    if n_rx < LAYOUT.size(count) and n_rx < PKT_MAX_SIZE:
        return None  # "bad idle": truncated request, no reply
    if count > PKT_MAX_REGS:
        return _CORRUPT_CRC  # DMA-complete path; CRC over bytes beyond the buffer cannot match
    req, crc_ok = LAYOUT.unpack(packet)
    if not crc_ok:
        return _CORRUPT_CRC
    code, page, offset = req.code, req.page, req.offset
    try:
        if code == RequestCode.WRITE:
            ok = store.write(page, offset, req.regs, now_us)
            return LAYOUT.pack(ReplyCode.SUCCESS if ok else ReplyCode.ERROR, page, offset, ())
        if code == RequestCode.READ:
            regs = store.read(page, offset)
            if regs is None:
                return LAYOUT.pack(ReplyCode.ERROR, page, offset, ())
            return LAYOUT.pack(ReplyCode.SUCCESS, page, offset, regs[:min(count, PKT_MAX_REGS)])
    except Exception:  # noqa: BLE001 - the real IO cannot throw out of its interrupt
        # A bug in a page hook is logged loudly; the FMU sees a refused access, not a crash.
        _log.exception("IO register access page %d offset %d failed", page, offset)
        return LAYOUT.pack(ReplyCode.ERROR, page, offset, ())
    return _CORRUPT_CODE
