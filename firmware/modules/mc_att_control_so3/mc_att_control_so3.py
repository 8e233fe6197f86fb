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
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Final

from firmware.modules.mc_att_control.handover import Handover, other_att_controller
from firmware.modules.mc_att_control.mc_att_control import PARAMS as MC_ATT_PARAMS
from firmware.modules.mc_att_control.quat import Quat, qfrom_axis_angle, qfrom_euler, qmul, qyaw
from firmware.modules.mc_att_control_so3.so3 import so3_error, yaw_feed_forward_body
from firmware.platform.module import ModuleError, WorkItemModule
from firmware.platform.params import ParamDef

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["PARAMS", "McAttControlSo3Module"]

_G: Final = "Multicopter Attitude Control"
_D2R: Final = math.pi / 180.0

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


class McAttControlSo3Module(WorkItemModule):
    """``mc_att_control_so3``: vehicle_attitude (+ setpoint or sticks) -> vehicle_rates_setpoint
    by the geometric law."""

    NAME = "mc_att_control_so3"
    DESCRIPTION = "multicopter attitude controller, geometric SO(3) law (Lee 2010)"
    WQ = "wq:rate_ctrl"
    #: STM32F427: two quaternion products, no trigonometry, ~80 us per run
    CPU_COST_NS = 80_000
    INTERVAL_LIMIT_US = 4_000
    PARAMS = PARAMS
    ATT_IMPL = 1

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.qd: Quat = (1.0, 0.0, 0.0, 0.0)
        self.thrust_body = [0.0, 0.0, 0.0]
        self.yawspeed_ff = 0.0
        self.reset_integral = False
        self.stabilized = False
        self.attitude_enabled = True
        self.armed = False
        self.landed = True
        self.man_yaw_sp = math.nan
        self.last_att_us = 0
        self.have_sp = False
        self.integ = [0.0, 0.0, 0.0]      # rad/s per body axis
        self.err = (0.0, 0.0, 0.0)
        self.handover = Handover()
        self.first_output = True
        self.rates_published = 0

    def _start(self) -> None:
        other = other_att_controller(self.system.modules, self.name)
        if other is not None:
            raise ModuleError(f"{other} is running: `{other} stop; {self.name} start` on one "
                              "line, or set MC_ATT_IMPL")
        orb = self.platform.orb
        self.pub_rates = self.advertise("vehicle_rates_setpoint")
        self.rates_msg = orb.new("vehicle_rates_setpoint")
        self.pub_att_sp = self.advertise("vehicle_attitude_setpoint")
        self.att_sp_msg = orb.new("vehicle_attitude_setpoint")
        item = self.work_item
        assert item is not None
        self.sub_att = self.subscribe_callback(item, "vehicle_attitude",
                                               interval_us=self.INTERVAL_LIMIT_US)
        self.sub_att_sp = self.subscribe("vehicle_attitude_setpoint")
        self.sub_mode = self.subscribe("vehicle_control_mode")
        self.sub_manual = self.subscribe("manual_control_setpoint")
        self.sub_land = self.subscribe("vehicle_land_detected")
        self.sub_armed = self.subscribe("actuator_armed")
        self.sub_hover = self.subscribe("hover_thrust_estimate")
        self.sub_param = self.subscribe("parameter_update")
        self.manual = orb.new("manual_control_setpoint")
        params = self.system.params
        hover = params.get("MPC_THR_HOVER", 0.5) if params is not None else 0.5
        self.hover_thrust = float(hover if hover is not None else 0.5)
        self._load_params()
        last_sp = self.sub_att_sp.node.last
        yaw_sp = float(last_sp.yaw_body) if last_sp is not None else math.nan
        self.man_yaw_sp = yaw_sp if math.isfinite(yaw_sp) else math.nan
        if params is not None and "MC_ATT_IMPL" in params \
                and params["MC_ATT_IMPL"] != self.ATT_IMPL:
            params.set("MC_ATT_IMPL", self.ATT_IMPL)
        if self.sub_att.node.last is not None:
            # a swap in flight: answer the latest attitude now, which the controller stopped
            # a moment ago may have left queued, rather than one attitude period later
            item.schedule_now()

    def _stop(self) -> None:
        self.info(f"stopped after {self.rates_published} rate setpoints")

    def _load_params(self) -> None:
        p = self.param
        self.gains = (float(p("MC_SO3_RP_P")), float(p("MC_SO3_RP_P")), float(p("MC_SO3_YAW_P")))
        self.ki = float(p("MC_SO3_I"))
        self.i_lim = float(p("MC_SO3_I_LIM"))
        self.rate_max = (p("MC_ROLLRATE_MAX") * _D2R, p("MC_PITCHRATE_MAX") * _D2R,
                         p("MC_YAWRATE_MAX") * _D2R)
        self.man_tilt_max = p("MPC_MAN_TILT_MAX") * _D2R
        self.man_yaw_max = p("MPC_MAN_Y_MAX") * _D2R
        self.manthr_min = float(p("MPC_MANTHR_MIN"))
        self.thr_curve = int(p("MPC_THR_CURVE"))
        params = self.system.params
        thr_max = params.get("MPC_THR_MAX", 1.0) if params is not None else 1.0
        self.thr_max = float(thr_max if thr_max is not None else 1.0)
        if params is not None and "MPC_THR_HOVER" in params and not self.sub_hover.advertised:
            self.hover_thrust = float(params["MPC_THR_HOVER"])

    # -- inputs (as mc_att_control) -----------------------------------------------------------

    def _poll(self) -> None:
        m = self.sub_mode.update()
        if m is not None:
            self.attitude_enabled = bool(m.flag_control_attitude_enabled)
            self.stabilized = bool(m.flag_control_attitude_enabled
                                   and m.flag_control_manual_enabled
                                   and not m.flag_control_climb_rate_enabled
                                   and not m.flag_control_velocity_enabled
                                   and not m.flag_control_position_enabled)
        m = self.sub_land.update()
        if m is not None:
            self.landed = bool(m.landed)
        m = self.sub_armed.update()
        if m is not None:
            self.armed = bool(m.armed)
        m = self.sub_manual.update()
        if m is not None:
            self.manual = m
        m = self.sub_hover.update()
        if m is not None and m.valid:
            self.hover_thrust = float(m.hover_thrust)
        if self.sub_param.updated():
            self.sub_param.update()
            self._load_params()
        if not self.stabilized:
            sp = self.sub_att_sp.update()
            if sp is not None:
                self.qd = (float(sp.q_d[0]), float(sp.q_d[1]), float(sp.q_d[2]),
                           float(sp.q_d[3]))
                tb = sp.thrust_body
                self.thrust_body[0], self.thrust_body[1], self.thrust_body[2] = tb[0], tb[1], tb[2]
                self.yawspeed_ff = float(sp.yaw_sp_move_rate)
                self.reset_integral = bool(sp.reset_integral)
                self.have_sp = True

    def _throttle_curve(self, stick: float) -> float:
        """Throttle stick (-1..1) to collective thrust: mid stick is hover unless curve = 1."""
        t = min(max(0.5 * (stick + 1.0), 0.0), 1.0)
        lo, hi = self.manthr_min, self.thr_max
        if self.thr_curve == 1:
            return lo + (hi - lo) * t
        h = min(max(self.hover_thrust, lo), hi)
        if t < 0.5:
            return lo + (h - lo) * 2.0 * t
        return h + (hi - h) * 2.0 * (t - 0.5)

    def _stabilized_setpoint(self, q: Quat, dt: float) -> None:
        """Sticks -> attitude setpoint, as mc_att_control makes it (published for the log)."""
        man = self.manual
        yaw = qyaw(q)
        thr = self._throttle_curve(man.throttle)
        if self.man_yaw_sp != self.man_yaw_sp:  # NaN: started with no heading setpoint
            self.man_yaw_sp = yaw
        if not self.armed or self.landed and thr <= self.manthr_min + 0.05:
            self.man_yaw_sp = yaw
            self.yawspeed_ff = 0.0
        else:
            self.yawspeed_ff = man.yaw * self.man_yaw_max
            self.man_yaw_sp += self.yawspeed_ff * dt
            err = math.remainder(self.man_yaw_sp - yaw, 2.0 * math.pi)
            if abs(err) > 0.5 * math.pi:
                self.man_yaw_sp = yaw + math.copysign(0.5 * math.pi, err)
        self.man_yaw_sp = math.remainder(self.man_yaw_sp, 2.0 * math.pi)
        tilt = self.man_tilt_max
        q_tilt = qfrom_axis_angle(man.roll * tilt, -man.pitch * tilt, 0.0)
        self.qd = qmul(qfrom_euler(0.0, 0.0, self.man_yaw_sp), q_tilt)
        self.thrust_body[0] = self.thrust_body[1] = 0.0
        self.thrust_body[2] = -thr
        m = self.att_sp_msg
        m.timestamp = self.platform.hrt.absolute_time()
        w, x, y, z = self.qd
        m.roll_body = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
        m.pitch_body = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
        m.yaw_body = self.man_yaw_sp
        m.yaw_sp_move_rate = self.yawspeed_ff
        m.q_d[0], m.q_d[1], m.q_d[2], m.q_d[3] = w, x, y, z
        m.thrust_body[0], m.thrust_body[1], m.thrust_body[2] = 0.0, 0.0, -thr
        self.pub_att_sp.publish(m)
        self.sub_att_sp.update()   # our own publication is not an external setpoint
        self.have_sp = True

    # -- the loop ----------------------------------------------------------------------------

    def run(self) -> None:
        att = self.sub_att.update()
        if att is None:
            return
        self._poll()
        q: Quat = (float(att.q[0]), float(att.q[1]), float(att.q[2]), float(att.q[3]))
        t = int(att.timestamp_sample)
        dt = (t - self.last_att_us) * 1e-6
        self.last_att_us = t
        if dt <= 0.0 or dt > 0.1:
            dt = 0.004
        if not self.attitude_enabled:
            return  # offboard body rates: the rate setpoint is someone else's
        if self.stabilized:
            self._stabilized_setpoint(q, dt)
        if not self.have_sp:
            return
        e = so3_error(q, self.qd)
        self.err = e
        kr, kp, ky = self.gains
        ffr, ffp, ffy = yaw_feed_forward_body(q, self.yawspeed_ff)
        pr, pp, py = kr * e[0] + ffr, kp * e[1] + ffp, ky * e[2] + ffy
        now = self.platform.hrt.absolute_time()
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
        mr, mp, my = self.rate_max
        m = self.rates_msg
        m.timestamp = now
        m.roll = _clamp(pr + integ[0], mr)
        m.pitch = _clamp(pp + integ[1], mp)
        m.yaw = _clamp(py + integ[2], my)
        tb = self.thrust_body
        m.thrust_body[0], m.thrust_body[1], m.thrust_body[2] = tb[0], tb[1], tb[2]
        m.reset_integral = self.reset_integral
        self.pub_rates.publish(m)
        self.rates_published += 1

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
        m = self.rates_msg
        e, i = self.err, self.integ
        return [f"stabilized {self.stabilized} armed {self.armed} landed {self.landed}",
                f"{self.rates_published} rate setpoints published since start",
                f"attitude error (sin angle * axis) {e[0]:+.4f} {e[1]:+.4f} {e[2]:+.4f}",
                f"integrator r {i[0]:+.4f} p {i[1]:+.4f} y {i[2]:+.4f} rad/s",
                (f"rate sp r {m.roll:+.3f} p {m.pitch:+.3f} y {m.yaw:+.3f} "
                 f"thrust {-m.thrust_body[2]:.3f}")]
