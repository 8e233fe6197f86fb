"""Geofence: PX4's maximum distance and height from home, the uploaded polygons and circles,
and the GF_ACTION reaction.

PX4's navigator checks the vehicle against the fence (``Geofence::isCloserThanMaxDistToHome``,
``isBelowMaxAltitude``, ``isInsidePolygonOrCircle``) and publishes ``geofence_result``; the
commander's failsafe turns a breach into the GF_ACTION reaction. Here the commander owns both
halves (one loop, no extra topic), with PX4's parameters and semantics:

* GF_MAX_HOR_DIST: horizontal distance from home (0: no limit); GF_MAX_VER_DIST: height above
  home (0: no limit). Both need a valid home.
* The fence uploaded by a ground station (dataman's fence list, mission_type FENCE): the vehicle
  must be inside every inclusion polygon and circle and outside every exclusion polygon and
  circle (PX4's ``checkPointAgainstPolygonCircle`` for each area, all of them passing);
  polygons with PX4's PNPOLY test on latitude/longitude, circles by the horizontal distance to
  the centre. As PX4's ``checkHomeRequirementsForGeofence``, an area that does not hold the
  home position is dropped with "Geofence invalid, doesn't contain Home position". The return
  point is stored but not used (PX4: "TODO").
* GF_SOURCE: 0 the estimator's global position (``vehicle_global_position``), 1 the GPS
  directly (``sensor_gps``, with a 3D fix).
* GF_ACTION: 0 none, 1 warning only, 2 Hold, 3 Return, 4 Terminate, 5 Land. The reaction is a
  latched failsafe cause like RC loss (only armed and in the air): Hold clears when the vehicle
  is back inside; Return/Land hold for COM_FAIL_ACT_T first, as every delayed reaction.
* The breach is reported once per breach ("Maximum distance from home reached (20.0 m)",
  PX4's text; "Geofence violation" for the uploaded areas), with the failsafe's "Failsafe:
  geofence breached, hold".

SYS_STATUS's MAV_SYS_STATUS_GEOFENCE bit (:meth:`Geofence.sensor_bits`): present when a fence
is configured (a distance or height limit, or an uploaded area), enabled when GF_ACTION is not
None as well, healthy unless breached, also when no fence is present. MAVProxy says "fence
breach" when the health bit is clear (it starts from "healthy"), so the bit is set whenever the
vehicle is not outside a fence. PX4 fills these bits from its health reports; which it sets for
the geofence is the emulator's reading of the MAVLink definition, not taken from PX4's code.

Not modelled: GF_PREDICT (PX4 predicts the breach from the braking distance; here the fence
trips at the boundary), GF_COUNT, the polygons' altitude limits.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Final

from firmware.modules.commander import failsafe as fs
from firmware.modules.dataman.points import (
    FENCE_CIRCLE_INCLUSION,
    FENCE_POLYGON_INCLUSION,
    polygons_and_circles,
)
from firmware.modules.navigator.geo import distance_m
from firmware.platform.params import ParamDef

if TYPE_CHECKING:
    from firmware.modules.commander.commander import CommanderModule

__all__ = ["GEOFENCE_PARAMS", "GF_ACTIONS", "Geofence", "fence_areas", "inside_fence",
           "inside_polygon"]

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


def inside_polygon(lat: float, lon: float, vertices: list[tuple[float, float]]) -> bool:
    """Whether (lat, lon) is inside the polygon: PNPOLY (W. R. Franklin), as PX4's
    ``Geofence::insidePolygon`` runs it on latitude/longitude (simple polygons only; the
    upload refuses self-intersecting ones)."""
    inside = False
    n = len(vertices)
    j = n - 1
    for i in range(n):
        lat_i, lon_i = vertices[i]
        lat_j, lon_j = vertices[j]
        if (lon_i >= lon) != (lon_j >= lon) and \
                lat <= (lat_j - lat_i) * (lon - lon_i) / (lon_j - lon_i) + lat_i:
            inside = not inside
        j = i
    return inside


#: an area: (command, polygon vertices or None, circle (lat, lon, radius) or None)
_Area = tuple[int, list[tuple[float, float]] | None, tuple[float, float, float] | None]


def fence_areas(points: Any, home: tuple[float, float] | None) -> tuple[list[_Area], int]:
    """The uploaded fence's areas in use and how many were dropped: with a home, an area that
    does not hold it is dropped (PX4's checkHomeRequirementsForGeofence)."""
    polygons, circles = polygons_and_circles(points)
    areas: list[_Area] = [(c, v, None) for c, v in polygons]
    areas += [(c, None, (lat, lon, r)) for c, lat, lon, r in circles]
    kept = [a for a in areas if home is None or _area_passes(a, home[0], home[1])]
    return kept, len(areas) - len(kept)


def inside_fence(areas: list[_Area], lat: float, lon: float) -> bool:
    """Whether a point passes every area (inside each inclusion, outside each exclusion)."""
    return all(_area_passes(a, lat, lon) for a in areas)


def _area_passes(area: _Area, lat: float, lon: float) -> bool:
    """PX4's checkPointAgainstPolygonCircle: inside an inclusion, outside an exclusion."""
    cmd, vertices, circle = area
    if vertices is not None:
        inside = inside_polygon(lat, lon, vertices)
        return inside if cmd == FENCE_POLYGON_INCLUSION else not inside
    assert circle is not None
    inside = distance_m(circle[0], circle[1], lat, lon) < circle[2]
    return inside if cmd == FENCE_CIRCLE_INCLUSION else not inside


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
        #: the uploaded fence's areas in use, and the (list update, home) they were built for
        self.areas: list[_Area] = []
        self.outside_area = False
        self._areas_key: tuple[int, int, tuple[float, float] | None] | None = None
        cmd.failsafe.causes.setdefault("geofence", fs._Cause("geofence"))

    def _load_areas(self) -> None:
        """Rebuild the areas when dataman's fence list or the home position changed."""
        from firmware.modules.dataman import find_fence

        cmd = self.cmd
        store = find_fence(cmd.system)
        home = cmd._home if cmd.home_valid else None
        key = (-1 if store is None else id(store), 0 if store is None else store.update_counter,
               None if home is None else (float(home.lat), float(home.lon)))
        if key == self._areas_key:
            return
        self._areas_key = key
        self.areas = []
        if store is None:
            return
        self.areas, dropped = fence_areas(
            store.points, None if home is None else (float(home.lat), float(home.lon)))
        for _ in range(dropped):
            cmd.error("Geofence invalid, doesn't contain Home position")

    @property
    def present(self) -> bool:
        """Whether any fence is configured (a limit parameter or an uploaded area)."""
        p = self.cmd.p
        return bool(self.areas) or float(p["GF_MAX_HOR_DIST"]) > 0.0 or \
            float(p["GF_MAX_VER_DIST"]) > 0.0

    def sensor_bits(self) -> tuple[bool, bool, bool]:
        """MAV_SYS_STATUS_GEOFENCE (present, enabled, healthy), see the module's text."""
        self._load_areas()  # the check runs only while armed; the report always
        present = self.present
        return present, present and int(self.cmd.p["GF_ACTION"]) != 0, not self.breached

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
        self._load_areas()
        max_xy, max_z = float(p["GF_MAX_HOR_DIST"]), float(p["GF_MAX_VER_DIST"])
        limits = (max_xy > 0.0 or max_z > 0.0) and cmd.home_valid
        if not limits:
            self.horizontal = self.vertical = False
        if not limits and not self.areas:
            self.outside_area = False
            return False
        pos = self._position(now)
        if pos is None:  # keep the last verdict until it is known
            return self.horizontal or self.vertical or self.outside_area
        if limits:
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
        outside = not all(_area_passes(a, pos[0], pos[1]) for a in self.areas)
        if outside and not self.outside_area:
            cmd.warn("Geofence violation")
        self.outside_area = outside
        return self.horizontal or self.vertical or outside

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
                f"{p['GF_MAX_VER_DIST']:.0f} m vertical, {len(self.areas)} uploaded areas, "
                f"action {int(p['GF_ACTION'])}; "
                f"{'BREACHED' if self.breached else 'inside'} ({self.dist_xy:.1f} m, "
                f"{self.dist_z:.1f} m), {self.breaches} breaches")

    def snapshot(self) -> dict[str, Any]:
        return {"breached": self.breached, "horizontal": self.horizontal,
                "vertical": self.vertical, "outside_area": self.outside_area,
                "areas": len(self.areas), "dist_xy": self.dist_xy, "dist_z": self.dist_z}
