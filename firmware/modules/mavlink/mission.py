"""The mission protocol against dataman's :class:`MissionStore`.

Upload: MISSION_COUNT -> MISSION_REQUEST_INT for each item -> MISSION_ITEM_INT (or the float
MISSION_ITEM) -> MISSION_ACK. Items go into the store's inactive slot, and only a complete
upload is committed, so the navigator never sees half a mission (PX4's two-slot scheme). A
request not answered within :data:`RETRY_US` is repeated; after :data:`MAX_RETRIES` the upload
is abandoned with MAV_MISSION_OPERATION_CANCELLED.

Download: MISSION_REQUEST_LIST -> MISSION_COUNT; MISSION_REQUEST_INT/MISSION_REQUEST for each
sequence number; the GCS's MISSION_ACK ends it. Also MISSION_CLEAR_ALL, MISSION_SET_CURRENT,
and MISSION_ITEM_REACHED when the navigator reports a new reached item.

Fence and rally point lists have no storage or user in this flight stack: requests for them
are answered MAV_MISSION_UNSUPPORTED (and AUTOPILOT_VERSION does not claim those
capabilities), which QGroundControl handles.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Final

from pymavlink.dialects.v20 import common as mav

if TYPE_CHECKING:
    from firmware.modules.mavlink.instance import MavlinkInstance

__all__ = ["SUPPORTED_NAV_CMDS", "MissionService"]

RETRY_US: Final = 500_000
MAX_RETRIES: Final = 5
SUPPORTED_NAV_CMDS: Final = frozenset({16, 17, 19, 20, 21, 22, 178})
_REL_FRAMES: Final = frozenset({mav.MAV_FRAME_GLOBAL_RELATIVE_ALT, mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT})
_ABS_FRAMES: Final = frozenset({mav.MAV_FRAME_GLOBAL, mav.MAV_FRAME_GLOBAL_INT})
_NO_POS_CMDS: Final = frozenset({20, 178})  # RTL and DO_CHANGE_SPEED carry no position


class MissionService:
    def __init__(self, inst: MavlinkInstance) -> None:
        self.inst = inst
        self._up: dict[str, Any] | None = None     # upload in progress
        self._down_partner: tuple[int, int] | None = None
        self._result_sub = inst.module.subscribe("mission_result")
        self._last_reached = -1
        self.uploads = 0

    def handlers(self) -> dict[int, Callable[[Any], None]]:
        return {mav.MAVLINK_MSG_ID_MISSION_COUNT: self._on_count,
                mav.MAVLINK_MSG_ID_MISSION_ITEM_INT: self._on_item,
                mav.MAVLINK_MSG_ID_MISSION_ITEM: self._on_item,
                mav.MAVLINK_MSG_ID_MISSION_REQUEST_LIST: self._on_request_list,
                mav.MAVLINK_MSG_ID_MISSION_REQUEST_INT: self._on_request,
                mav.MAVLINK_MSG_ID_MISSION_REQUEST: self._on_request,
                mav.MAVLINK_MSG_ID_MISSION_ACK: self._on_ack,
                mav.MAVLINK_MSG_ID_MISSION_CLEAR_ALL: self._on_clear,
                mav.MAVLINK_MSG_ID_MISSION_SET_CURRENT: self._on_set_current}

    def store(self) -> Any:
        try:
            from firmware.modules.dataman import find_store
        except ImportError:
            return None
        return find_store(self.inst.system)

    def _ack(self, m: Any, result: int, mission_type: int = 0) -> None:
        self.inst.send(mav.MAVLink_mission_ack_message(m.get_srcSystem(), m.get_srcComponent(),
                                                       result, mission_type))

    def _check_type(self, m: Any) -> Any:
        """The store for a mission-type request, or None after answering why not."""
        mtype = getattr(m, "mission_type", 0)
        if mtype != mav.MAV_MISSION_TYPE_MISSION:
            self._ack(m, mav.MAV_MISSION_UNSUPPORTED, mtype)
            return None
        store = self.store()
        if store is None:
            self.inst.send_text(mav.MAV_SEVERITY_ERROR, "Mission storage (dataman) not running")
            self._ack(m, mav.MAV_MISSION_ERROR, mtype)
        return store

    # -- upload -----------------------------------------------------------------------------

    def _on_count(self, m: Any) -> None:
        store = self._check_type(m)
        if store is None:
            return
        from firmware.modules.dataman.store import MAX_ITEMS

        if m.count > MAX_ITEMS:
            self._ack(m, mav.MAV_MISSION_NO_SPACE)
            return
        if m.count == 0:
            store.clear()
            self._up = None
            self._ack(m, mav.MAV_MISSION_ACCEPTED)
            return
        # Items overwrite the inactive slot from index 0; commit() drops what lies beyond.
        self._up = {"partner": (m.get_srcSystem(), m.get_srcComponent()), "count": m.count,
                    "next": 0, "slot": store.inactive_slot(), "sent_us": 0, "tries": 0,
                    "store": store, "current": 0}
        self._request_next()

    def _request_next(self) -> None:
        up = self._up
        assert up is not None
        sysid, compid = up["partner"]
        self.inst.send(mav.MAVLink_mission_request_int_message(sysid, compid, up["next"], 0))
        up["sent_us"] = self.inst.time_us()
        up["tries"] += 1

    def _on_item(self, m: Any) -> None:
        up = self._up
        if getattr(m, "mission_type", 0) != mav.MAV_MISSION_TYPE_MISSION:
            self._ack(m, mav.MAV_MISSION_UNSUPPORTED, m.mission_type)
            return
        if up is None:
            return  # a late duplicate after the upload ended
        if m.seq != up["next"]:
            if m.seq < up["next"]:
                return  # a repeat of an item already stored
            self._ack(m, mav.MAV_MISSION_INVALID_SEQUENCE)
            return
        result, item = self._to_item(m, up["store"])
        if item is None:
            self._ack(m, result)
            self._up = None
            return
        up["store"].write_item(up["slot"], m.seq, item)
        if m.current:
            up["current"] = m.seq
        up["next"] += 1
        up["tries"] = 0
        if up["next"] < up["count"]:
            self._request_next()
            return
        up["store"].commit(up["slot"], up["count"], up["current"])
        self._up = None
        self.uploads += 1
        self._ack(m, mav.MAV_MISSION_ACCEPTED)

    def _to_item(self, m: Any, store: Any) -> tuple[int, Any]:
        cmd = int(m.command)
        if cmd not in SUPPORTED_NAV_CMDS:
            self.inst.send_text(mav.MAV_SEVERITY_CRITICAL,
                                f"Mission item {m.seq}: command {cmd} not supported")
            return mav.MAV_MISSION_UNSUPPORTED, None
        is_int = m.get_msgId() == mav.MAVLINK_MSG_ID_MISSION_ITEM_INT
        lat = m.x / 1e7 if is_int else float(m.x)
        lon = m.y / 1e7 if is_int else float(m.y)
        if m.frame in _REL_FRAMES:
            rel = True
        elif m.frame in _ABS_FRAMES:
            rel = False
        elif cmd in _NO_POS_CMDS or m.frame == mav.MAV_FRAME_MISSION:
            rel = True
        else:
            return mav.MAV_MISSION_UNSUPPORTED_FRAME, None
        item = store.new_item(lat=lat, lon=lon, altitude=float(m.z), altitude_is_relative=rel,
                              nav_cmd=cmd, frame=3 if rel else 0,
                              autocontinue=bool(m.autocontinue), origin=0)
        if cmd == 16:
            item.time_inside = max(float(m.param1), 0.0)
            item.acceptance_radius = float(m.param2)
            item.yaw = math.radians(m.param4) if math.isfinite(m.param4) else math.nan
        elif cmd == 19:
            item.time_inside = max(float(m.param1), 0.0)
            item.loiter_radius = float(m.param3)
        elif cmd == 17:
            item.loiter_radius = float(m.param3)
        elif cmd in (21, 22):
            item.yaw = math.radians(m.param4) if math.isfinite(m.param4) else math.nan
        elif cmd == 178:  # DO_CHANGE_SPEED: param2 speed (m/s), -1 or NaN: no change
            item.speed_m_s = float(m.param2) if math.isfinite(m.param2) and m.param2 > 0 else -1.0
        return mav.MAV_MISSION_ACCEPTED, item

    # -- download -----------------------------------------------------------------------------

    def _on_request_list(self, m: Any) -> None:
        store = self._check_type(m)
        if store is None:
            return
        self._down_partner = (m.get_srcSystem(), m.get_srcComponent())
        self.inst.send(mav.MAVLink_mission_count_message(m.get_srcSystem(), m.get_srcComponent(),
                                                         store.count, 0))

    def _on_request(self, m: Any) -> None:
        store = self._check_type(m)
        if store is None:
            return
        if self._up is not None:
            return
        item = store.item(m.seq)
        if item is None:
            self._ack(m, mav.MAV_MISSION_INVALID_SEQUENCE)
            return
        as_int = m.get_msgId() == mav.MAVLINK_MSG_ID_MISSION_REQUEST_INT
        self.inst.send(self._from_item(m, item, store, as_int))

    def _from_item(self, m: Any, it: Any, store: Any, as_int: bool) -> Any:
        cmd = int(it.nav_cmd)
        p1 = p2 = p3 = 0.0
        p4 = math.degrees(it.yaw) if math.isfinite(it.yaw) else math.nan
        if cmd == 16:
            p1, p2 = it.time_inside, it.acceptance_radius
        elif cmd == 19:
            p1, p3 = it.time_inside, it.loiter_radius
        elif cmd == 17:
            p3 = it.loiter_radius
        elif cmd == 178:
            p1, p2, p3 = 1.0, it.speed_m_s, -1.0  # ground speed, m/s, throttle unchanged
        frame = (mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT if as_int else
                 mav.MAV_FRAME_GLOBAL_RELATIVE_ALT) if it.altitude_is_relative else \
            (mav.MAV_FRAME_GLOBAL_INT if as_int else mav.MAV_FRAME_GLOBAL)
        current = int(m.seq == store.current_seq)
        args = (m.get_srcSystem(), m.get_srcComponent(), m.seq, frame, cmd, current,
                int(it.autocontinue), p1, p2, p3, p4)
        if as_int:
            return mav.MAVLink_mission_item_int_message(
                *args, round(it.lat * 1e7), round(it.lon * 1e7), it.altitude, 0)
        return mav.MAVLink_mission_item_message(*args, it.lat, it.lon, it.altitude, 0)

    def _on_ack(self, m: Any) -> None:
        self._down_partner = None

    # -- other ------------------------------------------------------------------------------

    def _on_clear(self, m: Any) -> None:
        store = self._check_type(m)
        if store is None:
            return
        store.clear()
        self._up = None
        self._ack(m, mav.MAV_MISSION_ACCEPTED)

    def _on_set_current(self, m: Any) -> None:
        store = self.store()
        if store is None:
            return
        if not store.set_current(int(m.seq)):
            self.inst.send_text(mav.MAV_SEVERITY_ERROR, f"Mission item {m.seq} does not exist")
        # the MISSION_CURRENT stream confirms the new item; send it now
        self.inst.send_stream_once(mav.MAVLINK_MSG_ID_MISSION_CURRENT)

    def update(self, now_us: int) -> None:
        up = self._up
        if up is not None and now_us - up["sent_us"] >= RETRY_US:
            if up["tries"] >= MAX_RETRIES:
                sysid, compid = up["partner"]
                self.inst.send(mav.MAVLink_mission_ack_message(
                    sysid, compid, mav.MAV_MISSION_OPERATION_CANCELLED, 0))
                self.inst.send_text(mav.MAV_SEVERITY_ERROR, "Mission upload timed out")
                self._up = None
            else:
                self._request_next()
        res = self._result_sub.update()
        if res is not None and res.seq_reached >= 0 and res.seq_reached != self._last_reached:
            self._last_reached = int(res.seq_reached)
            self.inst.send(mav.MAVLink_mission_item_reached_message(self._last_reached))
