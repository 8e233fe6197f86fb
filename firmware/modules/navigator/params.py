"""Navigator parameters (PX4's names and defaults: mission, takeoff, return, fixed wing)."""

from __future__ import annotations

from typing import Final

from firmware.platform.params import ParamDef

__all__ = ["PARAMS"]

_M: Final = "Mission"
_R: Final = "Return Mode"

PARAMS: Final[tuple[ParamDef, ...]] = (
    ParamDef("MIS_TAKEOFF_ALT", "FLOAT", 2.5, min=0.0, max=80.0, unit="m", group=_M,
             decimals=1, short="Default take-off altitude",
             long="Above home, for Takeoff mode and for the climb a mission inserts when it "
                  "starts on the ground."),
    ParamDef("NAV_ACC_RAD", "FLOAT", 10.0, min=0.05, max=200.0, unit="m", group=_M,
             decimals=1, short="Acceptance radius",
             long="Horizontal distance at which a waypoint counts as reached, unless the item "
                  "sets its own."),
    ParamDef("NAV_MC_ALT_RAD", "FLOAT", 0.8, min=0.05, max=200.0, unit="m", group=_M,
             decimals=1, short="MC altitude acceptance radius"),
    ParamDef("NAV_FW_ALT_RAD", "FLOAT", 10.0, min=0.05, max=200.0, unit="m", group=_M,
             decimals=1, short="FW altitude acceptance radius",
             long="Fixed wing: vertical distance at which a waypoint's altitude counts as "
                  "reached (a plane cannot hold altitude as tightly as a multicopter)."),
    ParamDef("NAV_FW_ALTL_RAD", "FLOAT", 5.0, min=0.05, max=200.0, unit="m", group=_M,
             decimals=1, short="FW altitude acceptance radius before a landing",
             long="Fixed wing: the tighter altitude acceptance of the waypoint before a land "
                  "item, so the approach starts from a clean altitude."),
    ParamDef("NAV_LOITER_RAD", "FLOAT", 50.0, min=25.0, max=1000.0, unit="m", group=_M,
             decimals=1, short="Loiter radius (FW only)",
             long="Default radius of the circles a plane flies for Hold, loiter items and "
                  "takeoff/return holds."),
    ParamDef("MIS_DIST_1WP", "FLOAT", 900.0, min=0.0, max=10000.0, unit="m", group=_M,
             decimals=1, short="Maximal horizontal distance from home to first waypoint",
             long="A mission whose first waypoint is farther is rejected; 0 disables."),
    ParamDef("RTL_RETURN_ALT", "FLOAT", 60.0, min=0.0, max=150.0, unit="m", group=_R,
             decimals=1, short="Return mode return altitude",
             long="Above home. The vehicle climbs to it first if it is lower."),
    ParamDef("RTL_DESCEND_ALT", "FLOAT", 30.0, min=2.0, max=100.0, unit="m", group=_R,
             decimals=1, short="Return mode loiter altitude",
             long="Above home: after returning, descend to this altitude before landing."),
    ParamDef("RTL_LAND_DELAY", "FLOAT", 0.0, min=-1.0, max=300.0, unit="s", group=_R,
             decimals=1, short="Return mode delay",
             long="Time to hover at RTL_DESCEND_ALT before landing; -1 hovers forever."),
    ParamDef("RTL_LOITER_RAD", "FLOAT", 50.0, min=25.0, max=1000.0, unit="m", group=_R,
             decimals=1, short="Loiter radius for RTL descend (FW only)",
             long="A plane descends to RTL_DESCEND_ALT and waits on a circle of this radius "
                  "around home."),
    ParamDef("RTL_MIN_DIST", "FLOAT", 10.0, min=0.5, max=100.0, unit="m", group=_R,
             decimals=1, short="Horizontal radius from home to trigger the minimum return alt",
             long="Closer than this, the vehicle returns at its current altitude or "
                  "RTL_DESCEND_ALT, whichever is higher."),
)
