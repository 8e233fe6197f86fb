"""The mission protocol against dataman's :class:`MissionStore`.

Upload: MISSION_COUNT -> MISSION_REQUEST_INT for each item -> MISSION_ITEM_INT (or the float
MISSION_ITEM) -> MISSION_ACK. Items go into the store's inactive slot, and only a complete
upload is committed, so the navigator never sees half a mission (PX4's two-slot scheme). A
request not answered within :data:`RETRY_US` is repeated; after :data:`MAX_RETRIES` the upload
is abandoned with MAV_MISSION_OPERATION_CANCELLED.

Download: MISSION_REQUEST_LIST -> MISSION_COUNT; MISSION_REQUEST_INT/MISSION_REQUEST for each
sequence number; the GCS's MISSION_ACK ends it. Also MISSION_CLEAR_ALL, MISSION_SET_CURRENT,
and MISSION_ITEM_REACHED when the navigator reports a new reached item.

Fence and rally point lists (mission_type FENCE and RALLY) go to
:class:`~firmware.modules.mavlink.fence_rally.PointsService` and dataman's fence and rally
stores; MISSION_CLEAR_ALL with MAV_MISSION_TYPE_ALL clears all three lists (PX4). Other
mission types are MAV_MISSION_UNSUPPORTED.

Bad input: a MISSION_COUNT beyond what the storage holds is MAV_MISSION_NO_SPACE at once (as
PX4); every item, float or int, goes through one check (:func:`check_item`) that answers
MAV_MISSION_UNSUPPORTED_FRAME or MAV_MISSION_UNSUPPORTED as PX4's parse_mavlink_mission_item
does, and, the emulator's own stricter choice, MAV_MISSION_INVALID_PARAM1..4 / PARAM5_X /
PARAM6_Y / PARAM7 for infinite parameters and non-finite or out-of-range positions (PX4 stores
those and leaves them to the navigator's feasibility check; refusing them here keeps the
stored mission downloadable and flyable), and aborts the upload; a failed save is
MAV_MISSION_ERROR (as PX4). In each case the previous mission stays active. A download asked
for during an upload is ignored with a STATUSTEXT, as PX4 does. Whatever the store holds
downloads (values no message field can carry are sent as NaN / INT32_MAX, MAVLink's
"unknown"), and a handler that fails anyway answers MAV_MISSION_ERROR instead of going silent
(and is counted and logged as a handler error).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Final

from firmware.modules.mavlink.dialect import mav

if TYPE_CHECKING:
    from firmware.modules.mavlink.instance import MavlinkInstance

__all__ = ["SUPPORTED_NAV_CMDS", "MissionService", "check_item", "position_deg"]

RETRY_US: Final = 500_000
MAX_RETRIES: Final = 5
SUPPORTED_NAV_CMDS: Final = frozenset({16, 17, 19, 20, 21, 22, 178, 3000})
_REL_FRAMES: Final = frozenset({mav.MAV_FRAME_GLOBAL_RELATIVE_ALT, mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT})
_ABS_FRAMES: Final = frozenset({mav.MAV_FRAME_GLOBAL, mav.MAV_FRAME_GLOBAL_INT})
#: RTL, DO_CHANGE_SPEED and DO_VTOL_TRANSITION carry no position
_NO_POS_CMDS: Final = frozenset({20, 178, 3000})
_GLOBAL_FRAMES: Final = _REL_FRAMES | _ABS_FRAMES
#: the parameters (1..4) each command uses; NaN in them is MAVLink's "default/unchanged"
#: (yaw: keep the heading mode; hold time: none; radii: NAV_ACC_RAD / the default; speed: no
#: change), infinity is never meaningful (the emulator's check). Unused parameters are
#: ignored.
_USED_PARAMS: Final[dict[int, tuple[int, ...]]] = {
    16: (1, 2, 4), 17: (3, 4), 19: (1, 3), 20: (), 21: (4,), 22: (4,), 178: (2,),
    3000: (1,)}
_INVALID_PARAM: Final = (mav.MAV_MISSION_INVALID_PARAM1, mav.MAV_MISSION_INVALID_PARAM2,
                         mav.MAV_MISSION_INVALID_PARAM3, mav.MAV_MISSION_INVALID_PARAM4)
INT32_MAX: Final = 0x7FFFFFFF
#: the largest finite float32 (a MAVLink float field)
FLT_MAX: Final = 3.4028234663852886e38


def position_deg(m: Any) -> tuple[float, float]:
    """An item's x/y in degrees: MISSION_ITEM_INT carries degE7 integers, MISSION_ITEM floats."""
    if m.get_msgId() == mav.MAVLINK_MSG_ID_MISSION_ITEM_INT:
        return int(m.x) / 1e7, int(m.y) / 1e7
    return float(m.x), float(m.y)


