"""Multicopter body-rate controller: PID per axis, run on every gyro sample.

This is the innermost loop of the cascade and the only one that sees the gyro at its full rate
(vehicle_angular_velocity, ~1 kHz from the MPU6000), so the work per sample is kept to plain
float arithmetic on attributes: no numpy, no lists built, no allocation beyond the published
snapshot the uORB broker takes.

Control law per axis (PX4's parallel form with a common gain K):

    u = K * (P * e + I_state - D * d(rate)/dt) + FF * rate_sp,    e = rate_sp - rate

* D acts on the measurement (not the error), so a setpoint step gives no derivative kick; the
  derivative is low-pass filtered (``MC_DTERM_CUTOFF``) because the raw difference of 1 kHz gyro
  samples is mostly noise.
* The integrator is clamped to ``MC_xR_INT_LIM`` and is frozen on an axis while the mixer
  saturates in the direction the integrator would push (anti-windup). The IO's mixer is not
  visible from here (2014 IO: the FMU sends controls only), so saturation is predicted with the
  quad-X mixing of the controls just computed: a motor command outside [0, 1] means saturated.
* Integrators are reset while landed or disarmed, so ground contact never winds them up.

Rate setpoints come from ``vehicle_rates_setpoint`` (the attitude controller), or in acro mode
from the sticks (``MC_ACRO_*_MAX``). Output: ``actuator_controls_0`` (roll, pitch, yaw in
[-1, 1], throttle in [0, 1] = the magnitude of the body z thrust).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Final

from firmware.platform.module import WorkItemModule
from firmware.platform.params import ParamDef

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
        self._reset_state()

    def _reset_state(self) -> None:
        self.ir = self.ip = self.iy = 0.0          # integrator states (control units)
        self.dr = self.dp = self.dy = 0.0          # filtered rate derivatives
        self.lr = self.lp = self.ly = 0.0          # previous rates
        self.sr = self.sp = self.sy = 0.0          # rate setpoint
        self.thrust = 0.0
        self.last_sample_us = 0
        self.armed = False
        self.landed = True
        self.acro = False
        self.saturated = False

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
        self.perf_loop = self.perf_alloc("count", "cycles")
        self._load_params()

    def _load_params(self) -> None:
        """Copy the parameters into attributes (the hot path never touches the param table)."""
        p = self.param
        kr, kp, ky = p("MC_ROLLRATE_K"), p("MC_PITCHRATE_K"), p("MC_YAWRATE_K")
        self.kpr, self.kip_r, self.kdr = kr * p("MC_ROLLRATE_P"), kr * p("MC_ROLLRATE_I"), \
            kr * p("MC_ROLLRATE_D")
        self.kpp, self.kip_p, self.kdp = kp * p("MC_PITCHRATE_P"), kp * p("MC_PITCHRATE_I"), \
            kp * p("MC_PITCHRATE_D")
        self.kpy, self.kip_y, self.kdy = ky * p("MC_YAWRATE_P"), ky * p("MC_YAWRATE_I"), \
            ky * p("MC_YAWRATE_D")
        self.ffr, self.ffp, self.ffy = (p("MC_ROLLRATE_FF"), p("MC_PITCHRATE_FF"),
                                        p("MC_YAWRATE_FF"))
        self.limr, self.limp, self.limy = p("MC_RR_INT_LIM"), p("MC_PR_INT_LIM"), \
            p("MC_YR_INT_LIM")
        self.dcut_hz = float(p("MC_DTERM_CUTOFF"))
        d2r = math.pi / 180.0
        self.acro_max = (p("MC_ACRO_R_MAX") * d2r, p("MC_ACRO_P_MAX") * d2r,
                         p("MC_ACRO_Y_MAX") * d2r)

    # -- the loop ----------------------------------------------------------------------------

    def _update_slow_inputs(self) -> None:
        """Arming, landing, mode and setpoint: cheap generation checks on every sample."""
        m = self.sub_armed.update()
        if m is not None:
            armed = bool(m.armed)
            if armed != self.armed:
                self._reset_integrals()
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
        if self.acro:
            ms = self.sub_manual.update()
            if ms is not None:
                ar, ap, ay = self.acro_max
                self.sr, self.sp, self.sy = ms.roll * ar, -ms.pitch * ap, ms.yaw * ay
                self.thrust = min(max(0.5 * (ms.throttle + 1.0), 0.0), 1.0)
        else:
            sp = self.sub_sp.update()
            if sp is not None:
                self.sr, self.sp, self.sy = sp.roll, sp.pitch, sp.yaw
                t = -sp.thrust_body[2]
                self.thrust = 0.0 if t < 0.0 else (min(t, 1.0))
                if sp.reset_integral:
                    self._reset_integrals()

    def _reset_integrals(self) -> None:
        self.ir = self.ip = self.iy = 0.0

    def run(self) -> None:
        g = self.sub_gyro.update()
        if g is None:
            return
        self._update_slow_inputs()
        wr, wp, wy = g.xyz
        t = g.timestamp_sample
        dt = (t - self.last_sample_us) * 1e-6
        self.last_sample_us = t
        if dt <= 0.0002 or dt > 0.02:   # first sample or a gap: no derivative this time
            dt = 0.001
            self.lr, self.lp, self.ly = wr, wp, wy
        # D-term: filtered derivative of the measured rate
        fc = self.dcut_hz
        a = 1.0 if fc <= 0.0 else dt / (dt + 1.0 / (6.283185307179586 * fc))
        inv = 1.0 / dt
        self.dr += a * ((wr - self.lr) * inv - self.dr)
        self.dp += a * ((wp - self.lp) * inv - self.dp)
        self.dy += a * ((wy - self.ly) * inv - self.dy)
        self.lr, self.lp, self.ly = wr, wp, wy

        er = self.sr - wr
        ep = self.sp - wp
        ey = self.sy - wy
        ur = self.kpr * er + self.ir - self.kdr * self.dr + self.ffr * self.sr
        up = self.kpp * ep + self.ip - self.kdp * self.dp + self.ffp * self.sp
        uy = self.kpy * ey + self.iy - self.kdy * self.dy + self.ffy * self.sy
        ur = -1.0 if ur < -1.0 else (min(ur, 1.0))
        up = -1.0 if up < -1.0 else (min(up, 1.0))
        uy = -1.0 if uy < -1.0 else (min(uy, 1.0))
        thr = self.thrust

        if self.armed and not self.landed:
            # Predict the quad-X mixer: with x = S*(pitch - roll) and y = S*(pitch + roll) the
            # motors are thr -x +yaw, thr +x +yaw, thr +y -yaw, thr -y -yaw.
            x = _S * (up - ur)
            y = _S * (up + ur)
            ax = x if x > 0.0 else -x
            ay = y if y > 0.0 else -y
            rp = max(ay, ax)
            sat_rp = thr - rp < 0.0 or thr + rp > 1.0
            sat_y = sat_rp or thr - rp - (uy if uy > 0.0 else -uy) < 0.0 \
                or thr + rp + (uy if uy > 0.0 else -uy) > 1.0
            self.saturated = sat_y
            # Integrate unless saturated in the direction of the integration.
            v = self.ir + self.kip_r * er * dt
            if not (sat_rp and er * ur > 0.0):
                lim = self.limr
                self.ir = -lim if v < -lim else (min(v, lim))
            v = self.ip + self.kip_p * ep * dt
            if not (sat_rp and ep * up > 0.0):
                lim = self.limp
                self.ip = -lim if v < -lim else (min(v, lim))
            v = self.iy + self.kip_y * ey * dt
            if not (sat_y and ey * uy > 0.0):
                lim = self.limy
                self.iy = -lim if v < -lim else (min(v, lim))
        else:
            self.ir = self.ip = self.iy = 0.0

        m = self.msg
        m.timestamp = self.platform.hrt.absolute_time()
        m.timestamp_sample = t
        c = m.control
        if self.armed:
            c[0] = ur
            c[1] = up
            c[2] = uy
            c[3] = thr
        else:
            c[0] = c[1] = c[2] = c[3] = 0.0
        self.pub.publish(m)
        self.perf_loop.count()

    def status_lines(self) -> list[str]:
        c = self.msg.control
        return [f"armed {self.armed} landed {self.landed} acro {self.acro}",
                f"controls r {c[0]:+.3f} p {c[1]:+.3f} y {c[2]:+.3f} t {c[3]:.3f}",
                f"integrators r {self.ir:+.4f} p {self.ip:+.4f} y {self.iy:+.4f}"]
