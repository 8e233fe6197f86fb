"""Navigator modes: each turns the vehicle's state into the current position setpoint.

A mode is activated when the commander's nav_state selects it (or the vehicle arms while it is
selected), runs ``on_active`` every navigator cycle, and writes the triplet through the
navigator's helpers. Takeoff, Hold (loiter) and Land live here; Mission and Return have their
own files.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from firmware.modules.navigator.navigator import NavigatorModule

__all__ = ["LandMode", "LoiterMode", "NavMode", "TakeoffMode"]

SP_POSITION, SP_VELOCITY, SP_LOITER, SP_TAKEOFF, SP_LAND, SP_IDLE = 0, 1, 2, 3, 4, 5


class NavMode:
    """Base: hooks the navigator calls."""

    name = "mode"

    def __init__(self, nav: NavigatorModule) -> None:
        self.nav = nav

    def on_activation(self) -> None:
        """Entered (or re-armed in) this mode: compute the first setpoint."""

    def on_active(self) -> None:
        """Every cycle while selected: check progress, move on."""

    def on_inactivation(self) -> None:
        """Left this mode."""


class TakeoffMode(NavMode):
    """Climb vertically to MIS_TAKEOFF_ALT above home (or the NAV_TAKEOFF altitude), then
    hold there and report ``mission_result.finished`` so the commander switches to Hold.

    A plane takes off in the direction it faces (PX4's fixed-wing Takeoff mode): the setpoint
    is where it stands with the current heading as the runway heading, the climbout is done
    once it is within NAV_FW_ALT_RAD below the target, and it then circles the takeoff point
    (NAV_LOITER_RAD)."""

    name = "takeoff"

    def on_activation(self) -> None:
        nav = self.nav
        pos = nav.position()
        self.done = False
        if pos is None:
            nav.set_invalid()
            return
        lat, lon, alt = pos
        target = nav.takeoff_alt_cmd
        if target is None or not math.isfinite(target):
            home_alt = nav.home_alt()
            base = home_alt if home_alt is not None else alt
            target = base + nav.p["MIS_TAKEOFF_ALT"]
        if not nav.landed() and alt > target:
            target = alt  # already higher: hold where we are
        self.target_alt = target
        nav.set_current(SP_TAKEOFF, lat, lon, target, nav.heading(), previous=False)
        nav.result_finished(False)

    def on_active(self) -> None:
        nav = self.nav
        if self.done or not nav.armed:
            return
        pos = nav.position()
        if pos is None or nav.landed():
            return
        err = pos[2] - self.target_alt
        reached = err >= -nav.alt_acc() if nav.fixed_wing() else abs(err) <= nav.alt_acc()
        if reached:
            self.done = True
            cur = nav.triplet.current
            nav.set_current(SP_LOITER, cur.lat, cur.lon, cur.alt, cur.yaw, previous=False)
            nav.info("Takeoff to target altitude complete")
            nav.result_finished(True)


class LoiterMode(NavMode):
    """Hold: at the current setpoint if the vehicle is already there, else where it is;
    DO_REPOSITION moves the hold point."""

    name = "loiter"

    def on_activation(self) -> None:
        nav = self.nav
        if nav.reposition is not None:
            self._reposition(nav.reposition)
            return
        if nav.landed():
            nav.set_idle()
            return
        cur = nav.triplet.current
        pos = nav.position()
        if pos is None:
            nav.set_invalid()
            return
        if cur.valid and cur.type in (SP_POSITION, SP_LOITER) and nav.is_at(cur.lat, cur.lon,
                                                                         cur.alt):
            nav.set_current(SP_LOITER, cur.lat, cur.lon, cur.alt, cur.yaw)
        else:
            nav.set_current(SP_LOITER, pos[0], pos[1], pos[2], nav.heading())

    def on_active(self) -> None:
        if self.nav.reposition is not None:
            self._reposition(self.nav.reposition)

    def _reposition(self, target: tuple[float, float, float, float]) -> None:
        """Hold at DO_REPOSITION's ``(lat, lon, alt, yaw)``; NaN keeps that part as it is."""
        nav = self.nav
        lat, lon, alt, yaw = target
        nav.reposition = None
        pos = nav.position()
        cur = nav.triplet.current
        if pos is None:
            return
        lat = lat if math.isfinite(lat) else pos[0]
        lon = lon if math.isfinite(lon) else pos[1]
        alt = alt if math.isfinite(alt) else (cur.alt if cur.valid else pos[2])
        yaw = yaw if math.isfinite(yaw) else nav.heading()
        nav.set_current(SP_LOITER, lat, lon, alt, yaw)


class LandMode(NavMode):
    """Land where the vehicle is; idle once the land detector says landed."""

    name = "land"

    def on_activation(self) -> None:
        nav = self.nav
        if nav.landed():
            nav.set_idle()
            return
        pos = nav.position()
        if pos is None:
            nav.set_invalid()
            return
        nav.set_current(SP_LAND, pos[0], pos[1], pos[2], nav.heading())

    def on_active(self) -> None:
        nav = self.nav
        if nav.landed() and nav.triplet.current.type != SP_IDLE:
            nav.set_idle()


def copy_setpoint(dst: Any, src: Any) -> None:
    """Copy one position_setpoint into another in place (the triplet's previous/next)."""
    for k in ("timestamp", "valid", "type", "lat", "lon", "alt", "yaw", "yaw_valid",
              "acceptance_radius", "loiter_radius", "vx", "vy", "vz"):
        setattr(dst, k, getattr(src, k))
