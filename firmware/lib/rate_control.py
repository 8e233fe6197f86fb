"""PX4's ``RateControl`` library (src/lib/rate_control): a PID with feed-forward on body rates.

The multicopter rate controller (``mc_rate_control``) owns one and feeds it every
``vehicle_angular_velocity``; the library knows nothing of uORB or parameters, so it can be
tested alone (tests/flight/test_rate_control.py) and reused by other vehicles, as in PX4.

Control law, per axis, on :class:`~firmware.lib.vector3.Vector3` (gains already multiplied by
PX4's common ``MC_*RATE_K``, as MulticopterRateControl does before ``setPidGains``)::

    torque = P * e + I_state - D * angular_accel + FF * rate_sp,    e = rate_sp - rate

* D acts on the measured angular acceleration, not on the error: a setpoint step gives no
  derivative kick.
* The integrator is clamped to ``integrator limit`` per axis and is not propagated when the
  result is not finite.
* Anti-windup: the control allocator's saturation status (:meth:`set_saturation_status`) says
  per axis whether more positive or more negative torque cannot be produced; the error is then
  clamped so the integrator does not grow further in that direction (PX4's ``updateIntegral``).

PX4 also scales the I gain down with large rate errors (``i_factor``, full at 0, none at 400
deg/s); this model does not (its rate controller never did), which keeps the logs of flights
flown before the library existed byte-identical.

:meth:`update` is PX4's call: torque from the current integrator, then the integrator updated
unless landed, with the saturation status set before the call. A caller whose saturation is
judged from the torque just computed (mc_rate_control predicts the IO's mixer, which it cannot
observe) uses the two halves, :meth:`torque` and :meth:`update_integral`, with
:meth:`set_saturation_status` between them.
"""

from __future__ import annotations

import math
from typing import Any

from firmware.lib.vector3 import Vector3

__all__ = ["RateControl"]


class RateControl:
    """PID + FF on the three body rates with integrator limits and anti-windup."""

    def __init__(self) -> None:
        self.gain_p = Vector3()
        self.gain_i = Vector3()
        self.gain_d = Vector3()
        self.gain_ff = Vector3()
        self.lim_int = Vector3()
        self.rate_int = Vector3()
        #: the error of the last :meth:`torque` call, integrated by :meth:`update_integral`
        self.rate_error = Vector3()
        self.sat_pos: tuple[bool, bool, bool] = (False, False, False)
        self.sat_neg: tuple[bool, bool, bool] = (False, False, False)

    # -- configuration (PX4: setPidGains, setIntegratorLimit, setFeedForwardGain) -------------

    def set_pid_gains(self, p: Vector3, i: Vector3, d: Vector3) -> None:
        self.gain_p, self.gain_i, self.gain_d = p.copy(), i.copy(), d.copy()

    def set_integrator_limit(self, lim: Vector3) -> None:
        self.lim_int = lim.copy()

    def set_feed_forward_gain(self, ff: Vector3) -> None:
        self.gain_ff = ff.copy()

    def set_saturation_status(self, positive: tuple[bool, bool, bool],
                              negative: tuple[bool, bool, bool]) -> None:
        """Per axis: the allocator cannot give more positive / more negative torque."""
        self.sat_pos = positive
        self.sat_neg = negative

    # -- the loop --------------------------------------------------------------------------

    def update(self, rate: Vector3, rate_sp: Vector3, angular_accel: Vector3, dt: float,
               landed: bool) -> Vector3:
        """Torque command (normalised, unclamped) for one rate sample; integrates unless
        ``landed``. ``dt`` in s, rates in rad/s, ``angular_accel`` in rad/s^2."""
        torque = self.torque(rate, rate_sp, angular_accel)
        if not landed:
            self.update_integral(dt)
        return torque

    def torque(self, rate: Vector3, rate_sp: Vector3, angular_accel: Vector3) -> Vector3:
        """The first half of :meth:`update`: the PID + FF output with the current integrator."""
        e = rate_sp - rate
        self.rate_error = e
        return (self.gain_p.emult(e) + self.rate_int - self.gain_d.emult(angular_accel)
                + self.gain_ff.emult(rate_sp))

    def update_integral(self, dt: float) -> None:
        """The second half of :meth:`update`: integrate the last error over ``dt`` s, with
        anti-windup from the saturation status and the integrator limits."""
        e, i, gi, lim = self.rate_error, self.rate_int, self.gain_i, self.lim_int
        pos, neg = self.sat_pos, self.sat_neg
        i.x = _integrate(i.x, _unsaturated(e.x, pos[0], neg[0]), gi.x, lim.x, dt)
        i.y = _integrate(i.y, _unsaturated(e.y, pos[1], neg[1]), gi.y, lim.y, dt)
        i.z = _integrate(i.z, _unsaturated(e.z, pos[2], neg[2]), gi.z, lim.z, dt)

    def reset_integral(self) -> None:
        """PX4's ``resetIntegral``: on arming, disarming, landing or a controller's request."""
        i = self.rate_int
        i.x = i.y = i.z = 0.0

    def get_rate_control_status(self, status: Any) -> None:
        """Fill a ``rate_ctrl_status``-like message's integrator fields (PX4's
        ``getRateControlStatus``)."""
        status.rollspeed_integ = self.rate_int.x
        status.pitchspeed_integ = self.rate_int.y
        status.yawspeed_integ = self.rate_int.z


def _unsaturated(e: float, positive: bool, negative: bool) -> float:
    """The error with the saturated direction removed (no further wind-up that way)."""
    if positive and e > 0.0:
        return 0.0
    if negative and e < 0.0:
        return 0.0
    return e


def _integrate(i: float, e: float, gain: float, lim: float, dt: float) -> float:
    v = i + gain * e * dt
    if not math.isfinite(v):
        return i
    return -lim if v < -lim else (min(v, lim))