def check_item(command: int, frame: int, params: tuple[float, float, float, float],
               lat_deg: float, lon_deg: float, alt_m: float) -> int:
    """The one validation of a mission item, for both protocols: MAV_MISSION_ACCEPTED or a
    MAV_MISSION_RESULT, the frame first, then the command, then the fields.

    The frame and command codes are PX4's, except that RTL and DO_CHANGE_SPEED are also
    taken in a global frame (PX4 takes them only in MAV_FRAME_MISSION; the emulator's own
    GCS client sends RTL in the mission's global frame). The field codes (INVALID_PARAMn for
    infinity, PARAM5_X / PARAM6_Y / PARAM7 for positions) are the emulator's choice: PX4
    stores such items and leaves them to the navigator's feasibility check."""
    if frame in _GLOBAL_FRAMES:
        if command not in SUPPORTED_NAV_CMDS:
            return mav.MAV_MISSION_UNSUPPORTED
    elif frame == mav.MAV_FRAME_MISSION:
        if command not in _NO_POS_CMDS:  # PX4: a position command needs a global frame
            return mav.MAV_MISSION_UNSUPPORTED
    else:
        return mav.MAV_MISSION_UNSUPPORTED_FRAME
    for n in _USED_PARAMS[command]:
        if math.isinf(params[n - 1]):
            return int(_INVALID_PARAM[n - 1])
    if command not in _NO_POS_CMDS:
        if not (math.isfinite(lat_deg) and -90.0 <= lat_deg <= 90.0):
            return mav.MAV_MISSION_INVALID_PARAM5_X
        if not (math.isfinite(lon_deg) and -180.0 <= lon_deg <= 180.0):
            return mav.MAV_MISSION_INVALID_PARAM6_Y
        if not math.isfinite(alt_m):
            return mav.MAV_MISSION_INVALID_PARAM7
    return mav.MAV_MISSION_ACCEPTED


def _e7(deg: float) -> int:
    """Degrees as MAVLink degE7 for a download: INT32_MAX ("unknown") if it cannot be one."""
    if not math.isfinite(deg):
        return INT32_MAX
    return max(-INT32_MAX, min(INT32_MAX, round(deg * 1e7)))


def _float_field(v: float) -> float:
    """``v`` for a MAVLink float field of a download: beyond float32's range it becomes
    infinity of its sign (a download never fails; an upload refuses infinity)."""
    return v if not math.isfinite(v) or abs(v) <= FLT_MAX else math.copysign(math.inf, v)


