"""The position -> velocity -> acceleration -> thrust cascade, on plain floats.

Units: NED metres, m/s, m/s^2; thrust normalised (1 = full collective). NaN in a setpoint axis
means "not controlled at this level" (PX4's convention): a NaN position gives a pure velocity
setpoint, a NaN velocity with a finite acceleration gives a pure acceleration (tilt) setpoint.

1. velocity setpoint = MPC_*_P * position error + velocity feed-forward, limited (horizontal
   norm MPC_XY_VEL_MAX, vertical MPC_Z_VEL_MAX_UP/DN);
2. acceleration = P * velocity error + I + acceleration feed-forward - D * measured
   acceleration (D on the measurement, no kick on setpoint steps);
3. thrust: the vertical part is ``(g - a_z) * hover / g`` (thrust proportional to throttle
   around hover, the hover throttle from the estimator), clamped to [MPC_THR_MIN, MPC_THR_MAX];
   the horizontal part is limited by the tilt limit and by what is left of MPC_THR_MAX, so
   altitude has priority over horizontal acceleration;
4. the integrators stop in the direction of a saturated output (anti-windup).

The attitude setpoint follows from the thrust direction and the yaw setpoint.
"""

from __future__ import annotations

import math
from typing import Final

from common.quaternion import Quat, q_from_dcm_columns
from common.units import G0_M_S2

__all__ = ["G", "PositionControl", "attitude_from_thrust"]



def attitude_from_thrust(tx: float, ty: float, tz: float, yaw: float) -> Quat:
    """The attitude whose body -z axis points along the thrust vector, with heading ``yaw``."""
    n = math.sqrt(tx * tx + ty * ty + tz * tz)
    if n < 1e-6:
        bz = (0.0, 0.0, 1.0)
    else:
        bz = (-tx / n, -ty / n, -tz / n)
    # y axis of the heading frame, then x = yc x bz, y = bz x x
    ycx, ycy = -math.sin(yaw), math.cos(yaw)
    bx = (ycy * bz[2], -ycx * bz[2], ycx * bz[1] - ycy * bz[0])
    nx = math.sqrt(bx[0] * bx[0] + bx[1] * bx[1] + bx[2] * bx[2])
    if nx < 1e-6:  # thrust horizontal along the heading's y axis: degenerate, keep level x
        bx = (math.cos(yaw), math.sin(yaw), 0.0)
    else:
        bx = (bx[0] / nx, bx[1] / nx, bx[2] / nx)
    by = (bz[1] * bx[2] - bz[2] * bx[1], bz[2] * bx[0] - bz[0] * bx[2],
          bz[0] * bx[1] - bz[1] * bx[0])
    return q_from_dcm_columns(bx, by, bz)


