"""Flight tasks: what the vehicle should do, as a trajectory setpoint for the position controller.

* :class:`TaskAuto` follows ``position_setpoint_triplet.current`` (navigator): TAKEOFF climbs
  straight up at ``MPC_TKO_SPEED``, POSITION/LOITER fly a straight line to the point (cruise
  ``MPC_XY_CRUISE``, accelerations ``MPC_ACC_HOR``/``MPC_ACC_UP_MAX``/``MPC_ACC_DOWN_MAX``,
  jerk ``MPC_JERK_AUTO``) and hold it, LAND holds the horizontal position and descends at
  ``MPC_LAND_SPEED`` below ``MPC_LAND_ALT2`` (faster above, up to ``MPC_Z_VEL_MAX_DN`` at
  ``MPC_LAND_ALT1``), IDLE keeps the motors idle on the ground.
* :class:`TaskManualPosition`: sticks are velocities (``MPC_VEL_MANUAL``, ``MPC_Z_VEL_MAX_*``),
  centred sticks brake and hold the position.
* :class:`TaskManualAltitude`: sticks tilt the vehicle (``MPC_MAN_TILT_MAX``) as an acceleration
  setpoint, the throttle stick is a climb rate, centred it holds the altitude.

Setpoints use NaN for "not controlled" as in PX4's trajectory_setpoint.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Final
from common.units import G0_M_S2

if TYPE_CHECKING:
    from firmware.modules.mc_pos_control.mc_pos_control import McPosControlModule

__all__ = [
    "SP_IDLE",
    "SP_LAND",
    "SP_LOITER",
    "SP_POSITION",
    "SP_TAKEOFF",
    "SP_VELOCITY",
    "LineTrajectory",
    "TaskAuto",
    "TaskManualAltitude",
    "TaskManualPosition",
]

SP_POSITION, SP_VELOCITY, SP_LOITER, SP_TAKEOFF, SP_LAND, SP_IDLE = range(6)
NAN: Final = math.nan


class LineTrajectory:
    """A straight-line reference from ``start`` to ``end`` with speed, acceleration and jerk
    limits: the along-track acceleration slews at the jerk limit toward what reaches the cruise
    speed, and braking uses the deceleration that stops exactly at the end (kept below 70 % of
    the limit, so the jerk-limited slew can follow it)."""

    def __init__(self) -> None:
        self.start = (0.0, 0.0, 0.0)
        self.dir = (0.0, 0.0, 0.0)
        self.length = 0.0
        self.s = self.v = self.a = 0.0
        self.v_max, self.a_max, self.j_max = 1.0, 1.0, 1.0
        self.done = True

    def plan(self, start: tuple[float, float, float], end: tuple[float, float, float],
             v0: tuple[float, float, float], cruise_xy: float, v_up: float, v_dn: float,
             acc_xy: float, acc_up: float, acc_dn: float, jerk: float) -> None:
        dx, dy, dz = end[0] - start[0], end[1] - start[1], end[2] - start[2]
        n = math.sqrt(dx * dx + dy * dy + dz * dz)
        self.start = start
        self.length = n
        self.s = 0.0
        self.a = 0.0
        if n < 1e-3:
            self.dir = (0.0, 0.0, 0.0)
            self.v = 0.0
            self.done = True
            return
        ux, uy, uz = dx / n, dy / n, dz / n
        self.dir = (ux, uy, uz)
        h = math.hypot(ux, uy)
        vz_lim, az_lim = (v_up, acc_up) if uz < 0.0 else (v_dn, acc_dn)
        v_max = a_max = math.inf
        if h > 1e-6:
            v_max, a_max = cruise_xy / h, acc_xy / h
        if abs(uz) > 1e-6:
            v_max = min(v_max, vz_lim / abs(uz))
            a_max = min(a_max, az_lim / abs(uz))
        self.v_max, self.a_max, self.j_max = v_max, a_max, jerk
        v = v0[0] * ux + v0[1] * uy + v0[2] * uz
        self.v = min(max(v, 0.0), v_max)
        self.done = False

    def update(self, dt: float) -> None:
        if self.done:
            return
        rem = self.length - self.s
        v, a = self.v, self.a
        a_brake = 0.7 * self.a_max
        if rem <= 1e-4:
            a_des = -a_brake
        elif v * v > 2.0 * a_brake * rem:      # braking: stop exactly at the end
            a_des = -v * v / (2.0 * rem)
        else:
            a_des = (self.v_max - v) * self.j_max / self.a_max
            a_des = min(a_des, self.a_max)
        a_des = max(a_des, -self.a_max)
        # jerk limit on the way up; braking demands are followed at once (safety first)
        da = self.j_max * dt
        if a_des > a + da:
            a += da
        elif a_des < a - da and a_des > -a_brake:
            a -= da
        else:
            a = a_des
        v += a * dt
        v = min(v, self.v_max)
        self.s += v * dt
        if self.s >= self.length or v <= 0.0 and rem < 0.05:
            self.s, v, a, self.done = self.length, 0.0, 0.0, True
        self.v, self.a = max(v, 0.0), a

    def position(self) -> tuple[float, float, float]:
        s = self.s
        return (self.start[0] + self.dir[0] * s, self.start[1] + self.dir[1] * s,
                self.start[2] + self.dir[2] * s)

    def velocity(self) -> tuple[float, float, float]:
        return (self.dir[0] * self.v, self.dir[1] * self.v, self.dir[2] * self.v)

    def acceleration(self) -> tuple[float, float, float]:
        return (self.dir[0] * self.a, self.dir[1] * self.a, self.dir[2] * self.a)


class _Task:
    """Common output fields: the trajectory setpoint of this cycle."""

    name = "none"

    def __init__(self, ctl: McPosControlModule) -> None:
        self.ctl = ctl
        self.pos = [NAN, NAN, NAN]
        self.vel = [NAN, NAN, NAN]
        self.acc = [NAN, NAN, NAN]
        self.yaw = NAN
        self.yawspeed = 0.0
        self.idle = False   # the vehicle should sit on the ground with motors idle

    def activate(self) -> None:
        """Start from the vehicle's state (called on entering the task and while on ground)."""
        c = self.ctl
        self.yaw = c.yaw

    def update(self, dt: float) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def wants_takeoff(self, z: float) -> bool:
        """On the ground: does the setpoint ask to climb (more than 0.3 m or 0.3 m/s)?"""
        if self.idle:
            return False
        return (math.isfinite(self.pos[2]) and self.pos[2] < z - 0.3) or \
            (math.isfinite(self.vel[2]) and self.vel[2] < -0.3)

    def _hold(self, x: float, y: float, z: float) -> None:
        self.pos[0], self.pos[1], self.pos[2] = x, y, z
        self.vel[0] = self.vel[1] = self.vel[2] = 0.0
        self.acc[0] = self.acc[1] = self.acc[2] = NAN


