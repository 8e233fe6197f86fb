"""Multicopter body-rate controller (PX4's ``MulticopterRateControl``), run on every gyro sample.

This is the innermost loop of the cascade and the only one that sees the gyro at its control
rate (vehicle_angular_velocity, IMU_GYRO_RATEMAX). As in PX4 the control law lives in the
:class:`~firmware.lib.rate_control.RateControl` library (PID + FF on 3-vectors, integrator
limits, anti-windup); this module is the uORB glue around it:

* gains from ``MC_*RATE_P/I/D/FF`` times the common ``MC_*RATE_K`` (PX4's parallel form with a
  common gain), integrator limits from ``MC_*R_INT_LIM``;
* the D term acts on the derivative of the measured rate, low-pass filtered here
  (``MC_DTERM_CUTOFF``) because the raw difference of gyro samples is mostly noise;
* anti-windup needs the mixer's saturation. The IO's mixer is not visible from here (2014 IO:
  the FMU sends controls only), so saturation is predicted with the quad-X mixing of the
  controls just computed (a motor command outside [0, 1] means saturated) and handed to the
  library between its torque and integral halves (see its docstring);
* integrators are reset while landed or disarmed, so ground contact never winds them up.

Rate setpoints come from ``vehicle_rates_setpoint`` (the attitude controller), or in acro mode
from the sticks (``MC_ACRO_*_MAX``). Output: ``actuator_controls_0`` (roll, pitch, yaw in
[-1, 1], throttle in [0, 1] = the magnitude of the body z thrust).

A VTOL (``vehicle_status.is_vtol``) publishes the same controls as
``actuator_controls_virtual_mc`` instead, which vtol_att_control weighs into group 0 (PX4's
way); it keeps publishing in fixed-wing flight, where vtol_att_control runs on them, but with
zero controls and its integrators reset (the rotors are off, nothing must wind up).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Final

from firmware.lib.rate_control import RateControl
from firmware.lib.vector3 import Vector3
from firmware.platform.module import WorkItemModule
from firmware.platform.params import ParamDef
from firmware.platform.uorb import Publication

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["PARAMS", "McRateControlModule"]

_G: Final = "Multicopter Rate Control"


def _p(name: str, default: float, lo: float, hi: float, short: str, unit: str = "",
       decimals: int = 3) -> ParamDef:
    return ParamDef(name, "FLOAT", default, min=lo, max=hi, unit=unit, group=_G, short=short,
                    decimals=decimals)


#: PX4-like defaults; the F450 airframe overrides them (see tests/flight F450_PARAMS).
PARAMS: tuple[ParamDef, ...] = (
    _p("MC_ROLLRATE_P", 0.15, 0.01, 0.5, "Roll rate P gain"),
    _p("MC_ROLLRATE_I", 0.2, 0.0, 10.0, "Roll rate I gain"),
    _p("MC_ROLLRATE_D", 0.003, 0.0, 0.1, "Roll rate D gain", decimals=4),
    _p("MC_ROLLRATE_FF", 0.0, 0.0, 1.0, "Roll rate feed-forward"),
    _p("MC_ROLLRATE_K", 1.0, 0.01, 5.0, "Roll rate controller gain"),
    _p("MC_RR_INT_LIM", 0.3, 0.0, 1.0, "Roll rate integrator limit"),
    _p("MC_PITCHRATE_P", 0.15, 0.01, 0.6, "Pitch rate P gain"),
    _p("MC_PITCHRATE_I", 0.2, 0.0, 10.0, "Pitch rate I gain"),
    _p("MC_PITCHRATE_D", 0.003, 0.0, 0.1, "Pitch rate D gain", decimals=4),
    _p("MC_PITCHRATE_FF", 0.0, 0.0, 1.0, "Pitch rate feed-forward"),
    _p("MC_PITCHRATE_K", 1.0, 0.01, 5.0, "Pitch rate controller gain"),
    _p("MC_PR_INT_LIM", 0.3, 0.0, 1.0, "Pitch rate integrator limit"),
    _p("MC_YAWRATE_P", 0.2, 0.0, 0.6, "Yaw rate P gain"),
    _p("MC_YAWRATE_I", 0.1, 0.0, 10.0, "Yaw rate I gain"),
    _p("MC_YAWRATE_D", 0.0, 0.0, 0.1, "Yaw rate D gain", decimals=4),
    _p("MC_YAWRATE_FF", 0.0, 0.0, 1.0, "Yaw rate feed-forward"),
    _p("MC_YAWRATE_K", 1.0, 0.01, 5.0, "Yaw rate controller gain"),
    _p("MC_YR_INT_LIM", 0.3, 0.0, 1.0, "Yaw rate integrator limit"),
    _p("MC_DTERM_CUTOFF", 30.0, 0.0, 1000.0, "Cutoff of the D-term low-pass (0: none)", "Hz",
       1),
    _p("MC_ACRO_R_MAX", 720.0, 0.0, 1800.0, "Max acro roll rate", "deg/s", 1),
    _p("MC_ACRO_P_MAX", 720.0, 0.0, 1800.0, "Max acro pitch rate", "deg/s", 1),
    _p("MC_ACRO_Y_MAX", 540.0, 0.0, 1800.0, "Max acro yaw rate", "deg/s", 1),
)

#: quad X mixer factors (roll, pitch, yaw) per motor, used only to predict saturation
_S: Final = 0.707107


class McRateControlModule(WorkItemModule):
    """``mc_rate_control``: vehicle_angular_velocity -> actuator_controls_0 at the gyro rate."""

    NAME = "mc_rate_control"
    DESCRIPTION = "multicopter rate controller"
    WQ = "wq:rate_ctrl"
    #: STM32F427 @168 MHz, float PID x3 with filters, uORB copies: ~60 us per run
    CPU_COST_NS = 60_000
    PARAMS = PARAMS

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.rate_control = RateControl()
        self._reset_state()

    def _reset_state(self) -> None:
        self.rate_control.reset_integral()
        self.rates_sp = Vector3()                  # rad/s
        self.rate_prev = Vector3()                 # the last measured rate, rad/s
        self.rate_deriv = Vector3()                # its filtered derivative, rad/s^2
        self.thrust = 0.0
        self.last_sample_us = 0
        self.armed = False
        self.landed = True
        self.acro = False
        self.saturated = False
        self.vtol = False
        self.vtol_fw = False

    # -- life cycle --------------------------------------------------------------------------

    def _start(self) -> None:
        orb = self.platform.orb
        self.pub = self.advertise("actuator_controls_0")
        self.msg = orb.new("actuator_controls_0")
        item = self.work_item
        assert item is not None  # started: the module's work item exists
        self.sub_gyro = self.subscribe_callback(item, "vehicle_angular_velocity")
        self.sub_sp = self.subscribe("vehicle_rates_setpoint")
        self.sub_armed = self.subscribe("actuator_armed")
        self.sub_land = self.subscribe("vehicle_land_detected")
        self.sub_mode = self.subscribe("vehicle_control_mode")
        self.sub_manual = self.subscribe("manual_control_setpoint")
        self.sub_param = self.subscribe("parameter_update")
        self.sub_status = self.subscribe("vehicle_status")
        self.pub_virtual: Publication | None = None   # advertised when the vehicle is a VTOL
        self.perf_loop = self.perf_alloc("count", "cycles")
        self._load_params()

    def _load_params(self) -> None:
        """Hand the gains to the library (the hot path never touches the param table)."""
        p = self.param
        k = Vector3(p("MC_ROLLRATE_K"), p("MC_PITCHRATE_K"), p("MC_YAWRATE_K"))
        rc = self.rate_control
        rc.set_pid_gains(
            k.emult(Vector3(p("MC_ROLLRATE_P"), p("MC_PITCHRATE_P"), p("MC_YAWRATE_P"))),
            k.emult(Vector3(p("MC_ROLLRATE_I"), p("MC_PITCHRATE_I"), p("MC_YAWRATE_I"))),
            k.emult(Vector3(p("MC_ROLLRATE_D"), p("MC_PITCHRATE_D"), p("MC_YAWRATE_D"))))
        rc.set_feed_forward_gain(Vector3(p("MC_ROLLRATE_FF"), p("MC_PITCHRATE_FF"),
                                         p("MC_YAWRATE_FF")))
        rc.set_integrator_limit(Vector3(p("MC_RR_INT_LIM"), p("MC_PR_INT_LIM"),
                                        p("MC_YR_INT_LIM")))
        self.dcut_hz = float(p("MC_DTERM_CUTOFF"))
        d2r = math.pi / 180.0
        self.acro_max = Vector3(p("MC_ACRO_R_MAX") * d2r, p("MC_ACRO_P_MAX") * d2r,
                                p("MC_ACRO_Y_MAX") * d2r)

    # -- the loop ----------------------------------------------------------------------------

    def _update_slow_inputs(self) -> None:
        """Arming, landing, mode and setpoint: cheap generation checks on every sample."""
        m = self.sub_armed.update()
        if m is not None:
            armed = bool(m.armed)
            if armed != self.armed:
                self.rate_control.reset_integral()
            self.armed = armed
        m = self.sub_land.update()
        if m is not None:
            self.landed = bool(m.landed)
        m = self.sub_mode.update()
        if m is not None:
            self.acro = (m.flag_control_rates_enabled and not m.flag_control_attitude_enabled
                         and m.flag_control_manual_enabled)
        if self.sub_param.updated():
            self.sub_param.update()
            self._load_params()
        m = self.sub_status.update()
        if m is not None:
            self.vtol = bool(m.is_vtol)
            self.vtol_fw = self.vtol and not m.in_transition_mode and \
                m.vehicle_type == m.VEHICLE_TYPE_FIXED_WING
        if self.acro:
            ms = self.sub_manual.update()
            if ms is not None:
                self.rates_sp = Vector3(ms.roll, -ms.pitch, ms.yaw).emult(self.acro_max)
                self.thrust = min(max(0.5 * (ms.throttle + 1.0), 0.0), 1.0)
        else:
            sp = self.sub_sp.update()
            if sp is not None:
                self.rates_sp = Vector3(sp.roll, sp.pitch, sp.yaw)
                t = -sp.thrust_body[2]
                self.thrust = 0.0 if t < 0.0 else (min(t, 1.0))
                if sp.reset_integral:
                    self.rate_control.reset_integral()

    def _rate_derivative(self, rate: Vector3, dt: float) -> Vector3:
        """The D term's input: the measured rate's derivative through MC_DTERM_CUTOFF."""
        fc = self.dcut_hz
        a = 1.0 if fc <= 0.0 else dt / (dt + 1.0 / (6.283185307179586 * fc))
        d = self.rate_deriv
        d = d + ((rate - self.rate_prev) * (1.0 / dt) - d) * a
        self.rate_deriv = d
        self.rate_prev = rate
        return d

    def _predict_saturation(self, u: Vector3, thr: float) -> None:
        """Tell the library which torque directions the quad-X mixer cannot give now.

        With x = S*(pitch - roll) and y = S*(pitch + roll) the motors are thr -x +yaw,
        thr +x +yaw, thr +y -yaw, thr -y -yaw: roll and pitch saturate when a motor leaves
        [0, 1] without yaw, yaw also when it does with yaw. An axis is saturated in the
        direction of its command (more of the same cannot be had)."""
        x = _S * (u.y - u.x)
        y = _S * (u.y + u.x)
        ax = x if x > 0.0 else -x
        ay = y if y > 0.0 else -y
        rp = max(ay, ax)
        sat_rp = thr - rp < 0.0 or thr + rp > 1.0
        ayaw = u.z if u.z > 0.0 else -u.z
        sat_y = sat_rp or thr - rp - ayaw < 0.0 or thr + rp + ayaw > 1.0
        self.saturated = sat_y
        self.rate_control.set_saturation_status(
            (sat_rp and u.x > 0.0, sat_rp and u.y > 0.0, sat_y and u.z > 0.0),
            (sat_rp and u.x < 0.0, sat_rp and u.y < 0.0, sat_y and u.z < 0.0))

    def run(self) -> None:
        g = self.sub_gyro.update()
        if g is None:
            return
        self._update_slow_inputs()
        wr, wp, wy = g.xyz
        rate = Vector3(wr, wp, wy)
        t = g.timestamp_sample
        dt = (t - self.last_sample_us) * 1e-6
        self.last_sample_us = t
        if dt <= 0.0002 or dt > 0.02:   # first sample or a gap: no derivative this time
            dt = 0.001
            self.rate_prev = rate
        accel = self._rate_derivative(rate, dt)
        rc = self.rate_control
        u = rc.torque(rate, self.rates_sp, accel).constrain(-1.0, 1.0)
        thr = self.thrust
        if self.vtol_fw:
            u = Vector3()
            thr = 0.0
            rc.reset_integral()
        elif self.armed and not self.landed:
            self._predict_saturation(u, thr)
            rc.update_integral(dt)
        else:
            rc.reset_integral()

        m = self.msg
        m.timestamp = self.platform.hrt.absolute_time()
        m.timestamp_sample = t
        c = m.control
        if self.armed:
            c[0] = u.x
            c[1] = u.y
            c[2] = u.z
            c[3] = thr
        else:
            c[0] = c[1] = c[2] = c[3] = 0.0
        if self.vtol:
            if self.pub_virtual is None:
                self.pub_virtual = self.advertise("actuator_controls_virtual_mc")
            self.pub_virtual.publish(m)
        else:
            self.pub.publish(m)
        self.perf_loop.count()

    def status_lines(self) -> list[str]:
        c = self.msg.control
        i = self.rate_control.rate_int
        return [f"armed {self.armed} landed {self.landed} acro {self.acro}",
                f"controls r {c[0]:+.3f} p {c[1]:+.3f} y {c[2]:+.3f} t {c[3]:.3f}",
                f"integrators r {i.x:+.4f} p {i.y:+.4f} y {i.z:+.4f}"]