class PositionControl:
    """State (the velocity integrators) and one update of the cascade."""

    def __init__(self) -> None:
        self.xy_p = 0.95
        self.z_p = 1.0
        self.vxy_p, self.vxy_i, self.vxy_d = 1.8, 0.4, 0.2
        self.vz_p, self.vz_i, self.vz_d = 4.0, 2.0, 0.0
        self.vxy_max, self.vz_up, self.vz_dn = 12.0, 3.0, 1.5
        self.tilt_max = math.radians(45.0)
        self.thr_min, self.thr_max = 0.12, 1.0
        self.hover = 0.5
        self.int_x = self.int_y = self.int_z = 0.0
        # outputs of the last update
        self.vel_sp = [0.0, 0.0, 0.0]
        self.acc_sp = [0.0, 0.0, 0.0]
        self.thrust = [0.0, 0.0, 0.0]

    def reset(self) -> None:
        self.int_x = self.int_y = self.int_z = 0.0

    def set_hover_thrust(self, hover: float) -> None:
        """Change the hover thrust without a thrust jump: re-express the z integrator."""
        hover = min(max(hover, 0.05), 0.95)
        if hover != self.hover:
            self.int_z += (self.acc_sp[2] - G0_M_S2) * (self.hover / hover - 1.0)
            self.hover = hover

    def update(self, dt: float, pos: tuple[float, float, float],
               vel: tuple[float, float, float], acc: tuple[float, float, float],
               pos_sp: list[float], vel_sp: list[float], acc_sp: list[float],
               integrate_xy: bool = True, integrate_z: bool = True,
               thr_max_override: float | None = None) -> None:
        """One step; results in ``vel_sp``, ``acc_sp`` and ``thrust`` (NED, normalised)."""
        # -- position -> velocity ---------------------------------------------------------
        v = self.vel_sp
        for i, k in ((0, self.xy_p), (1, self.xy_p), (2, self.z_p)):
            ps, vs = pos_sp[i], vel_sp[i]
            if math.isfinite(ps):
                v[i] = k * (ps - pos[i]) + (vs if math.isfinite(vs) else 0.0)
            else:
                v[i] = vs
        vx, vy, vz = v
        if math.isfinite(vx) and math.isfinite(vy):
            n = math.hypot(vx, vy)
            if n > self.vxy_max:
                s = self.vxy_max / n
                v[0] = vx = vx * s
                v[1] = vy = vy * s
        if math.isfinite(vz):
            v[2] = vz = -self.vz_up if vz < -self.vz_up else (min(vz, self.vz_dn))

        # -- velocity -> acceleration -----------------------------------------------------
        a = self.acc_sp
        ex = ey = ez = 0.0
        xy_vel = math.isfinite(vx) and math.isfinite(vy)
        if xy_vel:
            ex, ey = vx - vel[0], vy - vel[1]
            a[0] = self.vxy_p * ex + self.int_x - self.vxy_d * acc[0]
            a[1] = self.vxy_p * ey + self.int_y - self.vxy_d * acc[1]
        else:
            a[0] = a[1] = 0.0
        if math.isfinite(acc_sp[0]) and math.isfinite(acc_sp[1]):
            a[0] += acc_sp[0]
            a[1] += acc_sp[1]
        z_vel = math.isfinite(vz)
        if z_vel:
            ez = vz - vel[2]
            a[2] = self.vz_p * ez + self.int_z - self.vz_d * acc[2]
        else:
            a[2] = self.int_z
        if math.isfinite(acc_sp[2]):
            a[2] += acc_sp[2]

        # -- acceleration -> thrust ---------------------------------------------------------
        hg = self.hover / G0_M_S2
        thr_max = self.thr_max if thr_max_override is None else thr_max_override
        thr_min = min(self.thr_min, thr_max)
        tz = (G0_M_S2 - a[2]) * hg           # vertical thrust, positive up
        sat_z_hi = tz > thr_max
        sat_z_lo = tz < thr_min
        tz = thr_max if sat_z_hi else (thr_min if sat_z_lo else tz)
        tx, ty = a[0] * hg, a[1] * hg
        txy = math.hypot(tx, ty)
        lim = tz * math.tan(self.tilt_max)
        rem = thr_max * thr_max - tz * tz
        rem = math.sqrt(rem) if rem > 0.0 else 0.0
        lim = min(lim, rem)
        sat_xy = txy > lim
        if sat_xy:
            s = lim / txy
            tx, ty = tx * s, ty * s
        t = self.thrust
        t[0], t[1], t[2] = tx, ty, -tz

        # -- integrators with anti-windup ---------------------------------------------------
        if z_vel and integrate_z and not ((sat_z_hi and ez < 0.0) or (sat_z_lo and ez > 0.0)):
            iz = self.int_z + self.vz_i * ez * dt
            self.int_z = -G0_M_S2 if iz < -G0_M_S2 else (min(iz, G0_M_S2))
        if xy_vel and integrate_xy and not (sat_xy and ex * a[0] + ey * a[1] > 0.0):
            ix = self.int_x + self.vxy_i * ex * dt
            iy = self.int_y + self.vxy_i * ey * dt
            n = math.hypot(ix, iy)
            if n > G0_M_S2:
                ix, iy = ix * G0_M_S2 / n, iy * G0_M_S2 / n
            self.int_x, self.int_y = ix, iy
