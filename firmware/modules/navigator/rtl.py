"""Return mode: climb, fly home, descend, (wait), land — PX4's classic RTL phases.

* return altitude: RTL_RETURN_ALT above home, or the current altitude if higher; within
  RTL_MIN_DIST of home it is the current altitude or RTL_DESCEND_ALT, whichever is higher (no
  pointless climb right next to home);
* CLIMB over the activation point until within NAV_MC_ALT_RAD of it (skipped if high enough);
* RETURN to home at that altitude, heading towards home, until within NAV_ACC_RAD;
* DESCEND over home to RTL_DESCEND_ALT (skipped if already at or below it);
* LOITER for RTL_LAND_DELAY seconds (0 skips, -1 hovers forever);
* LAND at home; LANDED when the land detector says so (the commander then auto-disarms).

Without a home position it lands where it is; on the ground it does nothing.

A fixed wing flies the same phases as PX4's RTL for planes: it climbs circling (NAV_LOITER_RAD)
over where Return started, flies home, descends circling home on RTL_LOITER_RAD, waits there
on the circle, and lands at home (its LAND setpoint's previous point is the loiter, from which
the position controller makes its approach). Altitudes count as reached within NAV_FW_ALT_RAD,
home within the L1 distance when that is larger than NAV_ACC_RAD. A negative RTL_LAND_DELAY
keeps it circling home (PX4's default for planes without a landing site).

A VTOL on the wing first asks vtol_att_control for the back transition (DO_VTOL_TRANSITION to
multicopter) and then returns and lands as a multicopter: its vertical landing needs no
approach, and a quad-chute's Return must not put it back on the wing it gave up.

The destination is PX4's RTL_TYPE 0 (the default, "return to the closest safe point"): home
or, when a ground station uploaded rally points (dataman's rally list), whichever of home and
the rally points is closest to where Return starts. The phases are the same over a rally
point, its altitude (above home, or AMSL, as uploaded) being the ground the vehicle lands on.
"""

from __future__ import annotations

from typing import Any, Final

from firmware.modules.navigator.geo import bearing_rad, distance_m
from firmware.modules.navigator.modes import SP_LAND, SP_LOITER, SP_POSITION, NavMode

__all__ = ["RTL_STATES", "RtlMode"]

CLIMB, RETURN, DESCEND, LOITER, LAND, LANDED = range(6)
DO_VTOL_TRANSITION: Final = 3000
VTOL_STATE_MC: Final = 3.0
RTL_STATES: Final[tuple[str, ...]] = ("climb", "return", "descend", "loiter", "land", "landed")


