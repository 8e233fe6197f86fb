"""The VTOL transition flight task (PX4's FlightTaskTransition, behaviour not code).

While a standard VTOL changes between multicopter and fixed-wing flight (front: the pusher
accelerates it; back: drag slows it), the lift rotors must neither hold a position against the
pusher nor chase one at cruise speed: they hold the altitude the transition started at
(vertical velocity setpoint 0 around it) and keep the vehicle level (no horizontal velocity or
position setpoint, no horizontal acceleration: the thrust vector stays vertical), on the
heading it had. The wing takes over the lift as airspeed grows; vtol_att_control fades the
rotors' share out (front) or in (back), and the altitude loop's integrator follows.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from firmware.modules.mc_pos_control.flight_tasks import _Task

if TYPE_CHECKING:
    from firmware.modules.mc_pos_control.mc_pos_control import McPosControlModule

__all__ = ["TaskTransition"]

NAN = math.nan


class TaskTransition(_Task):
    """Altitude hold, level, heading hold: the rotors' part of a VTOL transition."""

    name = "transition"

    def __init__(self, ctl: McPosControlModule) -> None:
        super().__init__(ctl)
        self.z_hold = 0.0

    def activate(self) -> None:
        super().activate()
        self.z_hold = self.ctl.z

    def wants_takeoff(self, z: float) -> bool:
        return False     # a transition is flown in the air; on the ground it stays there

    def update(self, dt: float) -> None:
        self.pos[0] = self.pos[1] = NAN
        self.pos[2] = self.z_hold
        self.vel[0] = self.vel[1] = NAN
        self.vel[2] = 0.0
        self.acc[0] = self.acc[1] = self.acc[2] = NAN
        self.yawspeed = 0.0
