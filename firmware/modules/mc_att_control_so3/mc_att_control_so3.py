"""Multicopter attitude controller, geometric law on SO(3) (``mc_att_control_so3``).

The second implementation of the attitude controller (issue 23): the same inputs and outputs
as ``mc_att_control`` (``vehicle_attitude_setpoint`` or the sticks in stabilized mode ->
``vehicle_rates_setpoint``), another law (``so3.py``: Lee, Leok, McClamroch 2010, with the
integral of Goodarzi, Lee, Lee 2013), so that either can fly the vehicle and one can replace
the other in flight: ``mc_att_control stop; mc_att_control_so3 start`` on one shell line, or
``param set MC_ATT_IMPL 1`` (``mc_att_select``).

Bumpless start: the integrator starts at the difference between the last rate setpoint the
previous controller published and this law's proportional part and feed-forward
(back-calculation), so the first output equals the last one (``handover.py``); the manual
heading setpoint starts from the last attitude setpoint's. The integrator only runs airborne
and armed, and is cleared on the ground, as PX4's rate integrators are.

Gains: ``MC_SO3_RP_P``/``MC_SO3_YAW_P`` (1/s, per body axis; the PX4 defaults of
``MC_ROLL_P``/``MC_YAW_P``), ``MC_SO3_I`` (1/s^2) limited to ``MC_SO3_I_LIM`` (rad/s); rate
limits, manual tilt and throttle curve are ``mc_att_control``'s parameters.

Everything but the law is ``mc_att_control``'s (this class derives from it and overrides
``_law`` and ``_hand_over``): the inputs, stabilized mode, the VTOL hand-off to the
fixed-wing controller, the rate limits and the publication.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Final

from firmware.modules.mc_att_control.mc_att_control import PARAMS as MC_ATT_PARAMS
from firmware.modules.mc_att_control.mc_att_control import McAttControlModule
from common.quaternion import Quat
from firmware.modules.mc_att_control_so3.so3 import so3_error, yaw_feed_forward_body
from firmware.platform.params import ParamDef

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["PARAMS", "McAttControlSo3Module"]

_G: Final = "Multicopter Attitude Control"

PARAMS: tuple[ParamDef, ...] = (
    ParamDef("MC_SO3_RP_P", "FLOAT", 6.5, min=0.0, max=12.0, unit="1/s", group=_G,
             decimals=2, short="SO(3) attitude controller: roll and pitch gain"),
    ParamDef("MC_SO3_YAW_P", "FLOAT", 2.8, min=0.0, max=5.0, unit="1/s", group=_G,
             decimals=2, short="SO(3) attitude controller: yaw gain"),
    ParamDef("MC_SO3_I", "FLOAT", 0.5, min=0.0, max=5.0, unit="1/s^2", group=_G, decimals=2,
             short="SO(3) attitude controller: integral gain",
             long="Integral of the attitude error added to the rate setpoint (airborne only)."),
    ParamDef("MC_SO3_I_LIM", "FLOAT", 0.3, min=0.0, max=2.0, unit="rad/s", group=_G,
             decimals=2, short="SO(3) attitude controller: integral limit per axis"),
) + MC_ATT_PARAMS   # the rate limits, manual tilt and throttle curve it shares


def _clamp(v: float, lim: float) -> float:
    return -lim if v < -lim else (lim if v > lim else v)


class McAttControlSo3Module(McAttControlModule):
    """``mc_att_control_so3``: vehicle_attitude (+ setpoint or sticks) -> vehicle_rates_setpoint
    by the geometric law."""

    NAME = "mc_att_control_so3"
    DESCRIPTION = "multicopter attitude controller, geometric SO(3) law (Lee 2010)"
    #: STM32F427: two quaternion products, no trigonometry, ~80 us per run
    CPU_COST_NS = 80_000
    PARAMS = PARAMS
    ATT_IMPL = 1

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.man_yaw_sp = math.nan
        self.integ = [0.0, 0.0, 0.0]      # rad/s per body axis
        self.err = (0.0, 0.0, 0.0)

    def _load_params(self) -> None:
        super()._load_params()
        p = self.param
        self.gains = (float(p("MC_SO3_RP_P")), float(p("MC_SO3_RP_P")), float(p("MC_SO3_YAW_P")))
        self.ki = float(p("MC_SO3_I"))
        self.i_lim = float(p("MC_SO3_I_LIM"))

    def _law(self, q: Quat, dt: float, now: int) -> tuple[float, float, float]:
        """Lee's proportional term on the SO(3) error, the yaw feed-forward, and the
        integral (airborne and armed only, cleared on the ground and on reset_integral)."""
        e = so3_error(q, self.qd)
        self.err = e
        kr, kp, ky = self.gains
        ffr, ffp, ffy = yaw_feed_forward_body(q, self.yawspeed_ff)
        pr, pp, py = kr * e[0] + ffr, kp * e[1] + ffp, ky * e[2] + ffy
        integ = self.integ
        if self.first_output:
            self._hand_over(pr, pp, py, now)
        elif not self.armed or self.landed or self.reset_integral:
            integ[0] = integ[1] = integ[2] = 0.0
        else:
            ki, lim = self.ki * dt, self.i_lim
            integ[0] = _clamp(integ[0] + ki * e[0], lim)
            integ[1] = _clamp(integ[1] + ki * e[1], lim)
            integ[2] = _clamp(integ[2] + ki * e[2], lim)
        return pr + integ[0], pp + integ[1], py + integ[2]

    def _hand_over(self, pr: float, pp: float, py: float, now: int) -> None:
        """First output: start the integrator at what the previous controller's last rate
        setpoint had beyond this law's proportional part (back-calculation), if recent and
        flying; it absorbs the difference up to MC_SO3_I_LIM per axis."""
        self.first_output = False
        ho = self.handover
        if not ho.take(self.pub_rates.node.last, now) or not self.armed or self.landed:
            return
        dr, dp, dy = ho.difference(pr, pp, py)
        lim = self.i_lim
        self.integ[0], self.integ[1], self.integ[2] = _clamp(dr, lim), _clamp(dp, lim), \
            _clamp(dy, lim)
        i = self.integ
        self.info(ho.report(pr + i[0], pp + i[1], py + i[2],
                            math.sqrt(dr * dr + dp * dp + dy * dy)))

    def status_lines(self) -> list[str]:
        e, i = self.err, self.integ
        lines = super().status_lines()
        return lines[:2] + [
            f"attitude error (sin angle * axis) {e[0]:+.4f} {e[1]:+.4f} {e[2]:+.4f}",
            f"integrator r {i[0]:+.4f} p {i[1]:+.4f} y {i[2]:+.4f} rad/s"] + lines[2:]
