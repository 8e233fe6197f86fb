"""Mission mode: fly the dataman mission item by item.

Per item: the setpoint (position, loiter, takeoff, land), reached-checks on the global position
(horizontal acceptance radius: the item's or NAV_ACC_RAD; altitude: NAV_MC_ALT_RAD), a hold
time (``time_inside``) once reached, then the next item if ``autocontinue``. As in PX4:

* a mission started on the ground whose first item is not a takeoff climbs vertically first, to
  the item's altitude but at least MIS_TAKEOFF_ALT above home;
* a land item far from the vehicle first flies there at the current altitude, then lands;
  landing completes the mission;
* a return item hands over to the commander (NAV_RETURN_TO_LAUNCH);
* after the last item the vehicle holds at it; the next activation after a finished mission
  starts again from item 0;
* yaw: the item's yaw if set, else heading towards the item.
* DO_VTOL_TRANSITION (3000, param1 3 multicopter / 4 fixed wing) asks vtol_att_control for the
  transition (``vehicle_command``) and holds the mission there, on the setpoint it had, until
  the commander reports the new vehicle type out of transition; a vehicle that is not a VTOL
  passes the item, as PX4.

On a fixed wing (PX4's navigator for planes): altitudes are reached within NAV_FW_ALT_RAD (see
the navigator), waypoints within the larger of their radius and the L1 distance; a takeoff
item (or the inserted climb) is a TAKEOFF setpoint at the item's position, or on the runway
heading from where the plane stands if it has none, and is reached by altitude alone: the
position controller climbs out on the runway heading, then the next item follows; loiter
items are LOITER setpoints on the item's loiter radius (else NAV_LOITER_RAD), reached once
within 1.2 times that radius; a land item is a LAND setpoint at the touchdown point at once
(no flight there at the current altitude first: the previous waypoint and the touchdown point
make the approach, which the position controller flies with its flare).
"""

from __future__ import annotations

import math
from typing import Any, Final

from firmware.modules.navigator.geo import bearing_rad, distance_m
from firmware.modules.navigator.modes import (
    SP_LAND,
    SP_LOITER,
    SP_POSITION,
    SP_TAKEOFF,
    NavMode,
)

__all__ = ["MissionMode"]

WAYPOINT: Final = 16
LOITER_UNLIM: Final = 17
LOITER_TIME: Final = 19
RTL: Final = 20
LAND: Final = 21
TAKEOFF: Final = 22
_POSITION_ITEMS: Final = frozenset({WAYPOINT, LOITER_UNLIM, LOITER_TIME, LAND, TAKEOFF})
_LOITER_ITEMS: Final = frozenset({LOITER_UNLIM, LOITER_TIME})
CMD_RTL: Final = 20

# work phases of one item
P_TAKEOFF_FIRST, P_ITEM, P_MOVE_TO_LAND, P_LAND, P_HOLD, P_DONE, P_TRANSITION = range(7)
DO_VTOL_TRANSITION: Final = 3000
VTOL_STATE_FW: Final = 4
VTOL_STATE_MC: Final = 3.0


DO_CHANGE_SPEED: Final = 178


