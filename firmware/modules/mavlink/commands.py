"""Commands: COMMAND_LONG / COMMAND_INT to ``vehicle_command``, acks back as COMMAND_ACK.

What the link itself can answer (message requests and intervals, capabilities, protocol
version) is answered here at once with an ack. Everything else is published on
``vehicle_command`` (``from_external`` set, the sender as source) for the commander, navigator
and the others; their ``vehicle_command_ack`` answers go out on every link as COMMAND_ACK (PX4
sends external acks on all links: the GCS may have sent on any of them).

A command is never left unanswered by the link: a message id or interval that is NaN,
infinite or out of range is MAV_RESULT_DENIED (as PX4 denies a request it cannot act on), and
whatever a handler here raises is answered MAV_RESULT_FAILED (and logged).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from firmware.modules.mavlink.dialect import mav
from firmware.modules.mavlink.streams import MAX_INTERVAL_US
from firmware.version import board_uid, os_version_word, software_hash, version_word

if TYPE_CHECKING:
    from firmware.modules.mavlink.instance import MavlinkInstance

__all__ = ["CAPABILITIES", "BadParam", "CommandService", "autopilot_version", "interval_us",
           "message_id", "send_protocol_version"]

CAPABILITIES = (mav.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT | mav.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
                | mav.MAV_PROTOCOL_CAPABILITY_MISSION_INT | mav.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
                | mav.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
                | mav.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET
                | mav.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
                | mav.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
                | mav.MAV_PROTOCOL_CAPABILITY_MAVLINK2
                | mav.MAV_PROTOCOL_CAPABILITY_FTP
                | mav.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE   # fence and rally lists (PX4)
                | mav.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY)
#: the FMUv2's USB ids (3D Robotics), as PX4 reports them
VENDOR_ID, PRODUCT_ID = 0x26AC, 0x0011
_GLOBAL_FRAMES = frozenset({mav.MAV_FRAME_GLOBAL, mav.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                            mav.MAV_FRAME_GLOBAL_INT, mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                            mav.MAV_FRAME_GLOBAL_TERRAIN_ALT,
                            mav.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT})


def autopilot_version(inst: MavlinkInstance) -> Any:
    system = inst.system
    # PX4: the first 16 hex digits of the software hash as a little-endian uint64
    sw = software_hash(system.version, system.git_hash)
    git = int(sw[:16], 16).to_bytes(8, "little")
    uid = int.from_bytes(board_uid(system.board_name)[:8], "little")
    return mav.MAVLink_autopilot_version_message(
        CAPABILITIES, version_word(system.version), version_word(system.version),
        os_version_word(), 2, list(git), list(git), [0] * 8, VENDOR_ID, PRODUCT_ID, uid)


PROTOCOL_VERSION_ID, PROTOCOL_VERSION_CRC_EXTRA = 300, 217
#: MAVLink 2 message ids are 24 bits
MAX_MSG_ID = (1 << 24) - 1


class BadParam(ValueError):
    """A command parameter the link cannot act on (NaN, infinite, out of range): DENIED."""


def message_id(value: float) -> int:
    """A message id from a float command parameter; :class:`BadParam` unless it is a whole
    number in 0..2^24-1 (NaN and infinity included: PX4 would cast them to garbage)."""
    if not math.isfinite(value) or value != int(value) or not 0 <= value <= MAX_MSG_ID:
        raise BadParam(f"message id {value!r} is not a MAVLink message id")
    return int(value)


def interval_us(value: float) -> float:
    """A SET_MESSAGE_INTERVAL interval (-1 off, 0 default, > 0 µs); :class:`BadParam` if not
    finite or longer than MESSAGE_INTERVAL's int32 can report (~36 minutes)."""
    if not math.isfinite(value):
        raise BadParam(f"message interval {value!r} is not a number of microseconds")
    if value > MAX_INTERVAL_US:
        raise BadParam(f"message interval {value!r} µs is beyond {MAX_INTERVAL_US} µs")
    return value


def send_protocol_version(inst: MavlinkInstance) -> None:
    """PROTOCOL_VERSION (#300): version 2.0, supporting 1.0 to 2.0. pymavlink's dialects do not
    define it, so it is packed here: three uint16 and two 8-byte hashes (zeros: no spec hash)."""
    payload = struct.pack("<HHH8s8s", 200, 100, 200, bytes(8), bytes(8))
    msg = mav.MAVLink_message(PROTOCOL_VERSION_ID, "PROTOCOL_VERSION")
    inst.send_packed(msg, PROTOCOL_VERSION_CRC_EXTRA, payload)


