"""The offboard "flight task": fly the ``trajectory_setpoint`` an offboard controller sends.

In Offboard mode PX4 runs no flight task: the MAVLink receiver publishes the setpoint of each
SET_POSITION_TARGET_* message as ``trajectory_setpoint`` and the position controller follows
the latest one as it is, however old (keeping the stream alive is the commander's business:
COM_OF_LOSS_T). So a velocity setpoint keeps the vehicle moving at that velocity, a position
setpoint holds that position, position and velocity together give the velocity as a
feed-forward. This task does the same, and while it runs ``mc_pos_control`` does not publish a
trajectory setpoint of its own.

Before the first setpoint after the switch, and whenever a setpoint is one PX4's
``PositionControl::_inputValid`` refuses (an axis with nothing finite to control, x and y not
given together, a position without a valid position estimate, a velocity without a valid
velocity estimate), the vehicle stops where it is: velocity 0 on every axis, PX4's failsafe
setpoint (``generateFailsafeSetpoint``) with a velocity estimate. Infinite values are treated
as not given (NaN): an emulator guard, the MAVLink side already drops such messages.

Yaw: a finite ``yaw`` is the heading; without one a finite ``yawspeed`` turns the held heading,
else the heading at the switch is kept.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Final

from firmware.modules.mc_pos_control.flight_tasks import _Task

if TYPE_CHECKING:
    from firmware.modules.mc_pos_control.mc_pos_control import McPosControlModule

__all__ = ["TaskOffboard"]

NAN: Final = math.nan


def _finite_or_nan(v: float) -> float:
    return v if math.isfinite(v) else NAN


class TaskOffboard(_Task):
    """The latest offboard trajectory_setpoint, or stop if there is none usable."""

    name = "offboard"

    def __init__(self, ctl: McPosControlModule) -> None:
        super().__init__(ctl)
        self.sp_pos = [NAN, NAN, NAN]
        self.sp_vel = [NAN, NAN, NAN]
        self.sp_acc = [NAN, NAN, NAN]
        self.sp_yaw = NAN
        self.sp_yawspeed = NAN
        self.have_sp = False
        self.invalid = 0   # cycles flown on the failsafe setpoint with a setpoint present

    def activate(self) -> None:
        super().activate()
        # what is queued now was published before the switch (by this module, in another
        # mode): the offboard controller's setpoints are those that arrive from now on
        self.ctl.sub_traj.copy()
        self.have_sp = False

    def _take(self, m: Any) -> None:
        for i in range(3):
            self.sp_pos[i] = _finite_or_nan(float(m.position[i]))
            self.sp_vel[i] = _finite_or_nan(float(m.velocity[i]))
            self.sp_acc[i] = _finite_or_nan(float(m.acceleration[i]))
        self.sp_yaw = _finite_or_nan(float(m.yaw))
        self.sp_yawspeed = _finite_or_nan(float(m.yawspeed))
        self.have_sp = True

    def input_valid(self) -> bool:
        """PX4's PositionControl::_inputValid on the offboard setpoint."""
        finite = [[math.isfinite(x) for x in sp] for sp in (self.sp_pos, self.sp_vel, self.sp_acc)]
        p, v, a = finite
        if not all(pi or vi or ai for pi, vi, ai in zip(p, v, a)):
            return False  # an axis with no setpoint at any level
        if any(s[0] != s[1] for s in finite):
            return False  # x and y are controlled together
        lp = self.ctl.lpos
        if (p[0] and not lp.xy_valid) or (p[2] and not lp.z_valid):
            return False
        return not ((v[0] and not lp.v_xy_valid) or (v[2] and not lp.v_z_valid))

    def update(self, dt: float) -> None:
        m = self.ctl.sub_traj.copy() if self.ctl.sub_traj.updated() else None
        if m is not None:
            self._take(m)
        if self.have_sp and self.input_valid():
            for i in range(3):
                self.pos[i], self.vel[i], self.acc[i] = \
                    self.sp_pos[i], self.sp_vel[i], self.sp_acc[i]
        else:
            if self.have_sp:
                self.invalid += 1
            self.pos[0] = self.pos[1] = self.pos[2] = NAN
            self.vel[0] = self.vel[1] = self.vel[2] = 0.0
            self.acc[0] = self.acc[1] = self.acc[2] = NAN
        if math.isfinite(self.sp_yaw) and self.have_sp:
            self.yaw = self.sp_yaw
            self.yawspeed = 0.0
        elif math.isfinite(self.sp_yawspeed) and self.have_sp:
            self.yawspeed = self.sp_yawspeed
            self.yaw = math.remainder(self.yaw + self.yawspeed * dt, 2.0 * math.pi)
        else:
            self.yawspeed = 0.0
