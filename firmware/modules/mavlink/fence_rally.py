"""The mission protocol for geofence and rally point lists (mission_type FENCE = 1, RALLY = 2).

The same messages as missions (MISSION_COUNT, MISSION_REQUEST_INT, MISSION_ITEM_INT or
MISSION_ITEM, MISSION_ACK, MISSION_REQUEST_LIST, MISSION_CLEAR_ALL), each carrying its
mission_type, against dataman's fence and rally stores (:class:`~firmware.modules.dataman.
points.PointStore`). :class:`~firmware.modules.mavlink.mission.MissionService` hands every
message of these types here.

Items, as PX4's mavlink_mission.cpp parses them: in a global frame (relative or AMSL, float or
int), fence commands MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION / _EXCLUSION (param1 the
polygon's vertex count), NAV_FENCE_CIRCLE_INCLUSION / _EXCLUSION (param1 the radius) and
NAV_FENCE_RETURN_POINT; rally lists NAV_RALLY_POINT. A download gives them back as PX4 formats
them: param1 the vertex count or radius, the other parameters 0.

An upload is collected whole and stored only when complete and valid, so the previous list
stays active (and saved) whatever goes wrong. The answers:

* MISSION_COUNT beyond what the storage holds, or a polygon whose vertex count does:
  MAV_MISSION_NO_SPACE (PX4's answer to a count over its maximum);
* a frame other than the global ones: MAV_MISSION_UNSUPPORTED_FRAME; a command that is not of
  the list's type: MAV_MISSION_UNSUPPORTED (PX4);
* a polygon of fewer than 3 vertices: MAV_MISSION_ERROR (PX4's "Fence: too few vertices");
* the emulator's checks, stricter than PX4 (which stores such items and then misreads them):
  a vertex count that is not finite, that the following vertices do not repeat, or that the
  list ends before: MAV_MISSION_INVALID_PARAM1; a circle radius that is not a positive finite
  number: MAV_MISSION_INVALID_PARAM1; a self-intersecting polygon (PX4's point-in-polygon test
  "only supports non-complex polygons"): MAV_MISSION_ERROR; a latitude, longitude or altitude
  that is not finite or out of range: MAV_MISSION_INVALID_PARAM5_X / PARAM6_Y / PARAM7;
* a save that fails: MAV_MISSION_ERROR.

Each refusal has a STATUSTEXT saying why and ends the upload.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Final

from firmware.modules.dataman.points import (
    FENCE_CIRCLE_EXCLUSION,
    FENCE_CIRCLE_INCLUSION,
    FENCE_CMDS,
    FENCE_POLYGON_EXCLUSION,
    FENCE_POLYGON_INCLUSION,
    RALLY_POINT,
    Point,
    fence_problem,
    lat_lon_deg,
)
from firmware.modules.mavlink.dialect import mav
from firmware.modules.mavlink.mission import (
    INT32_MAX,
    MAX_RETRIES,
    RETRY_US,
    _e7,
    _float_field,
    _result_name,
    position_deg,
)

if TYPE_CHECKING:
    from firmware.modules.mavlink.instance import MavlinkInstance

__all__ = ["POINT_TYPES", "PointsService", "check_point"]

FENCE: Final = mav.MAV_MISSION_TYPE_FENCE
RALLY: Final = mav.MAV_MISSION_TYPE_RALLY
POINT_TYPES: Final = frozenset({FENCE, RALLY})
_REL_FRAMES: Final = frozenset({mav.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                                mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT})
_GLOBAL_FRAMES: Final = _REL_FRAMES | {mav.MAV_FRAME_GLOBAL, mav.MAV_FRAME_GLOBAL_INT}
_POLYGON: Final = frozenset({FENCE_POLYGON_INCLUSION, FENCE_POLYGON_EXCLUSION})
_CIRCLE: Final = frozenset({FENCE_CIRCLE_INCLUSION, FENCE_CIRCLE_EXCLUSION})
#: fence_problem's kinds -> MAV_MISSION_RESULT
_PROBLEM_RESULT: Final = {"too_few": mav.MAV_MISSION_ERROR,
                          "self_intersecting": mav.MAV_MISSION_ERROR,
                          "vertex_count": mav.MAV_MISSION_INVALID_PARAM1,
                          "radius": mav.MAV_MISSION_INVALID_PARAM1,
                          "command": mav.MAV_MISSION_UNSUPPORTED}


def check_point(mission_type: int, command: int, frame: int, param1: float, lat_deg: float,
                lon_deg: float, alt_m: float, capacity: int) -> int:
    """One fence or rally item's own fields: MAV_MISSION_ACCEPTED or why not (the frame, then
    the command, then the fields; the list's structure is :func:`fence_problem`'s)."""
    if frame not in _GLOBAL_FRAMES:
        return mav.MAV_MISSION_UNSUPPORTED_FRAME
    if (mission_type == FENCE and command not in FENCE_CMDS) or \
            (mission_type == RALLY and command != RALLY_POINT):
        return mav.MAV_MISSION_UNSUPPORTED
    if command in _POLYGON:
        if not math.isfinite(param1):
            return mav.MAV_MISSION_INVALID_PARAM1
        if param1 + 0.5 >= capacity + 1:
            return mav.MAV_MISSION_NO_SPACE
    if command in _CIRCLE and not (math.isfinite(param1) and param1 > 0.0):
        return mav.MAV_MISSION_INVALID_PARAM1
    if not (math.isfinite(lat_deg) and -90.0 <= lat_deg <= 90.0):
        return mav.MAV_MISSION_INVALID_PARAM5_X
    if not (math.isfinite(lon_deg) and -180.0 <= lon_deg <= 180.0):
        return mav.MAV_MISSION_INVALID_PARAM6_Y
    if not math.isfinite(alt_m) or abs(alt_m) > 1e7:
        return mav.MAV_MISSION_INVALID_PARAM7
    return mav.MAV_MISSION_ACCEPTED


class PointsService:
    """Uploads, downloads and clears of the fence and rally lists on one link."""

    def __init__(self, inst: MavlinkInstance) -> None:
        self.inst = inst
        self.up: dict[str, Any] | None = None
        self.uploads = 0

    def store(self, mission_type: int) -> Any:
        try:
            from firmware.modules.dataman import find_fence, find_rally
        except ImportError:
            return None
        return (find_fence if mission_type == FENCE else find_rally)(self.inst.system)

    def _ack(self, m: Any, result: int, mission_type: int) -> None:
        self.inst.send(mav.MAVLink_mission_ack_message(m.get_srcSystem(), m.get_srcComponent(),
                                                       result, mission_type))

    def _store_or_error(self, m: Any) -> Any:
        mtype = int(m.mission_type)
        store = self.store(mtype)
        if store is None:
            self.inst.send_text(mav.MAV_SEVERITY_ERROR, "Mission storage (dataman) not running")
            self._ack(m, mav.MAV_MISSION_ERROR, mtype)
        return store

    def _refuse(self, m: Any, result: int, text: str, mission_type: int) -> None:
        self.up = None
        self.inst.send_text(mav.MAV_SEVERITY_CRITICAL, text)
        self._ack(m, result, mission_type)

    def _commit(self, m: Any, store: Any, points: tuple[Point, ...], mtype: int) -> bool:
        from firmware.modules.dataman.store import SaveError, StoreError

        try:
            store.replace(points)
        except (SaveError, StoreError) as exc:
            self._refuse(m, mav.MAV_MISSION_ERROR, f"{store.name.capitalize()} not stored: "
                         f"{exc}", mtype)
            return False
        self._ack(m, mav.MAV_MISSION_ACCEPTED, mtype)
        return True

    # -- upload ---------------------------------------------------------------------------------

    def on_count(self, m: Any) -> None:
        store = self._store_or_error(m)
        if store is None:
            return
        mtype = int(m.mission_type)
        if m.count > store.capacity:
            self._refuse(m, mav.MAV_MISSION_NO_SPACE, f"{store.name.capitalize()} of {m.count} "
                         f"items refused: storage holds {store.capacity}", mtype)
            return
        if m.count == 0:
            self.up = None
            self._commit(m, store, (), mtype)
            return
        self.up = {"partner": (m.get_srcSystem(), m.get_srcComponent()), "type": mtype,
                   "count": int(m.count), "points": [], "sent_us": 0, "tries": 0,
                   "store": store}
        self._request_next()

    def _request_next(self) -> None:
        up = self.up
        assert up is not None
        sysid, compid = up["partner"]
        self.inst.send(mav.MAVLink_mission_request_int_message(sysid, compid, len(up["points"]),
                                                               up["type"]))
        up["sent_us"] = self.inst.time_us()
        up["tries"] += 1

    def on_item(self, m: Any) -> None:
        up = self.up
        mtype = int(m.mission_type)
        if up is None or (m.get_srcSystem(), m.get_srcComponent()) != up["partner"]:
            return  # a late duplicate, or another GCS than the uploader (PX4 ignores both)
        if mtype != up["type"]:
            self._ack(m, mav.MAV_MISSION_ERROR, mtype)  # PX4: "Unexpected mission type"
            return
        points: list[Point] = up["points"]
        if m.seq != len(points):
            if m.seq > len(points):
                self._ack(m, mav.MAV_MISSION_INVALID_SEQUENCE, mtype)
            return
        store = up["store"]
        cmd, frame, p1 = int(m.command), int(m.frame), float(m.param1)
        lat, lon = position_deg(m)
        alt = float(m.z)
        result = check_point(mtype, cmd, frame, p1, lat, lon, alt, store.capacity)
        if result != mav.MAV_MISSION_ACCEPTED:
            self._refuse(m, result, f"{store.name.capitalize()} item {m.seq} (command {cmd}) "
                         f"rejected: {_result_name(result)}", mtype)
            return
        is_int = m.get_msgId() == mav.MAVLINK_MSG_ID_MISSION_ITEM_INT
        lat_e7 = int(m.x) if is_int else _e7(lat)
        lon_e7 = int(m.y) if is_int else _e7(lon)
        points.append(Point(cmd, lat_e7, lon_e7, alt, frame in _REL_FRAMES,
                            max(0, min(0xFFFF, int(p1 + 0.5))) if cmd in _POLYGON else 0,
                            p1 if cmd in _CIRCLE else 0.0))
        done = len(points) == up["count"]
        if mtype == FENCE:
            problem = fence_problem(points, complete=done)
            if problem is not None:
                self._refuse(m, _PROBLEM_RESULT[problem.kind], problem.text, mtype)
                return
        up["tries"] = 0
        if not done:
            self._request_next()
            return
        self.up = None
        if self._commit(m, store, tuple(points), mtype):
            self.uploads += 1

    # -- download and the rest -------------------------------------------------------------------

    def _busy(self, m: Any) -> bool:
        """A download during an upload is ignored with PX4's STATUSTEXT, as for missions."""
        if self.up is None:
            return False
        self.inst.send_text(mav.MAV_SEVERITY_INFO,
                            "Mission download request ignored, already active")
        return True

    def on_request_list(self, m: Any) -> None:
        store = self._store_or_error(m)
        if store is None or self._busy(m):
            return
        self.inst.send(mav.MAVLink_mission_count_message(
            m.get_srcSystem(), m.get_srcComponent(), store.count, int(m.mission_type)))

    def on_request(self, m: Any) -> None:
        store = self._store_or_error(m)
        if store is None or self._busy(m):
            return
        mtype = int(m.mission_type)
        if not 0 <= m.seq < store.count:
            self._ack(m, mav.MAV_MISSION_INVALID_SEQUENCE, mtype)
            return
        p: Point = store.points[m.seq]
        as_int = m.get_msgId() == mav.MAVLINK_MSG_ID_MISSION_REQUEST_INT
        if p.relative:
            frame = mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT if as_int else \
                mav.MAV_FRAME_GLOBAL_RELATIVE_ALT
        else:
            frame = mav.MAV_FRAME_GLOBAL_INT if as_int else mav.MAV_FRAME_GLOBAL
        p1 = float(p.vertex_count) if p.nav_cmd in _POLYGON else \
            _float_field(p.radius_m) if p.nav_cmd in _CIRCLE else 0.0
        args = (m.get_srcSystem(), m.get_srcComponent(), m.seq, frame, p.nav_cmd, 0, 0,
                p1, 0.0, 0.0, 0.0)
        alt = _float_field(p.alt_m)
        if as_int:
            lat_e7 = max(-INT32_MAX, min(INT32_MAX, p.lat_e7))
            lon_e7 = max(-INT32_MAX, min(INT32_MAX, p.lon_e7))
            self.inst.send(mav.MAVLink_mission_item_int_message(*args, lat_e7, lon_e7, alt,
                                                                mtype))
        else:
            lat, lon = lat_lon_deg(p)
            self.inst.send(mav.MAVLink_mission_item_message(*args, lat, lon, alt, mtype))

    def on_ack(self, m: Any) -> None:
        up = self.up
        if up is not None and m.type == mav.MAV_MISSION_OPERATION_CANCELLED and \
                (m.get_srcSystem(), m.get_srcComponent()) == up["partner"]:
            self.up = None
            self.inst.send_text(mav.MAV_SEVERITY_INFO, "Mission upload cancelled")

    def on_clear(self, m: Any) -> None:
        store = self._store_or_error(m)
        if store is None:
            return
        self.up = None
        self._commit(m, store, (), int(m.mission_type))

    def update(self, now_us: int) -> None:
        up = self.up
        if up is not None and now_us - up["sent_us"] >= RETRY_US:
            if up["tries"] >= MAX_RETRIES:
                sysid, compid = up["partner"]
                self.inst.send(mav.MAVLink_mission_ack_message(
                    sysid, compid, mav.MAV_MISSION_OPERATION_CANCELLED, up["type"]))
                self.inst.send_text(mav.MAV_SEVERITY_ERROR, "Mission upload timed out")
                self.up = None
            else:
                self._request_next()
