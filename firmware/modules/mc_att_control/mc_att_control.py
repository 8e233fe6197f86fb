"""Multicopter attitude controller: quaternion error -> body rate setpoint.

Control law (reduced attitude first, as PX4 does it; written here from the published idea):

1. The *reduced* desired attitude turns the current body z axis onto the desired one by the
   shortest rotation, without touching the heading. This is the part a multicopter can achieve
   quickly (roll/pitch torque is large, yaw torque from rotor drag is ~8x smaller on the F450).
2. The remaining rotation from the reduced to the full desired attitude is a pure rotation about
   the desired z axis (the heading error). Only the fraction ``MC_YAW_WEIGHT`` of that angle is
   added back, so a large heading error never steals roll/pitch authority.
3. The error quaternion ``qe = q^-1 * q_d`` gives the rate setpoint ``2 sign(qe_w) qe_xyz``
   scaled by ``MC_ROLL_P``, ``MC_PITCH_P`` and ``MC_YAW_P / MC_YAW_WEIGHT`` (the division keeps
   the small-error yaw gain equal to ``MC_YAW_P``), plus the yaw rate feed-forward, limited per
   axis by ``MC_*RATE_MAX``.

Setpoint source: ``vehicle_attitude_setpoint`` (the position controller), or in stabilized mode
(manual, attitude control without climb rate control) the sticks: tilt up to
``MPC_MAN_TILT_MAX``, yaw rate up to ``MPC_MAN_Y_MAX``, throttle through ``MPC_THR_CURVE``.
Runs on ``vehicle_attitude`` updates, at most every ``MC_ATT_INTERVAL`` (250 Hz).

It can replace another attitude controller in flight (``mc_att_control_so3``, issue 23): its
first output continues from the last rate setpoint the other one published (``handover.py``),
and the manual heading setpoint from the last attitude setpoint, so the swap has no step.
Started, it records itself in ``MC_ATT_IMPL`` (``mc_att_select``), so that the parameter always
names the running attitude controller.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, ClassVar, Final

from firmware.modules.mc_att_control.handover import Handover, other_att_controller
from common.quaternion import (
    Quat,
    q_conj,
    q_from_rotvec,
    q_from_euler,
    q_mul,
    q_yaw,
)
from mypy_extensions import mypyc_attr

from firmware.platform.module import ModuleError, WorkItemModule
from firmware.platform.params import ParamDef

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["PARAMS", "McAttControlModule", "attitude_error_rates"]

_G: Final = "Multicopter Attitude Control"
_GM: Final = "Multicopter Position Control"
_D2R: Final = math.pi / 180.0


def _p(name: str, default: float, lo: float, hi: float, short: str, unit: str = "",
       group: str = _G, decimals: int = 2) -> ParamDef:
    return ParamDef(name, "FLOAT", default, min=lo, max=hi, unit=unit, group=group, short=short,
                    decimals=decimals)


PARAMS: tuple[ParamDef, ...] = (
    _p("MC_ROLL_P", 6.5, 0.0, 12.0, "Roll P gain", "1/s"),
    _p("MC_PITCH_P", 6.5, 0.0, 12.0, "Pitch P gain", "1/s"),
    _p("MC_YAW_P", 2.8, 0.0, 5.0, "Yaw P gain", "1/s"),
    _p("MC_YAW_WEIGHT", 0.4, 0.0, 1.0, "Yaw weight in the combined attitude error"),
    _p("MC_ROLLRATE_MAX", 220.0, 0.0, 1800.0, "Max roll rate", "deg/s", decimals=1),
    _p("MC_PITCHRATE_MAX", 220.0, 0.0, 1800.0, "Max pitch rate", "deg/s", decimals=1),
    _p("MC_YAWRATE_MAX", 200.0, 0.0, 1800.0, "Max yaw rate", "deg/s", decimals=1),
    _p("MPC_MAN_TILT_MAX", 35.0, 0.0, 90.0, "Max tilt in manual and altitude modes", "deg",
       _GM, 1),
    _p("MPC_MAN_Y_MAX", 150.0, 0.0, 400.0, "Max manual yaw rate", "deg/s", _GM, 1),
    _p("MPC_MANTHR_MIN", 0.08, 0.0, 1.0, "Minimum manual thrust", "", _GM),
    ParamDef("MPC_THR_CURVE", "INT32", 0, min=0, max=1, group=_GM,
             short="Thrust curve in manual mode",
             values={0: "Rescale to hover thrust (mid stick = hover)", 1: "No rescale"}),
)


def attitude_error_rates(q: Quat, qd: Quat, yaw_w: float) -> tuple[float, float, float]:
    """The body rotation vector (rad) from q toward qd, with only ``yaw_w`` of the heading error.

    Pure function of the two attitudes so it can be tested on its own.
    """
    w, x, y, z = q
    # body z axes in NED (third columns)
    ezx, ezy, ezz = 2.0 * (x * z + w * y), 2.0 * (y * z - w * x), w * w - x * x - y * y + z * z
    dw, dx, dy, dz = qd
    dzx, dzy, dzz = (2.0 * (dx * dz + dw * dy), 2.0 * (dy * dz - dw * dx),
                     dw * dw - dx * dx - dy * dy + dz * dz)
    dot = ezx * dzx + ezy * dzy + ezz * dzz
    if dot > -0.999:
        # shortest rotation ez -> ezd (world frame): q = normalize(1 + dot, ez x ezd)
        cx = ezy * dzz - ezz * dzy
        cy = ezz * dzx - ezx * dzz
        cz = ezx * dzy - ezy * dzx
        rw = 1.0 + dot
        n = math.sqrt(rw * rw + cx * cx + cy * cy + cz * cz)
        qr = (rw / n, cx / n, cy / n, cz / n)
        qd_red = q_mul(qr, q)
        # heading part: qd = qd_red * q_mix, q_mix a rotation about z
        mw, _mx, _my, mz = q_mul(q_conj(qd_red), qd)
        if mw < 0.0:
            mw, mz = -mw, -mz
        mw = -1.0 if mw < -1.0 else (min(mw, 1.0))
        mz = -1.0 if mz < -1.0 else (min(mz, 1.0))
        ang_w = yaw_w * math.acos(mw)
        ang_z = yaw_w * math.asin(mz)
        qd_final = q_mul(qd_red, (math.cos(ang_w), 0.0, 0.0, math.sin(ang_z)))
    else:  # upside down relative to the setpoint: no reduced attitude exists, go directly
        qd_final = qd
    ew, ex, ey, ez = q_mul(q_conj(q), qd_final)
    s = 2.0 if ew >= 0.0 else -2.0
    return s * ex, s * ey, s * ez


@mypyc_attr(allow_interpreted_subclasses=True)
class McAttControlModule(WorkItemModule):
    """``mc_att_control``: vehicle_attitude (+ setpoint or sticks) -> vehicle_rates_setpoint."""

    NAME = "mc_att_control"
    DESCRIPTION = "multicopter attitude controller"
    WQ = "wq:rate_ctrl"
    #: STM32F427: quaternion products and trig, ~100 us per run
    CPU_COST_NS = 100_000
    #: at most 250 Hz, however fast the estimator publishes
    INTERVAL_LIMIT_US: ClassVar[int] = 4_000
    PARAMS = PARAMS
    #: this law's number in MC_ATT_IMPL (mc_att_select); a ClassVar so that a law derived in
    #: pure Python (mc_att_control_so3) overrides it in the compiled tier too
    ATT_IMPL: ClassVar[int] = 0

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.qd: Quat = (1.0, 0.0, 0.0, 0.0)
        self.thrust_body = [0.0, 0.0, 0.0]
        self.yawspeed_ff = 0.0
        self.reset_integral = False
        self.stabilized = False
        #: vehicle_control_mode.flag_control_attitude_enabled: off when an offboard companion
        #: sends body rates, which must then reach the rate controller unchanged (as PX4)
        self.attitude_enabled = True
        self.armed = False
        self.landed = True
        self.man_yaw_sp = 0.0
        self.last_att_us = 0
        self.have_sp = False
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
        assert item is not None  # started: the module's work item exists
        self.sub_att = self.subscribe_callback(item, "vehicle_attitude",
                                               interval_us=self.INTERVAL_LIMIT_US)
        self.sub_att_sp = self.subscribe("vehicle_attitude_setpoint")
        self.sub_mode = self.subscribe("vehicle_control_mode")
        self.sub_manual = self.subscribe("manual_control_setpoint")
        self.sub_land = self.subscribe("vehicle_land_detected")
        self.sub_armed = self.subscribe("actuator_armed")
        self.sub_hover = self.subscribe("hover_thrust_estimate")
        self.sub_param = self.subscribe("parameter_update")
        self.sub_status = self.subscribe("vehicle_status")
        self.vtol_fw = False   # a VTOL flying as a plane: fw_att_control's turn
        self.manual = orb.new("manual_control_setpoint")
        params = self.system.params
        hover = params.get("MPC_THR_HOVER", 0.5) if params is not None else 0.5
        self.hover_thrust = float(hover if hover is not None else 0.5)
        self._load_params()
        # bumpless start in flight: the heading setpoint the previous controller held (NaN:
        # none yet, the first run takes the current heading)
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
        self.yaw_w = min(max(float(p("MC_YAW_WEIGHT")), 0.0), 1.0)
        yaw_gain = p("MC_YAW_P") / self.yaw_w if self.yaw_w > 0.01 else 0.0
        self.gains = (float(p("MC_ROLL_P")), float(p("MC_PITCH_P")), yaw_gain)
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

    # -- inputs ------------------------------------------------------------------------------

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
        m = self.sub_status.update()
        if m is not None:
            self.vtol_fw = bool(m.is_vtol and not m.in_transition_mode
                                and m.vehicle_type == m.VEHICLE_TYPE_FIXED_WING)
        if not self.stabilized:
            sp = self.sub_att_sp.update()
            if sp is not None:
                self.qd = tuple(sp.q_d)  # type: ignore[assignment]
                tb = sp.thrust_body
                self.thrust_body[0], self.thrust_body[1], self.thrust_body[2] = tb[0], tb[1], tb[2]
                self.yawspeed_ff = sp.yaw_sp_move_rate
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
        """Sticks -> attitude setpoint (tilt vector in the heading frame, yaw from the rate)."""
        man = self.manual
        yaw = q_yaw(q)
        thr = self._throttle_curve(man.throttle)
        if self.man_yaw_sp != self.man_yaw_sp:  # NaN: started with no heading setpoint
            self.man_yaw_sp = yaw
        if not self.armed or self.landed and thr <= self.manthr_min + 0.05:
            self.man_yaw_sp = yaw
            self.yawspeed_ff = 0.0
        else:
            self.yawspeed_ff = man.yaw * self.man_yaw_max
            self.man_yaw_sp += self.yawspeed_ff * dt
            # do not let the heading setpoint run away from the vehicle
            err = math.remainder(self.man_yaw_sp - yaw, 2.0 * math.pi)
            lim = 0.5 * math.pi
            if abs(err) > lim:
                self.man_yaw_sp = yaw + math.copysign(lim, err)
        self.man_yaw_sp = math.remainder(self.man_yaw_sp, 2.0 * math.pi)
        tilt = self.man_tilt_max
        q_tilt = q_from_rotvec(man.roll * tilt, -man.pitch * tilt, 0.0)
        self.qd = q_mul(q_from_euler(0.0, 0.0, self.man_yaw_sp), q_tilt)
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
        # our own publication must not come back as an external setpoint
        self.sub_att_sp.update()
        self.have_sp = True

    # -- the loop ----------------------------------------------------------------------------

    def run(self) -> None:
        att = self.sub_att.update()
        if att is None:
            return
        self._poll()
        q: Quat = tuple(att.q)  # type: ignore[assignment]
        t = att.timestamp_sample
        dt = (t - self.last_att_us) * 1e-6
        self.last_att_us = t
        if dt <= 0.0 or dt > 0.1:
            dt = 0.004
        if not self.attitude_enabled or self.vtol_fw:
            # rates only (offboard body rates), or a VTOL in fixed-wing flight: the rate
            # setpoint is someone else's
            return
        if self.stabilized:
            self._stabilized_setpoint(q, dt)
        if not self.have_sp:
            return
        now = self.platform.hrt.absolute_time()
        rr, rp, ry = self._law(q, dt, now)
        mr, mp, my = self.rate_max
        m = self.rates_msg
        m.timestamp = now
        m.roll = -mr if rr < -mr else (min(rr, mr))
        m.pitch = -mp if rp < -mp else (min(rp, mp))
        m.yaw = -my if ry < -my else (min(ry, my))
        tb = self.thrust_body
        m.thrust_body[0], m.thrust_body[1], m.thrust_body[2] = tb[0], tb[1], tb[2]
        m.reset_integral = self.reset_integral
        self.pub_rates.publish(m)
        self.rates_published += 1

    def _law(self, q: Quat, dt: float, now: int) -> tuple[float, float, float]:
        """PX4's quaternion law: body rates from the attitude error (tilt first, yaw weighted
        by MC_YAW_WEIGHT) times MC_*_P, plus the yaw rate feed-forward; the first output after
        a swap continues the previous controller's (``_hand_over``). The caller limits the
        rates to MC_*RATE_MAX. Another law (mc_att_control_so3) overrides this alone."""
        ex, ey, ez = attitude_error_rates(q, self.qd, self.yaw_w)
        kr, kp, ky = self.gains
        rr, rp, ry = kr * ex, kp * ey, ky * ez
        # yaw rate feed-forward: world z rate expressed in body axes
        ff = self.yawspeed_ff
        if ff != 0.0:
            w, x, y, z = q
            rr += ff * 2.0 * (x * z - w * y)
            rp += ff * 2.0 * (y * z + w * x)
            ry += ff * (w * w - x * x - y * y + z * z)
        if self.first_output:
            self._hand_over(rr, rp, ry, now)
        if self.handover.active:
            rr, rp, ry = self.handover.apply(rr, rp, ry, now)
        return rr, rp, ry

    def _hand_over(self, rr: float, rp: float, ry: float, now: int) -> None:
        """First output: continue from the previous controller's last rate setpoint, if recent
        (a swap in flight), by a fading offset: this law keeps no state that could absorb it."""
        self.first_output = False
        ho = self.handover
        if not ho.take(self.pub_rates.node.last, now) or not self.armed:
            return
        dr, dp, dy = ho.difference(rr, rp, ry)
        ho.start_offset((dr, dp, dy), now)
        r, p, y = ho.apply(rr, rp, ry, now)
        self.info(ho.report(r, p, y, math.sqrt(dr * dr + dp * dp + dy * dy)))

    def status_lines(self) -> list[str]:
        m = self.rates_msg
        return [f"stabilized {self.stabilized} armed {self.armed} landed {self.landed}",
                f"{self.rates_published} rate setpoints published since start",
                (f"rate sp r {m.roll:+.3f} p {m.pitch:+.3f} y {m.yaw:+.3f} "
                 f"thrust {-m.thrust_body[2]:.3f}")]