class TaskAuto(_Task):
    """position_setpoint_triplet.current -> straight lines, takeoff, land, idle."""

    name = "auto"

    def __init__(self, ctl: McPosControlModule) -> None:
        super().__init__(ctl)
        self.traj = LineTrajectory()
        self.key: tuple[Any, ...] | None = None
        self.target = (0.0, 0.0, 0.0)
        self.land_xy = (0.0, 0.0)
        self.land_vz = 0.0
        self.kind = -1

    def activate(self) -> None:
        super().activate()
        c = self.ctl
        self.key = None
        self.target = (c.x, c.y, c.z)
        self.traj.plan(self.target, self.target, (0.0, 0.0, 0.0), 1, 1, 1, 1, 1, 1, 1)
        self.land_vz = max(c.vz, 0.0)
        self.kind = -1  # the next plan starts from the vehicle's position and velocity

    def wants_takeoff(self, z: float) -> bool:
        return self.kind in (SP_TAKEOFF, SP_POSITION, SP_LOITER) and self.target[2] < z - 0.3

    def _local_target(self, sp: Any) -> tuple[float, float, float]:
        c = self.ctl
        if math.isfinite(sp.lat) and math.isfinite(sp.lon) and c.proj is not None \
                and (sp.lat != 0.0 or sp.lon != 0.0):
            x, y = c.proj.project(sp.lat, sp.lon)
        else:
            x, y = c.x, c.y
        z = c.ref_alt - sp.alt if math.isfinite(sp.alt) and c.ref_alt_valid else c.z
        return x, y, z

    def _replan(self, sp: Any) -> None:
        c = self.ctl
        p = c.prm
        kind = sp.type
        tgt = self._local_target(sp)
        if kind == SP_TAKEOFF:
            tgt = (self.target[0], self.target[1], tgt[2]) if self.kind == SP_TAKEOFF \
                else (c.x, c.y, tgt[2])
        # start from the reference if the vehicle follows it, else from the vehicle
        ref = self.traj.position()
        if (ref[0] - c.x) ** 2 + (ref[1] - c.y) ** 2 + (ref[2] - c.z) ** 2 < 4.0 \
                and self.kind >= 0:
            start, v0 = ref, self.traj.velocity()
        else:
            start, v0 = (c.x, c.y, c.z), (c.vx, c.vy, c.vz)
        cruise = sp.cruising_speed if sp.cruising_speed > 0.0 else p["MPC_XY_CRUISE"]
        v_up = p["MPC_TKO_SPEED"] if kind == SP_TAKEOFF else p["MPC_Z_VEL_MAX_UP"]
        self.traj.plan(start, tgt, v0, cruise, v_up, p["MPC_Z_VEL_MAX_DN"], p["MPC_ACC_HOR"],
                       p["MPC_ACC_UP_MAX"], p["MPC_ACC_DOWN_MAX"], p["MPC_JERK_AUTO"])
        self.target = tgt
        if kind == SP_LAND:
            self.land_xy = (tgt[0], tgt[1])
        if sp.yaw_valid and math.isfinite(sp.yaw):
            self.yaw = sp.yaw
        self.kind = kind

    def update(self, dt: float) -> None:
        c = self.ctl
        sp = c.triplet.current if c.triplet is not None else None
        if sp is None or not sp.valid:
            self.idle = False
            if self.kind != -2:
                self.kind = -2
                self.target = (c.x, c.y, c.z)
            self._hold(*self.target)
            return
        key = (sp.type, sp.lat, sp.lon, sp.alt, sp.yaw if sp.yaw_valid else None)
        if key != self.key:
            self.key = key
            self._replan(sp)
        self.idle = sp.type == SP_IDLE
        if sp.type == SP_LAND:
            self._land(dt)
            return
        if sp.type == SP_IDLE:
            self._hold(c.x, c.y, c.z)
            return
        if c.on_ground and sp.type == SP_TAKEOFF:
            # hold the line at the vehicle until the takeoff ramp is done
            self.traj.plan((c.x, c.y, c.z), (c.x, c.y, self.target[2]), (0.0, 0.0, 0.0),
                           1.0, c.prm["MPC_TKO_SPEED"], 1.0, 1.0, c.prm["MPC_ACC_UP_MAX"], 1.0,
                           c.prm["MPC_JERK_AUTO"])
            self.target = (c.x, c.y, self.target[2])
        self.traj.update(dt)
        px, py, pz = self.traj.position()
        vx, vy, vz = self.traj.velocity()
        ax, ay, az = self.traj.acceleration()
        self.pos[0], self.pos[1], self.pos[2] = px, py, pz
        self.vel[0], self.vel[1], self.vel[2] = vx, vy, vz
        self.acc[0], self.acc[1], self.acc[2] = ax, ay, az

    def _land(self, dt: float) -> None:
        """Hold the landing point, descend at the speed for the height above the ground."""
        c = self.ctl
        p = c.prm
        h = c.height_above_ground()
        alt1, alt2 = p["MPC_LAND_ALT1"], p["MPC_LAND_ALT2"]
        v_land, v_dn = p["MPC_LAND_SPEED"], p["MPC_Z_VEL_MAX_DN"]
        if h >= alt1:
            v = v_dn
        elif h <= alt2 or alt1 <= alt2:
            v = v_land
        else:
            v = v_land + (v_dn - v_land) * (h - alt2) / (alt1 - alt2)
        # slew the descent rate so the vertical speed changes smoothly
        step = p["MPC_ACC_DOWN_MAX"] * dt
        vz = self.land_vz
        vz = min(vz + step, v) if vz < v else max(vz - step, v)
        self.land_vz = vz
        self.pos[0], self.pos[1], self.pos[2] = self.land_xy[0], self.land_xy[1], NAN
        self.vel[0], self.vel[1], self.vel[2] = 0.0, 0.0, vz
        self.acc[0] = self.acc[1] = self.acc[2] = NAN
        self.traj.plan((c.x, c.y, c.z), (c.x, c.y, c.z), (0.0, 0.0, 0.0), 1, 1, 1, 1, 1, 1, 1)


