"""Geofence: PX4's maximum distance and height from home, and the GF_ACTION reaction.

PX4's navigator checks the vehicle against the fence (``Geofence::isCloserThanMaxDistToHome``,
``isBelowMaxAltitude``) and publishes ``geofence_result``; the commander's failsafe turns a
breach into the GF_ACTION reaction. Here the commander owns both halves (one loop, no extra
topic), with PX4's parameters and semantics:

* GF_MAX_HOR_DIST: horizontal distance from home (0: no limit); GF_MAX_VER_DIST: height above
  home (0: no limit). Both need a valid home.
* GF_SOURCE: 0 the estimator's global position (``vehicle_global_position``), 1 the GPS
  directly (``sensor_gps``, with a 3D fix).
* GF_ACTION: 0 none, 1 warning only, 2 Hold, 3 Return, 4 Terminate, 5 Land. The reaction is a
  latched failsafe cause like RC loss (only armed and in the air): Hold clears when the vehicle
  is back inside; Return/Land hold for COM_FAIL_ACT_T first, as every delayed reaction.
* The breach is reported once per breach ("Maximum distance from home reached (20.0 m)",
  PX4's text), with the failsafe's "Failsafe: geofence breached, hold".

Not modelled: polygon and circle fences from the GCS (dataman), GF_PREDICT (PX4 predicts the
breach from the braking distance; here the fence trips at the boundary), GF_COUNT.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Final

from firmware.modules.commander import failsafe as fs
from firmware.modules.navigator.geo import distance_m
from firmware.platform.params import ParamDef

if TYPE_CHECKING:
    from firmware.modules.commander.commander import CommanderModule

__all__ = ["GEOFENCE_PARAMS", "GF_ACTIONS", "Geofence"]

_G: Final = "Geofence"
GEOFENCE_PARAMS = (
    ParamDef("GF_ACTION", "INT32", 2, min=0, max=5, group=_G,
             short="Geofence violation action",
             values={0: "None", 1: "Warning", 2: "Hold mode", 3: "Return mode",
                     4: "Terminate", 5: "Land mode"}),
    ParamDef("GF_MAX_HOR_DIST", "FLOAT", 0.0, min=0.0, max=10000.0, unit="m", group=_G,
             decimals=0, short="Max horizontal distance in meters",
             long="Maximum horizontal distance from home. 0 disables the check."),
    ParamDef("GF_MAX_VER_DIST", "FLOAT", 0.0, min=0.0, max=10000.0, unit="m", group=_G,
             decimals=0, short="Max vertical distance in meters",
             long="Maximum height above home. 0 disables the check."),
    ParamDef("GF_SOURCE", "INT32", 0, min=0, max=1, group=_G,
             short="Geofence source",
             values={0: "GPOS (estimator)", 1: "GPS"}),
)

#: GF_ACTION -> failsafe action (1 "warning" reports without a reaction)
GF_ACTIONS: Final = {0: fs.A_NONE, 1: fs.A_NONE, 2: fs.A_HOLD, 3: fs.A_RTL, 4: fs.A_TERMINATE,
              5: fs.A_LAND}


class Geofence:
    """The fence check of one commander; :meth:`update` runs in its failsafe step."""

    def __init__(self, cmd: CommanderModule) -> None:
        self.cmd = cmd
        self.breached = False
        self.horizontal = False
        self.vertical = False
        self.breaches = 0
        self.dist_xy = 0.0
        self.dist_z = 0.0
        cmd.failsafe.causes.setdefault("geofence", fs._Cause("geofence"))

    def _position(self, now: int) -> tuple[float, float, float] | None:
        d, p = self.cmd.data, self.cmd.p
        if int(p["GF_SOURCE"]) == 1:
            g = d.gps.node.last
            if g is None or g.fix_type < 3:
                return None
            return g.lat, g.lon, g.alt
        if not d.gpos_valid(now, p["COM_POS_FS_EPH"]):
            return None
        g = d.gpos.node.last
        return g.lat, g.lon, g.alt

    def check(self, now: int) -> bool:
        """Whether the vehicle is outside the fence now (False without home or position)."""
        cmd, p = self.cmd, self.cmd.p
        max_xy, max_z = float(p["GF_MAX_HOR_DIST"]), float(p["GF_MAX_VER_DIST"])
        if (max_xy <= 0.0 and max_z <= 0.0) or not cmd.home_valid:
            self.horizontal = self.vertical = False
            return False
        pos = self._position(now)
        if pos is None:
            return self.horizontal or self.vertical   # keep the last verdict until it is known
        home = cmd._home
        self.dist_xy = distance_m(home.lat, home.lon, pos[0], pos[1])
        self.dist_z = pos[2] - home.alt
        horizontal = max_xy > 0.0 and self.dist_xy > max_xy
        vertical = max_z > 0.0 and self.dist_z > max_z
        if horizontal and not self.horizontal:
            cmd.warn(f"Maximum distance from home reached ({max_xy:.1f} m)")
        if vertical and not self.vertical:
            cmd.warn(f"Maximum altitude above home reached ({max_z:.1f} m)")
        self.horizontal, self.vertical = horizontal, vertical
        return horizontal or vertical

    def update(self, now: int, in_air: bool) -> None:
        """Check the fence and feed the failsafe cause ``geofence`` (armed only)."""
        cmd = self.cmd
        breached = self.check(now)
        if breached and not self.breached:
            self.breaches += 1
        self.breached = breached
        action = GF_ACTIONS.get(int(cmd.p["GF_ACTION"]), fs.A_NONE)
        f = cmd.failsafe
        if f.update("geofence", breached, action, now, in_air):
            cmd.error(f"Failsafe: geofence breached, "
                      f"{fs.ACTION_NAMES_LOWER[f.causes['geofence'].action]}")

    def status(self) -> str:
        p = self.cmd.p
        return (f"geofence: max {p['GF_MAX_HOR_DIST']:.0f} m horizontal, "
                f"{p['GF_MAX_VER_DIST']:.0f} m vertical, action {int(p['GF_ACTION'])}; "
                f"{'BREACHED' if self.breached else 'inside'} ({self.dist_xy:.1f} m, "
                f"{self.dist_z:.1f} m), {self.breaches} breaches")

    def snapshot(self) -> dict[str, Any]:
        return {"breached": self.breached, "horizontal": self.horizontal,
                "vertical": self.vertical, "dist_xy": self.dist_xy, "dist_z": self.dist_z}