class MissionService:
    def __init__(self, inst: MavlinkInstance) -> None:
        self.inst = inst
        self._up: dict[str, Any] | None = None     # upload in progress
        self._down_partner: tuple[int, int] | None = None
        self._result_sub = inst.module.subscribe("mission_result")
        self._last_reached = -1
        self.uploads = 0
        from firmware.modules.mavlink.fence_rally import PointsService

        #: the fence and rally lists' side of the protocol
        self.points = PointsService(inst)

    def handlers(self) -> dict[int, Callable[[Any], None]]:
        table: dict[int, Callable[[Any], None]] = {
            mav.MAVLINK_MSG_ID_MISSION_COUNT: self._on_count,
            mav.MAVLINK_MSG_ID_MISSION_ITEM_INT: self._on_item,
            mav.MAVLINK_MSG_ID_MISSION_ITEM: self._on_item,
            mav.MAVLINK_MSG_ID_MISSION_REQUEST_LIST: self._on_request_list,
            mav.MAVLINK_MSG_ID_MISSION_REQUEST_INT: self._on_request,
            mav.MAVLINK_MSG_ID_MISSION_REQUEST: self._on_request,
            mav.MAVLINK_MSG_ID_MISSION_ACK: self._on_ack,
            mav.MAVLINK_MSG_ID_MISSION_CLEAR_ALL: self._on_clear,
            mav.MAVLINK_MSG_ID_MISSION_SET_CURRENT: self._on_set_current}
        return {msg_id: self._guarded(fn) for msg_id, fn in table.items()}

    def _guarded(self, fn: Callable[[Any], None]) -> Callable[[Any], None]:
        """``fn`` answering MAV_MISSION_ERROR if it fails: the GCS's transfer ends with an
        answer instead of timing out, and a half-done upload is dropped (the previous
        mission stays active). The failure is still a bug: it is reported to the instance
        (:meth:`~MavlinkInstance.handler_failed`), which counts and logs it."""
        def handle(m: Any) -> None:
            try:
                fn(m)
            except Exception as exc:  # noqa: BLE001 - a GCS message must get an answer
                self._up = None
                self.points.up = None
                self.inst.handler_failed(m, exc)
                self._ack(m, mav.MAV_MISSION_ERROR, int(getattr(m, "mission_type", 0)))
        return handle

    def store(self) -> Any:
        try:
            from firmware.modules.dataman import find_store
        except ImportError:
            return None
        return find_store(self.inst.system)

    def _ack(self, m: Any, result: int, mission_type: int = 0) -> None:
        self.inst.send(mav.MAVLink_mission_ack_message(m.get_srcSystem(), m.get_srcComponent(),
                                                       result, mission_type))

    def _for_points(self, m: Any) -> bool:
        """Whether ``m`` is for the fence or rally list (then the points service has it)."""
        return int(getattr(m, "mission_type", 0)) in (mav.MAV_MISSION_TYPE_FENCE,
                                                      mav.MAV_MISSION_TYPE_RALLY)

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
        if self._for_points(m):
            self.points.on_count(m)
            return
        store = self._check_type(m)
        if store is None:
            return
        if m.count > store.capacity:  # PX4: refused before any item is requested
            self.inst.send_text(mav.MAV_SEVERITY_CRITICAL,
                                f"Mission of {m.count} items refused: storage holds "
                                f"{store.capacity}")
            self._ack(m, mav.MAV_MISSION_NO_SPACE)
            return
        if m.count == 0:
            self._up = None
            self._commit_or_error(m, store.clear)
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
        if self._for_points(m):
            self.points.on_item(m)
            return
        up = self._up
        if getattr(m, "mission_type", 0) != mav.MAV_MISSION_TYPE_MISSION:
            self._ack(m, mav.MAV_MISSION_UNSUPPORTED, m.mission_type)
            return
        if up is None:
            return  # a late duplicate after the upload ended
        if (m.get_srcSystem(), m.get_srcComponent()) != up["partner"]:
            return  # PX4: an item from another ground station than the uploader is ignored
        if m.seq != up["next"]:
            if m.seq < up["next"]:
                return  # a repeat of an item already stored
            self._ack(m, mav.MAV_MISSION_INVALID_SEQUENCE)
            return
        store = up["store"]
        result, item = self._to_item(m, store)
        if item is None:
            self._ack(m, result)
            self._up = None
            return
        if up["slot"] != store.inactive_slot():  # another link committed meanwhile
            self._abort(m, "Mission upload aborted: the mission changed meanwhile")
            return
        store.write_item(up["slot"], m.seq, item)
        if m.current:
            up["current"] = m.seq
        up["next"] += 1
        up["tries"] = 0
        if up["next"] < up["count"]:
            self._request_next()
            return
        self._up = None
        if self._commit_or_error(m, lambda: store.commit(up["slot"], up["count"],
                                                          up["current"])):
            self.uploads += 1

    def _commit_or_error(self, m: Any, commit: Callable[[], Any]) -> bool:
        """Run a store change; MAV_MISSION_ACCEPTED, or MAV_MISSION_ERROR if it could not be
        saved (PX4's answer to a storage failure; the previous mission stays active)."""
        from firmware.modules.dataman.store import SaveError

        try:
            commit()
        except SaveError as exc:
            self._abort(m, f"Mission not stored: {exc}")
            return False
        self._ack(m, mav.MAV_MISSION_ACCEPTED)
        return True

    def _abort(self, m: Any, text: str) -> None:
        self._up = None
        self.inst.send_text(mav.MAV_SEVERITY_CRITICAL, text)
        self._ack(m, mav.MAV_MISSION_ERROR)

    def _to_item(self, m: Any, store: Any) -> tuple[int, Any]:
        cmd = int(m.command)
        lat, lon = position_deg(m)
        p1, p2, p3, p4 = float(m.param1), float(m.param2), float(m.param3), float(m.param4)
        alt = float(m.z)
        result = check_item(cmd, int(m.frame), (p1, p2, p3, p4), lat, lon, alt)
        if result != mav.MAV_MISSION_ACCEPTED:
            self.inst.send_text(mav.MAV_SEVERITY_CRITICAL,
                                f"Mission item {m.seq} (command {cmd}) rejected: "
                                f"{_result_name(result)}")
            return result, None
        if cmd in _NO_POS_CMDS:
            lat = lon = 0.0
            alt = 0.0
        rel = m.frame not in _ABS_FRAMES
        item = store.new_item(lat=lat, lon=lon, altitude=alt, altitude_is_relative=rel,
                              nav_cmd=cmd, frame=3 if rel else 0,
                              autocontinue=bool(m.autocontinue), origin=0)
        yaw = math.radians(p4) if math.isfinite(p4) else math.nan
        if cmd == 16:
            item.time_inside = p1 if p1 > 0 else 0.0
            item.acceptance_radius = p2 if math.isfinite(p2) else 0.0
            item.yaw = yaw
        elif cmd == 19:
            item.time_inside = p1 if p1 > 0 else 0.0
            item.loiter_radius = p3 if math.isfinite(p3) else 0.0
        elif cmd == 17:
            item.loiter_radius = p3 if math.isfinite(p3) else 0.0
            item.yaw = yaw
        elif cmd in (21, 22):
            item.yaw = yaw
        elif cmd == 178:  # DO_CHANGE_SPEED: param2 speed (m/s), -1 or NaN: no change
            item.speed_m_s = p2 if math.isfinite(p2) and p2 > 0 else -1.0
        elif cmd == 3000:  # DO_VTOL_TRANSITION: param1 the state, in PX4's params[0]
            item.time_inside = p1 if math.isfinite(p1) else 0.0
        return mav.MAV_MISSION_ACCEPTED, item

    # -- download -----------------------------------------------------------------------------

    def _busy(self, m: Any) -> bool:
        """During an upload a download is ignored with a STATUSTEXT, as PX4's
        handle_mission_request_list / handle_mission_request_both do (no MISSION_COUNT that
        items would never follow, and no MISSION_ACK): the GCS retries, and the download works
        once the upload ends, is cancelled (MISSION_ACK OPERATION_CANCELLED) or times out."""
        if self._up is None:
            return False
        if m.get_msgId() == mav.MAVLINK_MSG_ID_MISSION_REQUEST_LIST:
            self.inst.send_text(mav.MAV_SEVERITY_INFO,
                                "Mission download request ignored, already active")
        else:
            self.inst.send_text(mav.MAV_SEVERITY_CRITICAL, "WPM: REJ. CMD: Busy")
        return True

    def _on_request_list(self, m: Any) -> None:
        if self._for_points(m):
            self.points.on_request_list(m)
            return
        store = self._check_type(m)
        if store is None or self._busy(m):
            return
        self._down_partner = (m.get_srcSystem(), m.get_srcComponent())
        self.inst.send(mav.MAVLink_mission_count_message(m.get_srcSystem(), m.get_srcComponent(),
                                                         store.count, 0))

    def _on_request(self, m: Any) -> None:
        if self._for_points(m):
            self.points.on_request(m)
            return
        store = self._check_type(m)
        if store is None or self._busy(m):
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
        p4 = math.degrees(it.yaw) if math.isfinite(it.yaw) else math.nan  # NaN: heading mode
        if cmd == 16:
            p1, p2 = it.time_inside, it.acceptance_radius
        elif cmd == 19:
            p1, p3 = it.time_inside, it.loiter_radius
        elif cmd == 17:
            p3 = it.loiter_radius
        elif cmd == 178:
            p1, p2, p3 = 1.0, it.speed_m_s, -1.0  # ground speed, m/s, throttle unchanged
        elif cmd == 3000:
            p1 = it.time_inside
        frame = (mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT if as_int else
                 mav.MAV_FRAME_GLOBAL_RELATIVE_ALT) if it.altitude_is_relative else \
            (mav.MAV_FRAME_GLOBAL_INT if as_int else mav.MAV_FRAME_GLOBAL)
        current = int(m.seq == store.current_seq)
        args = (m.get_srcSystem(), m.get_srcComponent(), m.seq, frame, cmd & 0xFFFF, current,
                int(bool(it.autocontinue)), _float_field(float(p1)), _float_field(float(p2)), _float_field(float(p3)),
                _float_field(float(p4)))
        alt = _float_field(float(it.altitude))
        if as_int:
            return mav.MAVLink_mission_item_int_message(*args, _e7(float(it.lat)),
                                                        _e7(float(it.lon)), alt, 0)
        return mav.MAVLink_mission_item_message(*args, _float_field(float(it.lat)), _float_field(float(it.lon)),
                                                alt, 0)

    def _on_ack(self, m: Any) -> None:
        if self._for_points(m):
            self.points.on_ack(m)
            return
        self._down_partner = None
        up = self._up
        if up is not None and m.type == mav.MAV_MISSION_OPERATION_CANCELLED and \
                (m.get_srcSystem(), m.get_srcComponent()) == up["partner"]:
            self._up = None  # the uploader gave up (the mission protocol's cancel)
            self.inst.send_text(mav.MAV_SEVERITY_INFO, "Mission upload cancelled")

    # -- other ------------------------------------------------------------------------------

    def _on_clear(self, m: Any) -> None:
        if self._for_points(m):
            self.points.on_clear(m)
            return
        if int(getattr(m, "mission_type", 0)) == mav.MAV_MISSION_TYPE_ALL:
            self._clear_all(m)
            return
        store = self._check_type(m)
        if store is None:
            return
        self._up = None
        self._commit_or_error(m, store.clear)

    def _clear_all(self, m: Any) -> None:
        """MISSION_CLEAR_ALL for MAV_MISSION_TYPE_ALL: mission, fence and rally points (PX4);
        one MISSION_ACK, ERROR if any of them could not be saved."""
        from firmware.modules.dataman.store import SaveError, StoreError

        stores = [self.store(), self.points.store(mav.MAV_MISSION_TYPE_FENCE),
                  self.points.store(mav.MAV_MISSION_TYPE_RALLY)]
        if any(st is None for st in stores):
            self.inst.send_text(mav.MAV_SEVERITY_ERROR, "Mission storage (dataman) not running")
            self._ack(m, mav.MAV_MISSION_ERROR, mav.MAV_MISSION_TYPE_ALL)
            return
        self._up = self.points.up = None
        result = mav.MAV_MISSION_ACCEPTED
        for st in stores:
            try:
                st.clear()
            except (SaveError, StoreError) as exc:
                self.inst.send_text(mav.MAV_SEVERITY_CRITICAL, f"Not cleared: {exc}")
                result = mav.MAV_MISSION_ERROR
        self._ack(m, result, mav.MAV_MISSION_TYPE_ALL)

    def _on_set_current(self, m: Any) -> None:
        store = self.store()
        if store is None:
            return
        from firmware.modules.dataman.store import SaveError

        try:
            if not store.set_current(int(m.seq)):
                self.inst.send_text(mav.MAV_SEVERITY_ERROR,
                                    f"Mission item {m.seq} does not exist")
        except SaveError as exc:
            self.inst.send_text(mav.MAV_SEVERITY_ERROR, f"Current mission item not saved: {exc}")
        # the MISSION_CURRENT stream confirms the new item; send it now
        self.inst.send_stream_once(mav.MAVLINK_MSG_ID_MISSION_CURRENT)

    def update(self, now_us: int) -> None:
        self.points.update(now_us)
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


def _result_name(result: int) -> str:
    entry = mav.enums["MAV_MISSION_RESULT"].get(result)
    return entry.name if entry is not None else str(result)