def _deadzone(v: float, dz: float) -> float:
    """Stick with a centre dead zone, rescaled so full deflection is still 1."""
    if abs(v) <= dz:
        return 0.0
    return (v - math.copysign(dz, v)) / (1.0 - dz)


class _TaskManualZ(_Task):
    """Vertical part shared by the manual tasks: throttle stick = climb rate, centre = hold."""

    def activate(self) -> None:
        super().activate()
        self.z_hold = self.ctl.z
        self.z_locked = True
        self.vz_sp = 0.0

    def _update_z(self, dt: float) -> None:
        c = self.ctl
        p = c.prm
        thr = _deadzone(c.manual.throttle, p["MPC_HOLD_DZ"])
        vz = -thr * (p["MPC_Z_VEL_MAX_UP"] if thr > 0.0 else p["MPC_Z_VEL_MAX_DN"])
        acc = (p["MPC_ACC_UP_MAX"] if vz < self.vz_sp else p["MPC_ACC_DOWN_MAX"]) * dt
        self.vz_sp = min(max(vz, self.vz_sp - acc), self.vz_sp + acc)
        if thr != 0.0:
            self.z_locked = False
        elif not self.z_locked and abs(c.vz) < p["MPC_HOLD_MAX_Z"] and abs(self.vz_sp) < 0.1:
            self.z_locked, self.z_hold = True, c.z
        if self.z_locked:
            self.pos[2], self.vel[2] = self.z_hold, 0.0
        else:
            self.pos[2], self.vel[2] = NAN, self.vz_sp

    def _update_yaw(self, dt: float) -> None:
        c = self.ctl
        rate = c.manual.yaw * c.man_yaw_max
        self.yawspeed = rate
        self.yaw = math.remainder(self.yaw + rate * dt, 2.0 * math.pi)


