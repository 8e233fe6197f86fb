"""The fixed-wing attitude and rate laws (PX4's ECL roll, pitch and yaw controllers in shape).

Per axis, two loops:

* attitude: an Euler angle error over a time constant gives an Euler rate setpoint
  (``FW_R_TC``, ``FW_P_TC``), limited (``FW_R_RMAX``, ``FW_P_RMAX_POS/NEG``); yaw has no
  angle loop: the coordinated-turn rate ``g tan(roll) cos(pitch) / V`` keeps the sideslip zero;
* rate: the Euler rates turned into body rates, then P, I and feed-forward on the body rate
  with airspeed scaling. Control surface moments grow with dynamic pressure, so the same
  deflection does more at speed: the scaler ``s = V_trim / V`` multiplies the feed-forward
  (which fights the damping moment, itself proportional to V) once and the P and I terms
  (which fight accelerations, proportional to V^2) twice::

      u = FF * s * rate_sp + P * s^2 * e + I,        I += I_gain * s^2 * e * dt  (|I| <= IMAX)

The integrator does not grow into a saturated output and is frozen on the ground (the module
tells it). Pure classes, unit-tested in tests/firmware/fw/test_fw_att_control.py.
"""

from __future__ import annotations

import math
from typing import Final
from common.units import G0_M_S2

__all__ = ["RateLoop", "coordinated_yaw_rate", "euler_rates_to_body"]



class RateLoop:
    """P + I + FF on one body rate with airspeed scaling and a bounded integrator."""

    def __init__(self) -> None:
        self.k_p = 0.05
        self.k_i = 0.1
        self.k_ff = 0.5
        self.i_max = 0.2
        self.integrator = 0.0
        self.last_output = 0.0

    def set_gains(self, k_p: float, k_i: float, k_ff: float, i_max: float) -> None:
        self.k_p, self.k_i, self.k_ff, self.i_max = k_p, k_i, k_ff, i_max

    def reset(self) -> None:
        self.integrator = 0.0

    def control(self, rate_sp: float, rate: float, scaler: float, dt: float,
                integrate: bool) -> float:
        err = rate_sp - rate
        if integrate and self.k_i > 0.0:
            di = err * dt * scaler * scaler * self.k_i
            # anti-windup: no further into a saturated output
            if (self.last_output >= 1.0 and di > 0.0) or (self.last_output <= -1.0 and di < 0.0):
                di = 0.0
            lim = self.i_max
            i = self.integrator + di
            self.integrator = -lim if i < -lim else (lim if i > lim else i)
        u = rate_sp * self.k_ff * scaler + err * self.k_p * scaler * scaler + self.integrator
        u = -1.0 if u < -1.0 else (1.0 if u > 1.0 else u)
        self.last_output = u
        return u


def coordinated_yaw_rate(roll: float, pitch: float, airspeed_m_s: float) -> float:
    """The heading rate (rad/s) of a turn without sideslip at this bank and airspeed."""
    if abs(roll) > 0.5 * math.pi - 0.05:  # knife edge or inverted: no coordinated turn
        return 0.0
    return math.tan(roll) * math.cos(pitch) * G0_M_S2 / max(airspeed_m_s, 1.0)


def euler_rates_to_body(roll: float, pitch: float, roll_dot: float, pitch_dot: float,
                        yaw_dot: float) -> tuple[float, float, float]:
    """Euler angle rates (ZYX) to body rates p, q, r."""
    sr, cr = math.sin(roll), math.cos(roll)
    sp, cp = math.sin(pitch), math.cos(pitch)
    return (roll_dot - sp * yaw_dot,
            cr * pitch_dot + sr * cp * yaw_dot,
            -sr * pitch_dot + cr * cp * yaw_dot)
