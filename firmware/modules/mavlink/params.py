"""The parameter protocol as PX4 speaks it (reference sheet 9.4).

* PARAM_REQUEST_LIST: first ``_HASH_CHECK`` (type UINT32, index -1, value = PX4's CRC-32 over
  every parameter's name and 4 value bytes in index order), then every parameter in index
  order, streamed as fast as the link's data rate allows.
* PARAM_SET ``_HASH_CHECK``: the GCS has the list cached; the stream stops.
* PARAM_SET NAME: the 4 bytes of ``param_value`` taken as the parameter's own type (byte-wise
  INT32 encoding), set, answered with PARAM_VALUE; an unknown name gets STATUSTEXT
  ``[pm] unknown param: NAME``.
* PARAM_REQUEST_READ by index, or by name when the index is -1.

PARAM_VALUE payloads are packed here from the exact bytes, so an INT32 whose bit pattern is a
float NaN goes out unchanged (a float round trip through Python could quiet a signalling NaN).
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from firmware.modules.mavlink.dialect import mav
from firmware.platform.params import ParamError

if TYPE_CHECKING:
    from firmware.modules.mavlink.instance import MavlinkInstance

__all__ = ["ParamService", "crc32_px4", "param_hash", "value_bytes"]

_PV = struct.Struct("<4sHH16sB")  # PARAM_VALUE wire order
_CRC_EXTRA_PARAM_VALUE = 220
HASH_CHECK = "_HASH_CHECK"


def _table() -> list[int]:
    out = []
    for i in range(256):
        c = i
        for _ in range(8):
            c = (c >> 1) ^ 0xEDB88320 if c & 1 else c >> 1
        out.append(c)
    return out


_CRC_TABLE = _table()


def crc32_px4(data: bytes, crc: int = 0) -> int:
    """PX4's ``crc32part``: the reflected CRC-32 table step, no initial or final inversion
    (QGroundControl computes the same to compare against its parameter cache)."""
    t = _CRC_TABLE
    for b in data:
        crc = t[(crc ^ b) & 0xFF] ^ (crc >> 8)
    return crc


def value_bytes(ptype: str, value: float) -> bytes:
    return struct.pack("<i", value) if ptype == "INT32" else struct.pack("<f", value)


def param_hash(params: Any) -> int:
    """The ``_HASH_CHECK`` value over every parameter in index order."""
    crc = 0
    for name in params.names:
        crc = crc32_px4(name.encode(), crc)
        crc = crc32_px4(value_bytes(params.defs[name].type, params.values[name]), crc)
    return crc


def raw_param_value(m: Any) -> bytes:
    """The 4 wire bytes of a received message's leading float field (PARAM_SET param_value)."""
    buf = bytes(m.get_msgbuf())
    head = 10 if buf[:1] == b"\xfd" else 6
    payload = buf[head:head + m._header.mlen] + b"\x00" * 4
    return payload[:4]


class ParamService:
    """PARAM_* messages of one link."""

    def __init__(self, inst: MavlinkInstance) -> None:
        self.inst = inst
        self._next = -2      # next index to stream: -2 idle, -1 the hash check, else an index
        self.sent_lists = 0

    def handlers(self) -> dict[int, Callable[[Any], None]]:
        return {mav.MAVLINK_MSG_ID_PARAM_REQUEST_LIST: self._on_request_list,
                mav.MAVLINK_MSG_ID_PARAM_REQUEST_READ: self._on_request_read,
                mav.MAVLINK_MSG_ID_PARAM_SET: self._on_set}

    @property
    def params(self) -> Any:
        return self.inst.system.params

    # -- sending ------------------------------------------------------------------------------

    def send_value(self, name: str, budget: bool = False) -> bool:
        p = self.params
        d = p.defs[name]
        raw = value_bytes(d.type, p.values[name])
        mtype = mav.MAV_PARAM_TYPE_INT32 if d.type == "INT32" else mav.MAV_PARAM_TYPE_REAL32
        return self._send(name, raw, len(p.names), p.index(name), mtype, budget)

    def _send(self, name: str, raw: bytes, count: int, index: int, mtype: int,
              budget: bool) -> bool:
        payload = _PV.pack(raw, count, index & 0xFFFF, name.encode()[:16], mtype)
        value = struct.unpack("<f", raw)[0]
        msg = mav.MAVLink_param_value_message(name.encode(), value, mtype, count, index & 0xFFFF)
        return self.inst.send_packed(msg, _CRC_EXTRA_PARAM_VALUE, payload, budget)

    def update(self, now_us: int) -> None:
        """Stream the list while the data rate allows (one PARAM_VALUE per ~37 bytes)."""
        p = self.params
        if self._next == -2 or p is None:
            return
        names = p.names
        while self._next < len(names):
            if self._next == -1:
                ok = self._send(HASH_CHECK, struct.pack("<I", param_hash(p)), len(names), -1,
                                mav.MAV_PARAM_TYPE_UINT32, True)
            else:
                ok = self.send_value(names[self._next], budget=True)
            if not ok:
                return
            self._next += 1
        self._next = -2
        self.sent_lists += 1

    # -- requests -------------------------------------------------------------------------------

    def _on_request_list(self, m: Any) -> None:
        if self.params is not None:
            self._next = -1

    def _name(self, m: Any) -> str:
        raw = m.param_id
        if isinstance(raw, bytes):
            raw = raw.decode("latin-1")
        return raw.split("\x00", 1)[0]

    def _on_request_read(self, m: Any) -> None:
        p = self.params
        if p is None:
            return
        if m.param_index >= 0:
            if m.param_index < len(p.names):
                self.send_value(p.names[m.param_index])
            return
        name = self._name(m)
        if name == HASH_CHECK:
            self._send(HASH_CHECK, struct.pack("<I", param_hash(p)), len(p.names), -1,
                       mav.MAV_PARAM_TYPE_UINT32, False)
        elif name in p:
            self.send_value(name)
        else:
            self.inst.send_text(mav.MAV_SEVERITY_ERROR, f"[pm] unknown param: {name}")

    def _on_set(self, m: Any) -> None:
        p = self.params
        if p is None:
            return
        name = self._name(m)
        if name == HASH_CHECK:
            self._next = -2
            return
        if name not in p:
            self.inst.send_text(mav.MAV_SEVERITY_ERROR, f"[pm] unknown param: {name}")
            return
        raw = raw_param_value(m)
        d = p.defs[name]
        value: int | float = struct.unpack("<i", raw)[0] if d.type == "INT32" \
            else struct.unpack("<f", raw)[0]
        try:
            p.set(name, value)
        except ParamError as exc:
            self.inst.send_text(mav.MAV_SEVERITY_ERROR, f"[pm] {exc}")
        self.send_value(name)