class TaskManualAltitude(_TaskManualZ):
    """Sticks tilt the vehicle (as a horizontal acceleration), throttle is a climb rate."""

    name = "altitude"

    def update(self, dt: float) -> None:
        c = self.ctl
        self._update_z(dt)
        self._update_yaw(dt)
        tan_t = math.tan(c.man_tilt_max)
        # stick in the heading frame: pitch forward (positive) is +x, roll right is +y
        fx, fy = c.manual.pitch * tan_t * G0_M_S2, c.manual.roll * tan_t * G0_M_S2
        cy, sy = math.cos(self.yaw), math.sin(self.yaw)
        self.pos[0] = self.pos[1] = NAN
        self.vel[0] = self.vel[1] = NAN
        self.acc[0], self.acc[1], self.acc[2] = cy * fx - sy * fy, sy * fx + cy * fy, NAN


class TaskManualPosition(_TaskManualZ):
    """Sticks are horizontal velocities in the heading frame; centred, brake and hold."""

    name = "position"

    def activate(self) -> None:
        super().activate()
        c = self.ctl
        self.xy_hold = (c.x, c.y)
        self.xy_locked = True
        self.vsp = [0.0, 0.0]

    def update(self, dt: float) -> None:
        c = self.ctl
        p = c.prm
        self._update_z(dt)
        self._update_yaw(dt)
        dz = p["MPC_HOLD_DZ"]
        sx, sy_ = _deadzone(c.manual.pitch, dz), _deadzone(c.manual.roll, dz)
        vmax = p["MPC_VEL_MANUAL"]
        cy, sy = math.cos(self.yaw), math.sin(self.yaw)
        wx, wy = (cy * sx - sy * sy_) * vmax, (sy * sx + cy * sy_) * vmax
        # acceleration-limited velocity setpoint
        dvx, dvy = wx - self.vsp[0], wy - self.vsp[1]
        n = math.hypot(dvx, dvy)
        step = p["MPC_ACC_HOR_MAX"] * dt
        if n > step:
            dvx, dvy = dvx * step / n, dvy * step / n
        self.vsp[0] += dvx
        self.vsp[1] += dvy
        if sx != 0.0 or sy_ != 0.0:
            self.xy_locked = False
        elif not self.xy_locked and math.hypot(c.vx, c.vy) < p["MPC_HOLD_MAX_XY"] \
                and math.hypot(*self.vsp) < 0.1:
            # lock where the velocity loop will bring it to rest (v decays with 1/P)
            k = 0.5 / max(p["MPC_XY_VEL_P_ACC"], 0.1)
            self.xy_locked, self.xy_hold = True, (c.x + c.vx * k, c.y + c.vy * k)
        if self.xy_locked:
            self.pos[0], self.pos[1] = self.xy_hold
            self.vel[0] = self.vel[1] = 0.0
            self.vsp[0] = self.vsp[1] = 0.0
        else:
            self.pos[0] = self.pos[1] = NAN
            self.vel[0], self.vel[1] = self.vsp
        self.acc[0] = self.acc[1] = self.acc[2] = NAN
