"""Fixed-wing attitude controller (PX4's ``fw_att_control``): attitude -> surfaces and throttle.

Runs on every ``vehicle_attitude`` (the estimator's 250 Hz) on the rate controller's queue and
publishes ``actuator_controls_0`` (roll, pitch, yaw in -1..1, throttle 0..1: AETR after the
mixer) and the body rate setpoints it flew (``vehicle_rates_setpoint``, for the log).

What it does depends on ``vehicle_control_mode``, as PX4:

* **manual** (attitude and rate control off): the sticks go straight to the surfaces, scaled
  by ``FW_MAN_R_SC``/``FW_MAN_P_SC``/``FW_MAN_Y_SC`` (stick forward = nose down = negative
  elevator), throttle stick -1..1 to 0..1;
* **stabilized** (attitude control, manual, no altitude/position control): roll and pitch
  setpoints from the sticks up to ``FW_MAN_R_MAX``/``FW_MAN_P_MAX`` (plus the trim offsets
  ``FW_RSP_OFF``/``FW_PSP_OFF``), the yaw stick added to the rudder, throttle from the stick;
  the setpoint is published on ``vehicle_attitude_setpoint`` for the log;
* **acro** (rate control, manual, no attitude control): the sticks are body rates up to
  ``FW_ACRO_X/Y/Z_MAX``;
* otherwise the setpoint of ``fw_pos_control_l1`` (``vehicle_attitude_setpoint``: q_d, and
  ``thrust_body[0]`` as throttle; ``fw_control_yaw_wheel`` steers with the rudder on the
  runway, holding ``yaw_body``).

The laws are in :mod:`.ecl` (attitude to Euler rates, coordinated turn, body rates with airspeed
scaling). Airspeed comes from the ``airspeed`` topic while it is valid, else ``FW_AIRSPD_TRIM``
(:class:`~.airspeed_input.AirspeedInput`). Integrators are frozen on the ground and while
disarmed, and reset on landing. A VTOL (``vehicle_status.is_vtol``) is flown by this module in
fixed-wing mode and in both transitions (the surfaces' share, which vtol_att_control weighs in);
its controls go to ``actuator_controls_virtual_fw`` instead of group 0 (PX4's way), and its rate
setpoints are published only in fixed-wing flight (in a transition the multicopter's are the
rate loop's). A plain plane is always flown here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Final

from common.mathlib import constrain
from firmware.lib.l1 import wrap_pi
from firmware.modules.fw_att_control.airspeed_input import AirspeedInput
from firmware.modules.fw_att_control.ecl import (
    RateLoop,
    coordinated_yaw_rate,
    euler_rates_to_body,
)
from firmware.modules.fw_att_control.params import ATT_PARAMS, SHARED_PARAMS
from common.quaternion import q_from_euler, q_to_euler
from firmware.platform.module import WorkItemModule
from firmware.platform.params import ParamDef
from firmware.platform.uorb import Publication

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["PARAMS", "FwAttControlModule"]

_D2R: Final = math.pi / 180.0
_GW: Final = "FW Attitude Control"

#: ground steering with the rudder (PX4's wheel controller, reduced to a heading hold)
_WHEEL_PARAMS: Final[tuple[ParamDef, ...]] = (
    ParamDef("FW_WR_P", "FLOAT", 0.5, min=0.0, max=1.0, group=_GW, decimals=3,
             short="Wheel steering rate proportional gain", unit="%/rad/s"),
    ParamDef("FW_WR_FF", "FLOAT", 0.2, min=0.0, max=10.0, group=_GW, decimals=3,
             short="Wheel steering rate feed-forward", unit="%/rad/s"),
    ParamDef("FW_W_RMAX", "FLOAT", 30.0, min=0.0, max=90.0, group=_GW, decimals=1,
             short="Maximum wheel steering rate", unit="deg/s"),
)

PARAMS: Final[tuple[ParamDef, ...]] = SHARED_PARAMS + ATT_PARAMS + _WHEEL_PARAMS

MODE_NONE: Final = 0
MODE_MANUAL: Final = 1
MODE_STABILIZED: Final = 2
MODE_AUTO: Final = 3
MODE_ACRO: Final = 4


class FwAttControlModule(WorkItemModule):
    """``fw_att_control``: vehicle_attitude (+ setpoint or sticks) -> actuator_controls_0."""

    NAME = "fw_att_control"
    DESCRIPTION = "fixed-wing attitude controller"
    WQ = "wq:rate_ctrl"
    #: STM32F427: three trig-heavy loops and uORB copies, ~80 us per run
    CPU_COST_NS = 80_000
    #: at most 250 Hz, however fast the estimator publishes
    INTERVAL_LIMIT_US = 4_000
    PARAMS = PARAMS

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.roll_loop = RateLoop()
        self.pitch_loop = RateLoop()
        self.yaw_loop = RateLoop()
        self.mode = MODE_NONE
        self.armed = False
        self.landed = True
        self.fixed_wing = True
        self.vtol = False
        self.vtol_fw = False
        self.pub_virtual: Publication | None = None
        self.last_att_us = 0
        self.have_sp = False
        self.roll_sp = 0.0
        self.pitch_sp = 0.0
        self.yaw_sp = 0.0
        self.throttle_sp = 0.0
        self.wheel = False
        self.rates = (0.0, 0.0, 0.0)

    # -- life cycle --------------------------------------------------------------------------

    def _start(self) -> None:
        orb = self.platform.orb
        self.pub_ctl = self.advertise("actuator_controls_0")
        self.ctl_msg = orb.new("actuator_controls_0")
        self.pub_rates = self.advertise("vehicle_rates_setpoint")
        self.rates_msg = orb.new("vehicle_rates_setpoint")
        self.pub_att_sp = self.advertise("vehicle_attitude_setpoint")
        self.att_sp_msg = orb.new("vehicle_attitude_setpoint")
        item = self.work_item
        assert item is not None  # started: the module's work item exists
        self.sub_att = self.subscribe_callback(item, "vehicle_attitude",
                                               interval_us=self.INTERVAL_LIMIT_US)
        self.sub_rate = self.subscribe("vehicle_angular_velocity")
        self.sub_att_sp = self.subscribe("vehicle_attitude_setpoint")
        self.sub_mode = self.subscribe("vehicle_control_mode")
        self.sub_manual = self.subscribe("manual_control_setpoint")
        self.sub_status = self.subscribe("vehicle_status")
        self.sub_land = self.subscribe("vehicle_land_detected")
        self.sub_armed = self.subscribe("actuator_armed")
        self.sub_param = self.subscribe("parameter_update")
        self.airspeed = AirspeedInput(self)
        self.manual = orb.new("manual_control_setpoint")
        self.perf_loop = self.perf_alloc("count", "cycles")
        self._load_params()

    def _load_params(self) -> None:
        p = self.param
        self.roll_loop.set_gains(p("FW_RR_P"), p("FW_RR_I"), p("FW_RR_FF"), p("FW_RR_IMAX"))
        self.pitch_loop.set_gains(p("FW_PR_P"), p("FW_PR_I"), p("FW_PR_FF"), p("FW_PR_IMAX"))
        self.yaw_loop.set_gains(p("FW_YR_P"), p("FW_YR_I"), p("FW_YR_FF"), p("FW_YR_IMAX"))
        self.r_tc = max(float(p("FW_R_TC")), 0.05)
        self.p_tc = max(float(p("FW_P_TC")), 0.05)
        self.r_rmax = p("FW_R_RMAX") * _D2R
        self.p_rmax_pos = p("FW_P_RMAX_POS") * _D2R
        self.p_rmax_neg = p("FW_P_RMAX_NEG") * _D2R
        self.y_rmax = p("FW_Y_RMAX") * _D2R
        self.r_lim = p("FW_R_LIM") * _D2R
        self.p_lim_min = p("FW_P_LIM_MIN") * _D2R
        self.p_lim_max = p("FW_P_LIM_MAX") * _D2R
        self.rsp_off = p("FW_RSP_OFF") * _D2R
        self.psp_off = p("FW_PSP_OFF") * _D2R
        self.man_r_max = p("FW_MAN_R_MAX") * _D2R
        self.man_p_max = p("FW_MAN_P_MAX") * _D2R
        self.man_sc = (float(p("FW_MAN_R_SC")), float(p("FW_MAN_P_SC")),
                       float(p("FW_MAN_Y_SC")))
        self.v_min = float(p("FW_AIRSPD_MIN"))
        self.v_trim = float(p("FW_AIRSPD_TRIM"))
        self.v_max = max(float(p("FW_AIRSPD_MAX")), self.v_min)
        self.airspeed.use = int(p("FW_ARSP_MODE")) == 0
        self.acro_max = (p("FW_ACRO_X_MAX") * _D2R, p("FW_ACRO_Y_MAX") * _D2R,
                         p("FW_ACRO_Z_MAX") * _D2R)
        self.trim = (float(p("TRIM_ROLL")), float(p("TRIM_PITCH")), float(p("TRIM_YAW")))
        self.wr_p, self.wr_ff = float(p("FW_WR_P")), float(p("FW_WR_FF"))
        self.w_rmax = p("FW_W_RMAX") * _D2R

    # -- inputs ------------------------------------------------------------------------------

    def _poll(self) -> None:
        m = self.sub_mode.update()
        if m is not None:
            att, man = bool(m.flag_control_attitude_enabled), bool(m.flag_control_manual_enabled)
            if man and not att and not m.flag_control_rates_enabled:
                self.mode = MODE_MANUAL
            elif man and not att:
                self.mode = MODE_ACRO
            elif (att and man and not m.flag_control_altitude_enabled
                  and not m.flag_control_velocity_enabled
                  and not m.flag_control_position_enabled):
                self.mode = MODE_STABILIZED
            elif att:
                self.mode = MODE_AUTO
            else:
                self.mode = MODE_NONE
        m = self.sub_status.update()
        if m is not None:
            self.fixed_wing = (not m.is_vtol or m.in_transition_mode
                               or m.vehicle_type == m.VEHICLE_TYPE_FIXED_WING)
            self.vtol = bool(m.is_vtol)
            self.vtol_fw = self.vtol and not m.in_transition_mode and \
                m.vehicle_type == m.VEHICLE_TYPE_FIXED_WING
        m = self.sub_land.update()
        if m is not None:
            landed = bool(m.landed)
            if landed and not self.landed:
                self._reset_integrators()
            self.landed = landed
        m = self.sub_armed.update()
        if m is not None:
            self.armed = bool(m.armed)
        m = self.sub_manual.update()
        if m is not None:
            self.manual = m
        m = self.sub_rate.update()
        if m is not None:
            self.rates = (float(m.xyz[0]), float(m.xyz[1]), float(m.xyz[2]))
        if self.sub_param.updated():
            self.sub_param.update()
            self._load_params()
        if self.mode == MODE_AUTO:
            sp = self.sub_att_sp.update()
            if sp is not None:
                r, pt, y = q_to_euler(tuple(sp.q_d))  # type: ignore[arg-type]
                self.roll_sp, self.pitch_sp, self.yaw_sp = r, pt, y
                self.throttle_sp = float(sp.thrust_body[0])
                self.wheel = bool(sp.fw_control_yaw_wheel)
                self.have_sp = True

    def _reset_integrators(self) -> None:
        self.roll_loop.reset()
        self.pitch_loop.reset()
        self.yaw_loop.reset()

    def _stabilized_setpoint(self) -> None:
        man = self.manual
        self.roll_sp = man.roll * self.man_r_max + self.rsp_off
        self.pitch_sp = -man.pitch * self.man_p_max + self.psp_off
        self.throttle_sp = constrain(0.5 * (man.throttle + 1.0), 0.0, 1.0)
        self.wheel = False
        m = self.att_sp_msg
        m.timestamp = self.platform.hrt.absolute_time()
        m.roll_body, m.pitch_body, m.yaw_body = self.roll_sp, self.pitch_sp, math.nan
        w, x, y, z = q_from_euler(self.roll_sp, self.pitch_sp, 0.0)
        m.q_d[0], m.q_d[1], m.q_d[2], m.q_d[3] = w, x, y, z
        m.thrust_body[0], m.thrust_body[1], m.thrust_body[2] = self.throttle_sp, 0.0, 0.0
        self.pub_att_sp.publish(m)
        self.sub_att_sp.update()      # our own publication is not an external setpoint
        self.have_sp = True

    # -- the loop ----------------------------------------------------------------------------

    def _publish(self, r: float, p: float, y: float, t: float, t_sample: int) -> None:
        """Controls out, with the airframe's surface trims added (PX4's TRIM_*: the deflection
        level flight at trim airspeed needs, so the integrators start near zero)."""
        m = self.ctl_msg
        m.timestamp = self.platform.hrt.absolute_time()
        m.timestamp_sample = t_sample
        c = m.control
        tr, tp, ty = self.trim
        c[0], c[1], c[2] = constrain(r + tr, -1.0, 1.0), constrain(p + tp, -1.0, 1.0), \
            constrain(y + ty, -1.0, 1.0)
        c[3] = t if self.armed else 0.0
        if self.vtol:
            if self.pub_virtual is None:
                self.pub_virtual = self.advertise("actuator_controls_virtual_fw")
            self.pub_virtual.publish(m)
        else:
            self.pub_ctl.publish(m)
        self.perf_loop.count()

    def run(self) -> None:
        att = self.sub_att.update()
        if att is None:
            return
        self._poll()
        now = self.platform.hrt.absolute_time()
        self.airspeed.update(now)
        t = int(att.timestamp_sample)
        dt = (t - self.last_att_us) * 1e-6
        self.last_att_us = t
        if dt <= 0.0 or dt > 0.1:
            dt = 0.004
        if not self.fixed_wing or self.mode == MODE_NONE:
            return
        if self.mode == MODE_MANUAL:
            man = self.manual
            rs, ps, ys = self.man_sc
            self._reset_integrators()
            self._publish(constrain(man.roll * rs, -1.0, 1.0), constrain(-man.pitch * ps, -1.0, 1.0),
                          constrain(man.yaw * ys, -1.0, 1.0),
                          constrain(0.5 * (man.throttle + 1.0), 0.0, 1.0), t)
            return
        if self.mode == MODE_STABILIZED:
            self._stabilized_setpoint()
        roll, pitch, yaw = q_to_euler(tuple(att.q))  # type: ignore[arg-type]
        v = self.airspeed.indicated_m_s if self.airspeed.valid else self.v_trim
        v = constrain(v, self.v_min, self.v_max)
        scaler = self.v_trim / v
        if self.mode == MODE_ACRO:
            self._acro(scaler, dt, t)
            return
        if not self.have_sp:
            return
        # attitude loops: Euler rate setpoints
        roll_sp = constrain(self.roll_sp, -self.r_lim, self.r_lim)
        pitch_sp = constrain(self.pitch_sp, self.p_lim_min, self.p_lim_max)
        roll_dot = constrain((roll_sp - roll) / self.r_tc, -self.r_rmax, self.r_rmax)
        pitch_dot = constrain((pitch_sp - pitch) / self.p_tc, -self.p_rmax_neg, self.p_rmax_pos)
        # the turn rate of a bank is the true airspeed's (the scaler above is the dynamic
        # pressure's, i.e. the indicated airspeed's)
        v_true = (max(self.airspeed.true_m_s, self.v_min) if self.airspeed.valid else v)
        yaw_dot = constrain(coordinated_yaw_rate(roll, pitch, v_true), -self.y_rmax, self.y_rmax)
        p_sp, q_sp, r_sp = euler_rates_to_body(roll, pitch, roll_dot, pitch_dot, yaw_dot)
        # rate loops
        integrate = self.armed and not self.landed
        p, q, r = self.rates
        u_r = self.roll_loop.control(p_sp, p, scaler, dt, integrate)
        u_p = self.pitch_loop.control(q_sp, q, scaler, dt, integrate)
        if self.wheel:
            # on the runway: hold the heading with the rudder (and the steered wheel)
            w_sp = constrain(wrap_pi(self.yaw_sp - yaw) / self.r_tc, -self.w_rmax, self.w_rmax)
            u_y = constrain(self.wr_ff * w_sp + self.wr_p * (w_sp - r), -1.0, 1.0)
            self.yaw_loop.reset()
        else:
            u_y = self.yaw_loop.control(r_sp, r, scaler, dt, integrate)
        if self.mode == MODE_STABILIZED:
            u_y = constrain(u_y + self.manual.yaw * self.man_sc[2], -1.0, 1.0)
        if not self.armed:
            self._reset_integrators()
        self._publish(u_r, u_p, u_y, constrain(self.throttle_sp, 0.0, 1.0), t)
        m = self.rates_msg
        m.timestamp = now
        m.roll, m.pitch, m.yaw = p_sp, q_sp, r_sp
        m.thrust_body[0], m.thrust_body[1], m.thrust_body[2] = self.throttle_sp, 0.0, 0.0
        if not self.vtol or self.vtol_fw:
            self.pub_rates.publish(m)

    def _acro(self, scaler: float, dt: float, t_sample: int) -> None:
        """Acro: the sticks are body rate setpoints (FW_ACRO_*_MAX at full stick)."""
        man = self.manual
        xm, ym, zm = self.acro_max
        p_sp, q_sp, r_sp = man.roll * xm, -man.pitch * ym, man.yaw * zm
        integrate = self.armed and not self.landed
        p, q, r = self.rates
        self._publish(self.roll_loop.control(p_sp, p, scaler, dt, integrate),
                      self.pitch_loop.control(q_sp, q, scaler, dt, integrate),
                      self.yaw_loop.control(r_sp, r, scaler, dt, integrate),
                      constrain(0.5 * (man.throttle + 1.0), 0.0, 1.0), t_sample)
        m = self.rates_msg
        m.timestamp = self.platform.hrt.absolute_time()
        m.roll, m.pitch, m.yaw = p_sp, q_sp, r_sp
        self.pub_rates.publish(m)

    def status_lines(self) -> list[str]:
        c = self.ctl_msg.control
        names = {MODE_NONE: "none", MODE_MANUAL: "manual", MODE_STABILIZED: "stabilized",
                 MODE_AUTO: "auto", MODE_ACRO: "acro"}
        asp = (f"{self.airspeed.indicated_m_s:.1f} m/s" if self.airspeed.valid
               else f"invalid (trim {self.v_trim:.1f} m/s)")
        return [f"mode {names.get(self.mode, '?')} armed {self.armed} landed {self.landed} "
                f"airspeed {asp}",
                f"controls r {c[0]:+.3f} p {c[1]:+.3f} y {c[2]:+.3f} t {c[3]:.3f}",
                (f"integrators r {self.roll_loop.integrator:+.4f} "
                 f"p {self.pitch_loop.integrator:+.4f} y {self.yaw_loop.integrator:+.4f}")]