class MissionMode(NavMode):
    name = "mission"

    def __init__(self, nav: Any) -> None:
        super().__init__(nav)
        self.items: list[Any] = []
        self.index = 0
        self.seq_reached = -1
        self.finished = False
        self.valid = False
        self.phase = P_DONE
        self.reached_at_us: int | None = None
        self.mission_id = 0
        self._to_fw = False      # the transition item's target: fixed wing (else multicopter)
        self._then_same_item = False  # a VTOL's land item waits for its back transition

    # -- mission (re)load -------------------------------------------------------------------

    def load(self, store: Any, mission: Any) -> None:
        """A new mission (or a jump): take the items, start at its current item."""
        self.items = list(store.items()) if store is not None else []
        self.mission_id = int(mission.mission_update_counter)
        self.index = int(mission.current_seq) if 0 <= mission.current_seq < len(self.items) \
            else 0
        self.seq_reached = -1
        self.finished = False
        self.valid = self._feasible()
        self.phase = P_DONE
        self.publish_result()

    def _feasible(self) -> bool:
        if not self.items:
            return False
        if self.nav.fixed_wing() and not self._fw_landing_ok():
            return False
        limit = self.nav.p["MIS_DIST_1WP"]
        home = self.nav.home()
        first = next((it for it in self.items if it.nav_cmd in _POSITION_ITEMS
                      and it.nav_cmd != TAKEOFF), None)
        if limit > 0 and home is not None and first is not None:
            d = distance_m(home[0], home[1], first.lat, first.lon)
            if d > limit:
                self.nav.warn(f"Mission rejected: first waypoint {d:.0f} m from home "
                              f"(MIS_DIST_1WP {limit:.0f} m)")
                return False
        outside = self._fence_violation()
        if outside is not None:
            self.nav.error(f"Geofence violation for waypoint {outside + 1}")
            return False
        return True

    def _fw_landing_ok(self) -> bool:
        """PX4's fixed-wing landing check: a plane lands along the line from the waypoint
        before the land item to the touchdown point, so a land item needs a position item
        right before it (it cannot be the first item either)."""
        for i, it in enumerate(self.items):
            if it.nav_cmd != LAND:
                continue
            prev = self.items[i - 1] if i > 0 else None
            if prev is None or prev.nav_cmd not in _POSITION_ITEMS or prev.nav_cmd == LAND:
                self.nav.warn(f"Mission rejected: fixed-wing landing (item {i + 1}) needs a "
                              "waypoint before it for the approach")
                return False
        return True

    def _fence_violation(self) -> int | None:
        """PX4's feasibility check against the uploaded fence (``checkGeofence``): the index
        of the first position item outside it, or None. Only with GF_ACTION above None, as
        the commander reacts to a breach only then; items without a position of their own
        (NaN: "here") are not checked."""
        from firmware.modules.commander.geofence import fence_areas, inside_fence
        from firmware.modules.dataman import find_fence

        params = self.nav.system.params
        if params is None or int(params.get("GF_ACTION", 0) or 0) <= 0:
            return None
        store = find_fence(self.nav.system)
        if store is None or not store.points:
            return None
        home = self.nav.home()
        areas, _ = fence_areas(store.points, None if home is None else (home[0], home[1]))
        for i, it in enumerate(self.items):
            if it.nav_cmd in _POSITION_ITEMS and math.isfinite(it.lat) and \
                    math.isfinite(it.lon) and not inside_fence(areas, it.lat, it.lon):
                return i
        return None

    def start_at(self, seq: int) -> None:
        """MISSION_START with a first item."""
        if 0 <= seq < len(self.items):
            self.index = seq
            self.finished = False
            self.publish_result()

    def publish_result(self) -> None:
        nav = self.nav
        r = nav.result
        r.mission_id = self.mission_id
        r.seq_reached = self.seq_reached
        r.seq_current = self.index if self.index < 0xFFFF else 0
        r.seq_total = len(self.items)
        r.valid = self.valid
        r.finished = self.finished
        r.failure = False
        nav.publish_result()

    # -- activation ---------------------------------------------------------------------------

    def on_activation(self) -> None:
        nav = self.nav
        if self.valid:   # a fence uploaded after the mission is checked when it starts
            outside = self._fence_violation()
            if outside is not None:
                nav.error(f"Geofence violation for waypoint {outside + 1}")
                self.valid = False
                self.publish_result()
        if not self.valid:
            nav.warn("Mission not valid, holding")
            nav.hold_here()
            return
        if self.finished or self.index >= len(self.items):
            self.index, self.seq_reached, self.finished = 0, -1, False
        self._start_item()
        self.publish_result()

    def _abs_alt(self, item: Any) -> float:
        if item.altitude_is_relative or item.frame == 3:
            h = self.nav.home_alt()
            return item.altitude + (h if h is not None else 0.0)
        return item.altitude

    def _acc(self, item: Any) -> float:
        r = item.acceptance_radius if item.acceptance_radius > 0 else self.nav.p["NAV_ACC_RAD"]
        if self.nav.fixed_wing():
            if item.nav_cmd in _LOITER_ITEMS:
                r = 1.2 * self._loiter_radius(item)
            return self.nav.acc_radius(r)
        return r

    def _loiter_radius(self, item: Any) -> float:
        r = abs(float(item.loiter_radius))
        return r if math.isfinite(r) and r > 0 else self.nav.loiter_radius()

    def _takeoff_sp(self, item: Any | None, pos: tuple[float, float, float],
                    alt: float) -> None:
        """A plane's takeoff: the item's position if it has one, else where the plane
        stands; yaw the runway heading (the item's yaw, else the current heading), which the
        position controller holds until it is clear of the ground."""
        nav = self.nav
        has_pos = item is not None and (item.lat or item.lon) and math.isfinite(item.lat)
        lat, lon = (item.lat, item.lon) if has_pos and item is not None else (pos[0], pos[1])
        yaw = item.yaw if item is not None and math.isfinite(item.yaw) else nav.heading()
        nav.set_current(SP_TAKEOFF, lat, lon, alt, yaw)

    def _yaw_to(self, item: Any, pos: tuple[float, float, float]) -> float:
        if math.isfinite(item.yaw):
            return item.yaw
        if distance_m(pos[0], pos[1], item.lat, item.lon) > self._acc(item):
            return bearing_rad(pos[0], pos[1], item.lat, item.lon)
        return self.nav.heading()

    def _start_item(self) -> None:
        nav = self.nav
        self.reached_at_us = None
        if self.index >= len(self.items):
            self._finish()
            return
        item = self.items[self.index]
        pos = nav.position()
        if pos is None:
            nav.hold_here()
            return
        cmd = item.nav_cmd
        if cmd == RTL:
            nav.send_command(CMD_RTL)
            self.phase = P_DONE
            return
        if cmd == LAND and nav.is_vtol() and nav.fixed_wing():
            # PX4's VTOL land: back to multicopter first, then this item as a vertical landing
            self._then_same_item = True
            self._to_fw = False
            nav.send_command(DO_VTOL_TRANSITION, VTOL_STATE_MC)
            cur = nav.triplet.current
            nav.set_current(SP_POSITION, pos[0], pos[1], cur.alt if cur.valid else pos[2],
                            nav.heading())
            self.phase = P_TRANSITION
            self.publish_result()
            return
        if cmd == DO_VTOL_TRANSITION and nav.is_vtol():
            # PX4 keeps a DO item's param1 in mission_item.params[0], which is time_inside
            self._to_fw = int(round(item.time_inside)) == VTOL_STATE_FW
            nav.send_command(DO_VTOL_TRANSITION, float(item.time_inside))
            # meanwhile a plain position setpoint (not a takeoff one, which the plane's
            # controller would start a climb-out from): to a plane, the next position item,
            # which it flies to once on the wing; to a multicopter, here. The rotors' transition
            # task follows neither, it holds the altitude.
            cur = nav.triplet.current
            alt = cur.alt if cur.valid else pos[2]
            nxt = next((it for it in self.items[self.index + 1:]
                        if it.nav_cmd in _POSITION_ITEMS), None) if self._to_fw else None
            lat, lon = (nxt.lat, nxt.lon) if nxt is not None else (pos[0], pos[1])
            nav.set_current(SP_POSITION, lat, lon, alt, nav.heading())
            self.phase = P_TRANSITION
            self.publish_result()
            return
        if cmd not in _POSITION_ITEMS:  # DO_* items act at once and are passed
            if cmd == DO_CHANGE_SPEED and item.speed_m_s > 0:
                nav.cruise_speed = float(item.speed_m_s)
            self.seq_reached = self.index
            self.index += 1
            self._start_item()
            return
        alt = self._abs_alt(item)
        fw = nav.fixed_wing()
        if nav.landed() and cmd != TAKEOFF:
            h = nav.home_alt()
            climb = max(alt, (h if h is not None else pos[2]) + nav.p["MIS_TAKEOFF_ALT"])
            self.phase = P_TAKEOFF_FIRST
            self._climb_alt = climb
            if fw:
                self._takeoff_sp(None, pos, climb)
            else:
                nav.set_current(SP_TAKEOFF, pos[0], pos[1], climb, nav.heading())
        elif cmd == TAKEOFF and fw:
            self.phase = P_ITEM
            self._takeoff_sp(item, pos, alt)
        elif cmd == TAKEOFF:
            self.phase = P_ITEM
            if nav.landed():
                nav.set_current(SP_TAKEOFF, pos[0], pos[1], alt, self._yaw_or_heading(item))
            else:
                nav.set_current(SP_POSITION, pos[0], pos[1], alt, self._yaw_or_heading(item))
        elif cmd == LAND:
            lat, lon = (item.lat, item.lon) if (item.lat or item.lon) else (pos[0], pos[1])
            self._land_at = (lat, lon, alt)
            if fw:   # the approach is the position controller's: land there at once
                self.phase = P_LAND
                nav.set_current(SP_LAND, lat, lon, alt, self._yaw_to(item, pos))
            elif distance_m(pos[0], pos[1], lat, lon) > self._acc(item):
                self.phase = P_MOVE_TO_LAND
                nav.set_current(SP_POSITION, lat, lon, pos[2],
                                bearing_rad(pos[0], pos[1], lat, lon), acc=self._acc(item))
            else:
                self.phase = P_LAND
                nav.set_current(SP_LAND, lat, lon, alt, self._yaw_or_heading(item))
        elif fw and cmd in _LOITER_ITEMS:
            self.phase = P_ITEM
            nav.set_current(SP_LOITER, item.lat, item.lon, alt, self._yaw_to(item, pos),
                            acc=self._acc(item), loiter_radius=self._loiter_radius(item))
        else:
            self.phase = P_ITEM
            sp_type = SP_LOITER if cmd == LOITER_UNLIM else SP_POSITION
            nav.set_current(sp_type, item.lat, item.lon, alt, self._yaw_to(item, pos),
                            acc=self._acc(item))
        self._set_next()
        self.publish_result()

    def _yaw_or_heading(self, item: Any) -> float:
        return item.yaw if math.isfinite(item.yaw) else self.nav.heading()

    def _set_next(self) -> None:
        nxt = self.items[self.index + 1] if self.index + 1 < len(self.items) else None
        if nxt is None or nxt.nav_cmd not in _POSITION_ITEMS or nxt.nav_cmd == TAKEOFF:
            self.nav.set_next(None)
            return
        sp_type = SP_LAND if nxt.nav_cmd == LAND else SP_POSITION
        self.nav.set_next((sp_type, nxt.lat, nxt.lon, self._abs_alt(nxt)))

    # -- progress -----------------------------------------------------------------------------

    def on_active(self) -> None:
        nav = self.nav
        if not nav.armed or self.phase == P_DONE:
            return
        pos = nav.position()
        if pos is None:
            return
        item = self.items[self.index]
        cur = nav.triplet.current
        fw = nav.fixed_wing()
        alt_ok = abs(pos[2] - cur.alt) <= nav.alt_acc()
        if fw and cur.type == SP_TAKEOFF:
            # a plane's climbout: reached once high enough, wherever it has flown meanwhile
            alt_ok = pos[2] >= cur.alt - nav.alt_acc()
        if self.phase == P_TRANSITION:
            if nav.vtol_state_is(self._to_fw):
                if self._then_same_item:      # a land item's back transition is over
                    self._then_same_item = False
                else:
                    self.seq_reached = self.index
                    self.index += 1
                self._start_item()
            return
        if self.phase == P_TAKEOFF_FIRST:
            if alt_ok and not nav.landed():
                self._start_item()  # the inserted climb is done: now the item itself
            return
        if self.phase == P_MOVE_TO_LAND:
            if distance_m(pos[0], pos[1], cur.lat, cur.lon) <= self._acc(item):
                self.phase = P_LAND
                lat, lon, alt = self._land_at
                nav.set_current(SP_LAND, lat, lon, alt, self._yaw_or_heading(item))
            return
        if self.phase == P_LAND:
            if nav.landed():
                self.seq_reached = self.index
                self.index += 1
                self._finish()
            return
        if self.phase == P_ITEM:
            if item.nav_cmd == TAKEOFF:
                reached = alt_ok and not nav.landed()
            else:
                reached = alt_ok and distance_m(pos[0], pos[1], cur.lat, cur.lon) <= \
                    self._acc(item)
            if not reached:
                return
            self.seq_reached = self.index
            self.phase = P_HOLD
            self.reached_at_us = nav.now_us
            self.publish_result()
        if self.phase == P_HOLD:
            if item.nav_cmd == LOITER_UNLIM or not item.autocontinue:
                return
            wait_us = item.time_inside * 1e6 if item.time_inside > 0 else 0
            if nav.now_us - (self.reached_at_us or 0) < wait_us:
                return
            self.index += 1
            self._start_item()

    def _finish(self) -> None:
        nav = self.nav
        self.finished = True
        self.phase = P_DONE
        if nav.landed():
            nav.set_idle()
        else:
            nav.hold_here(at_setpoint=True)
        nav.info("Mission finished" + (", landed" if nav.landed() else ", loitering"))
        self.publish_result()