class RtlMode(NavMode):
    name = "rtl"

    def __init__(self, nav: Any) -> None:
        super().__init__(nav)
        self.state = LANDED
        self.rtl_alt = 0.0
        self.loiter_since_us = 0
        #: the rally point Return flies to (-1: home)
        self.rally_index = -1

    def on_activation(self) -> None:
        nav = self.nav
        pos = nav.position()
        home = nav.home()
        if nav.landed() or pos is None:
            self._enter(LANDED)
            return
        if nav.is_vtol() and nav.fixed_wing():
            nav.send_command(DO_VTOL_TRANSITION, VTOL_STATE_MC)
            nav.info("Return: transition to multicopter first")
        if home is None:
            nav.warn("Return: no home position, landing here")
            self.home = (pos[0], pos[1], pos[2] - 0.0, nav.heading())
            self._enter(LAND, here=pos)
            return
        home = self._destination(pos, home)
        self.home = home
        p = nav.p
        dist = distance_m(pos[0], pos[1], home[0], home[1])
        if dist < p["RTL_MIN_DIST"]:
            self.rtl_alt = max(pos[2], home[2] + p["RTL_DESCEND_ALT"])
        else:
            self.rtl_alt = max(pos[2], home[2] + p["RTL_RETURN_ALT"])
        self._start = pos
        nav.info(f"Return: at {self.rtl_alt - home[2]:.0f} m above home, "
                 f"{dist:.0f} m away")
        self._enter(CLIMB if pos[2] < self.rtl_alt - nav.alt_acc() else RETURN)

    def _destination(self, pos: tuple[float, float, float],
                     home: tuple[float, float, float, float]
                     ) -> tuple[float, float, float, float]:
        """Home, or the closest rally point if one is closer than home (RTL_TYPE 0)."""
        from firmware.modules.dataman import find_rally

        store = find_rally(self.nav.system)
        best, best_dist = home, distance_m(pos[0], pos[1], home[0], home[1])
        chosen = -1
        for i, rp in enumerate(store.points if store is not None else ()):
            d = distance_m(pos[0], pos[1], rp.lat, rp.lon)
            if d < best_dist:
                alt = home[2] + rp.alt_m if rp.relative else rp.alt_m
                best, best_dist, chosen = (rp.lat, rp.lon, alt, home[3]), d, i
        if chosen >= 0:
            self.nav.info(f"Return: to rally point {chosen}, {best_dist:.0f} m away")
        self.rally_index = chosen
        return best

    def _enter(self, state: int, here: tuple[float, float, float] | None = None) -> None:
        nav = self.nav
        self.state = state
        if state == LANDED:
            nav.set_idle()
            return
        lat, lon, alt, yaw = self.home
        pos = nav.position() or (lat, lon, alt)
        fw = nav.fixed_wing()
        if state == CLIMB:
            nav.set_current(SP_LOITER if fw else SP_POSITION, self._start[0], self._start[1],
                            self.rtl_alt, nav.heading())
        elif state == RETURN:
            yaw_home = bearing_rad(pos[0], pos[1], lat, lon) if distance_m(
                pos[0], pos[1], lat, lon) > nav.p["NAV_ACC_RAD"] else nav.heading()
            nav.set_current(SP_POSITION, lat, lon, self.rtl_alt, yaw_home)
            nav.set_next((SP_LOITER, lat, lon, self._loiter_alt()) if fw else
                         (SP_LAND, lat, lon, alt))
        elif state == DESCEND:
            descend_alt = alt + nav.p["RTL_DESCEND_ALT"]
            if self.rtl_alt <= descend_alt + nav.alt_acc():
                self._enter(LOITER)
                return
            if fw:
                nav.set_current(SP_LOITER, lat, lon, descend_alt, yaw,
                                loiter_radius=nav.p["RTL_LOITER_RAD"])
            else:
                nav.set_current(SP_POSITION, lat, lon, descend_alt, yaw)
        elif state == LOITER:
            delay = nav.p["RTL_LAND_DELAY"]
            if delay == 0:
                self._enter(LAND)
                return
            self.loiter_since_us = nav.now_us
            if fw:
                nav.set_current(SP_LOITER, lat, lon, self._loiter_alt(), yaw,
                                loiter_radius=nav.p["RTL_LOITER_RAD"])
            else:
                nav.set_current(SP_LOITER, lat, lon, pos[2], yaw)
            if delay < 0:
                nav.info("Return: hovering over home (RTL_LAND_DELAY < 0)")
        elif state == LAND:
            if here is not None:
                nav.set_current(SP_LAND, here[0], here[1], here[2], nav.heading())
            else:
                nav.set_current(SP_LAND, lat, lon, alt, yaw)
                nav.info("Return: landing at home" if self.rally_index < 0 else
                         f"Return: landing at rally point {self.rally_index}")

    def _loiter_alt(self) -> float:
        """Where a plane circles home: RTL_DESCEND_ALT above it, or the return altitude if
        that is already no higher (no descent then)."""
        descend_alt = self.home[2] + self.nav.p["RTL_DESCEND_ALT"]
        return self.rtl_alt if self.rtl_alt <= descend_alt + self.nav.alt_acc() else \
            descend_alt

    def on_active(self) -> None:
        nav = self.nav
        if not nav.armed:
            return
        state = self.state
        if state == LANDED:
            return
        if state == LAND:
            if nav.landed():
                self._enter(LANDED)
            return
        pos = nav.position()
        if pos is None:
            return
        cur = nav.triplet.current
        p = nav.p
        alt_ok = abs(pos[2] - cur.alt) <= nav.alt_acc()
        if state == CLIMB and alt_ok:
            self._enter(RETURN)
        elif state == RETURN and alt_ok and \
                distance_m(pos[0], pos[1], cur.lat, cur.lon) <= nav.acc_radius():
            self._enter(DESCEND)
        elif state == DESCEND and alt_ok:
            self._enter(LOITER)
        elif state == LOITER:
            delay = p["RTL_LAND_DELAY"]
            if delay >= 0 and nav.now_us - self.loiter_since_us >= delay * 1e6:
                self._enter(LAND)

    @property
    def state_name(self) -> str:
        return RTL_STATES[self.state]
