"""The default mission of each vehicle class, as a ground station would plan it.

Positions are metres north and east of home; :meth:`DefaultMission.items` turns them into
MISSION_ITEM_INT messages for home's latitude and longitude. ``hil run`` flies the mission of
the airframe's class (``hil.airframes``) and checks what a PX4 user looks at against
``waypoints`` (the plan's turn points, for track and acceptance checks) and ``touchdown_ne``.

* multicopter: takeoff to 10 m, a square of four waypoints 20 m apart, return and land;
* fixedwing: a runway takeoff northwards climbing to 50 m, a square of four waypoints 300 m
  apart, a loiter at 30 m south of home where the landing pattern starts, then a landing
  northwards at home (30 m over 400 m, within PX4's 5 degree glide slope);
* vtol: a vertical takeoff to 30 m as a multicopter, the front transition (DO_VTOL_TRANSITION
  to fixed wing, northwards: the heading it took off with), the plane's square at 30 m, the
  back transition after its last waypoint, and a vertical landing at home (NAV_LAND, flown as
  a multicopter: to home at the altitude it has, then down).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pymavlink.dialects.v20 import common as mav

__all__ = ["DefaultMission", "MISSIONS", "M_PER_DEG_LAT", "mission_for"]

M_PER_DEG_LAT = 111_132.954

NAV_WAYPOINT = mav.MAV_CMD_NAV_WAYPOINT
NAV_LOITER_TIME = mav.MAV_CMD_NAV_LOITER_TIME
NAV_RTL = mav.MAV_CMD_NAV_RETURN_TO_LAUNCH
NAV_LAND = mav.MAV_CMD_NAV_LAND
NAV_TAKEOFF = mav.MAV_CMD_NAV_TAKEOFF
DO_VTOL_TRANSITION = mav.MAV_CMD_DO_VTOL_TRANSITION
#: DO_VTOL_TRANSITION param1: MAV_VTOL_STATE_MC / _FW
VTOL_MC = float(mav.MAV_VTOL_STATE_MC)
VTOL_FW = float(mav.MAV_VTOL_STATE_FW)


@dataclass(frozen=True)
class Item:
    """One mission item: command, metres north/east of home, altitude above home, params."""

    cmd: int
    north_m: float
    east_m: float
    alt_m: float
    param1: float = 0.0  # NAV_TAKEOFF: minimum pitch; NAV_LOITER_TIME: seconds;
    #                      DO_VTOL_TRANSITION: the state to go to (VTOL_MC, VTOL_FW)
    param3: float = 0.0  # NAV_LOITER_TIME: radius (m, 0: NAV_LOITER_RAD)


@dataclass(frozen=True)
class DefaultMission:
    name: str
    altitude_m: float                           # cruise altitude above home
    plan: tuple[Item, ...]
    #: the checked turn points, metres north/east; their items are sequence
    #: first_waypoint_seq .. first_waypoint_seq + len - 1
    waypoints: tuple[tuple[float, float], ...]
    touchdown_ne: tuple[float, float] = (0.0, 0.0)
    description: str = ""
    first_waypoint_seq: int = 1

    def items(self, home_lat_deg: float, home_lon_deg: float, target_system: int = 1,
              target_component: int = 1) -> list[mav.MAVLink_mission_item_int_message]:
        """The plan as MISSION_ITEM_INT messages (relative altitude frame)."""
        m_per_deg_lon = M_PER_DEG_LAT * math.cos(math.radians(home_lat_deg))
        out = []
        for seq, it in enumerate(self.plan):
            lat = home_lat_deg + it.north_m / M_PER_DEG_LAT
            lon = home_lon_deg + it.east_m / m_per_deg_lon
            out.append(mav.MAVLink_mission_item_int_message(
                target_system, target_component, seq,
                mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, it.cmd, int(seq == 0), 1,
                it.param1, 0.0, it.param3, math.nan,
                round(lat * 1e7), round(lon * 1e7), float(it.alt_m), 0))
        return out


#: the quadrotor's square (metres north, east of home)
SQUARE_NE = ((20.0, -10.0), (20.0, 10.0), (40.0, 10.0), (40.0, -10.0))
#: the plane's square, 300 m sides, north-east of the runway (flown clockwise)
FW_SQUARE_NE = ((400.0, 0.0), (400.0, 300.0), (100.0, 300.0), (100.0, 0.0))
FW_ALT_M = 50.0
#: the loiter that starts the landing pattern, on the runway line south of home
FW_LOITER_NE = (-400.0, 0.0)
FW_PATTERN_ALT_M = 30.0
#: the VTOL's altitude: takeoff, transitions and the square
VTOL_ALT_M = 30.0

MISSIONS: dict[str, DefaultMission] = {
    "multicopter": DefaultMission(
        "square", 10.0,
        (Item(NAV_TAKEOFF, 0.0, 0.0, 10.0),
         *(Item(NAV_WAYPOINT, n, e, 10.0) for n, e in SQUARE_NE),
         Item(NAV_RTL, 0.0, 0.0, 10.0)),
        SQUARE_NE,
        description="takeoff, 4 waypoints, return"),
    "fixedwing": DefaultMission(
        "fixed-wing circuit", FW_ALT_M,
        (Item(NAV_TAKEOFF, 300.0, 0.0, FW_ALT_M, param1=10.0),
         *(Item(NAV_WAYPOINT, n, e, FW_ALT_M) for n, e in FW_SQUARE_NE),
         Item(NAV_LOITER_TIME, *FW_LOITER_NE, FW_PATTERN_ALT_M, param1=10.0),
         Item(NAV_LAND, 0.0, 0.0, 0.0)),
        FW_SQUARE_NE,
        description="takeoff to 50 m, 4 waypoints 300 m apart, loiter, return and land"),
    "vtol": DefaultMission(
        "VTOL circuit", VTOL_ALT_M,
        (Item(NAV_TAKEOFF, 0.0, 0.0, VTOL_ALT_M),
         Item(DO_VTOL_TRANSITION, 0.0, 0.0, 0.0, param1=VTOL_FW),
         *(Item(NAV_WAYPOINT, n, e, VTOL_ALT_M) for n, e in FW_SQUARE_NE),
         Item(DO_VTOL_TRANSITION, 0.0, 0.0, 0.0, param1=VTOL_MC),
         Item(NAV_LAND, 0.0, 0.0, 0.0)),
        FW_SQUARE_NE,
        description="vertical takeoff to 30 m, transition, 4 waypoints 300 m apart, back "
                    "transition, vertical landing at home",
        first_waypoint_seq=2),
}


def mission_for(vehicle_class: str) -> DefaultMission:
    """The default mission of a vehicle class (``hil.airframes.CLASSES`` values)."""
    try:
        return MISSIONS[vehicle_class]
    except KeyError:
        raise ValueError(f"no default mission for vehicle class {vehicle_class!r}; "
                         f"known: {sorted(MISSIONS)}") from None