class CommandService:
    def __init__(self, inst: MavlinkInstance) -> None:
        self.inst = inst
        self._pub: Any = None  # advertised on the first forwarded command
        self._cmd = inst.platform.orb.new("vehicle_command")
        self._ack_sub = inst.module.subscribe("vehicle_command_ack")
        self._ack_sub.copy()  # only acks published from now on
        self.forwarded = 0
        self.local: dict[int, Callable[[Any], int]] = {
            mav.MAV_CMD_REQUEST_MESSAGE: self._request_message,
            mav.MAV_CMD_SET_MESSAGE_INTERVAL: self._set_interval,
            mav.MAV_CMD_GET_MESSAGE_INTERVAL: self._get_interval,
            mav.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: self._capabilities,
            mav.MAV_CMD_REQUEST_PROTOCOL_VERSION: self._protocol_version,
        }

    def handlers(self) -> dict[int, Callable[[Any], None]]:
        return {mav.MAVLINK_MSG_ID_COMMAND_LONG: self._on_long,
                mav.MAVLINK_MSG_ID_COMMAND_INT: self._on_int,
                mav.MAVLINK_MSG_ID_SET_MODE: self._on_set_mode}

    # -- incoming -------------------------------------------------------------------------------

    def _on_long(self, m: Any) -> None:
        self._handle(m, m.command, (m.param1, m.param2, m.param3, m.param4),
                     float(m.param5), float(m.param6), m.param7, m.confirmation)

    def _on_set_mode(self, m: Any) -> None:
        """SET_MODE (#11), deprecated but still sent by MAVROS and older ground stations. PX4's
        receiver (handle_message_set_mode) turns it into MAV_CMD_DO_SET_MODE: param1 the base
        mode, param2/param3 the main and sub mode of ``px4_custom_mode`` (custom_mode bits
        16-23 and 24-31), target component "all". The commander then switches as for the
        command, with the same refusals, and its ack goes out as COMMAND_ACK for
        DO_SET_MODE (176): PX4 answers SET_MODE that way too."""
        custom = int(m.custom_mode) & 0xFFFFFFFF
        main, sub = (custom >> 16) & 0xFF, (custom >> 24) & 0xFF
        self._forward(m, mav.MAV_CMD_DO_SET_MODE,
                      (float(m.base_mode), float(main), float(sub), 0.0), 0.0, 0.0, 0.0, 1)

    def _on_int(self, m: Any) -> None:
        if m.frame in _GLOBAL_FRAMES:
            x = m.x / 1e7 if m.x != 0x7FFFFFFF else math.nan
            y = m.y / 1e7 if m.y != 0x7FFFFFFF else math.nan
        else:
            x, y = float(m.x), float(m.y)
        self._handle(m, m.command, (m.param1, m.param2, m.param3, m.param4), x, y, m.z, 0)

    def _handle(self, m: Any, command: int, p: tuple, p5: float, p6: float, p7: float,
                confirmation: int) -> None:
        inst = self.inst
        src_sys, src_comp = m.get_srcSystem(), m.get_srcComponent()
        if m.target_component not in (0, inst.compid, mav.MAV_COMP_ID_ALL):
            inst.rx_not_for_us += 1
            return  # for another component of this system (a camera, a gimbal)
        if command == mav.MAV_CMD_INJECT_FAILURE and not self._failure_injection_enabled():
            # PX4's receiver: without SYS_FAILURE_EN the command is denied, never published
            inst.send_text(mav.MAV_SEVERITY_WARNING,
                           "Failure injection disabled: set SYS_FAILURE_EN to 1")
            inst.ack_command(command, mav.MAV_RESULT_DENIED, src_sys, src_comp)
            return
        local = self.local.get(command)
        if local is not None:
            self._local_p = (*p, p5, p6, p7)
            try:
                result = local(m)
            except BadParam as exc:
                result = mav.MAV_RESULT_DENIED
                inst.send_text(mav.MAV_SEVERITY_WARNING, f"Command {command} denied: {exc}")
            except Exception as exc:  # noqa: BLE001 - every command gets its answer
                result = mav.MAV_RESULT_FAILED
                inst.handler_failed(m, exc, f" {command}")
            inst.ack_command(command, result, src_sys, src_comp)
            return
        try:
            self._forward(m, command, p, p5, p6, p7, confirmation)
        except Exception as exc:  # noqa: BLE001 - every command gets its answer
            inst.handler_failed(m, exc, f" {command}")
            inst.ack_command(command, mav.MAV_RESULT_FAILED, src_sys, src_comp)

    def _forward(self, m: Any, command: int, p: tuple, p5: float, p6: float, p7: float,
                 confirmation: int) -> None:
        """Publish the command on ``vehicle_command`` for the module that handles it."""
        inst = self.inst
        src_sys, src_comp = m.get_srcSystem(), m.get_srcComponent()
        c = self._cmd
        c.timestamp = inst.time_us()
        c.param1, c.param2, c.param3, c.param4 = p
        c.param5, c.param6, c.param7 = p5, p6, p7
        c.command = command
        c.target_system = m.target_system
        c.target_component = getattr(m, "target_component", 0)  # SET_MODE has none: all
        c.source_system = src_sys
        c.source_component = src_comp
        c.confirmation = confirmation & 0xFF
        c.from_external = True
        if self._pub is None:
            self._pub = inst.module.advertise("vehicle_command")
        self._pub.publish(c)
        self.forwarded += 1

    def _failure_injection_enabled(self) -> bool:
        """SYS_FAILURE_EN (PX4: ``Mavlink::failure_injection_enabled``); off if undeclared."""
        params = self.inst.system.params
        return params is not None and bool(params.get("SYS_FAILURE_EN", 0))

    # -- answered here ----------------------------------------------------------------------

    _local_p: tuple = ()

    def _request_message(self, m: Any) -> int:
        from firmware.modules.mavlink.services import REQUESTABLE

        msg_id = message_id(self._local_p[0])
        inst = self.inst
        if msg_id == mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            inst.send(autopilot_version(inst))
        elif msg_id == PROTOCOL_VERSION_ID:
            send_protocol_version(inst)
        elif msg_id == mav.MAVLINK_MSG_ID_AVAILABLE_MODES:
            return inst.available_modes.request(self._local_p[1])
        elif msg_id in (mav.MAVLINK_MSG_ID_COMPONENT_METADATA,
                        mav.MAVLINK_MSG_ID_COMPONENT_INFORMATION):
            inst.send(inst.ftp.metadata.message(msg_id, inst.boot_ms()))
        elif msg_id in REQUESTABLE:
            REQUESTABLE[msg_id](inst)
        elif not inst.send_stream_once(msg_id):
            return mav.MAV_RESULT_UNSUPPORTED if inst.stream_interval_us(msg_id) is None \
                else mav.MAV_RESULT_TEMPORARILY_REJECTED
        return mav.MAV_RESULT_ACCEPTED

    def _set_interval(self, m: Any) -> int:
        from firmware.modules.mavlink.streams import DEFAULT_RATES, STREAM_BY_ID

        msg_id, interval = message_id(self._local_p[0]), interval_us(self._local_p[1])
        sdef = STREAM_BY_ID.get(msg_id)
        if sdef is None:
            return mav.MAV_RESULT_UNSUPPORTED
        if interval < 0:
            rate = 0.0
        elif interval == 0:
            rate = DEFAULT_RATES[self.inst.mode].get(sdef.name, 0.0)
        else:
            rate = 1e6 / interval
        self.inst.set_stream_rate(sdef.name, rate)
        return mav.MAV_RESULT_ACCEPTED

    def _get_interval(self, m: Any) -> int:
        msg_id = message_id(self._local_p[0])
        if msg_id > 0xFFFF:  # MESSAGE_INTERVAL's message_id is 16 bits
            raise BadParam(f"message id {msg_id} does not fit MESSAGE_INTERVAL")
        interval = self.inst.stream_interval_us(msg_id)
        self.inst.send(mav.MAVLink_message_interval_message(msg_id, interval if interval
                                                            is not None else 0))
        return mav.MAV_RESULT_ACCEPTED

    def _capabilities(self, m: Any) -> int:
        self.inst.send(autopilot_version(self.inst))
        return mav.MAV_RESULT_ACCEPTED

    def _protocol_version(self, m: Any) -> int:
        send_protocol_version(self.inst)
        return mav.MAV_RESULT_ACCEPTED

    # -- acks from the vehicle ----------------------------------------------------------------

    def update(self, now_us: int) -> None:
        while True:
            a = self._ack_sub.update()
            if a is None:
                return
            if a.from_external:
                self.inst.ack_command(int(a.command), int(a.result), int(a.target_system),
                                      int(a.target_component), int(a.result_param1),
                                      int(a.result_param2))
