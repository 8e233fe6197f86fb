"""Multicopter position controller module: flight task -> cascade -> attitude setpoint.

Runs on ``vehicle_local_position`` (at most every ``INTERVAL_LIMIT_US``, 100 Hz) whenever the
control mode enables climb-rate control (altitude, position and auto modes) and the vehicle is
armed. Each cycle:

1. the flight task for the mode (auto from the triplet, manual position, manual altitude) makes
   the trajectory setpoint (published as ``trajectory_setpoint``); in Offboard the offboard
   controller's ``trajectory_setpoint`` is followed instead and nothing is published over it
   (``offboard_task.py``, as PX4 runs no flight task in Offboard);
2. the takeoff state machine decides whether the vehicle sits on the ground (thrust 0, level,
   integrators reset), ramps the thrust limit up for takeoff (``MPC_TKO_RAMP_T``), or flies;
3. :class:`PositionControl` turns the setpoint into a thrust vector, published with the attitude
   setpoint (``vehicle_attitude_setpoint``) and for logs (``vehicle_local_position_setpoint``);
4. the hover thrust estimator learns the hover throttle in flight (``hover_thrust_estimate``) and
   the controller uses it.

A VTOL (``vehicle_status.is_vtol``) is flown here in multicopter flight and in both
transitions (then by :class:`TaskTransition`: altitude, level, heading), not as a plane.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from common.quaternion import q_yaw
from firmware.modules.mc_pos_control.flight_tasks import (
    TaskAuto,
    TaskManualAltitude,
    TaskManualPosition,
    _Task,
)
from firmware.modules.mc_pos_control.geo import MapProjection
from firmware.modules.mc_pos_control.hover_thrust_estimator import HoverThrustEstimator
from firmware.modules.mc_pos_control.offboard_task import TaskOffboard
from firmware.modules.mc_pos_control.params import PARAMS
from firmware.modules.mc_pos_control.position_control import (
    PositionControl,
    attitude_from_thrust,
)
from firmware.modules.mc_pos_control.transition_task import TaskTransition
from firmware.platform.module import WorkItemModule

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["PARAMS", "McPosControlModule"]

_D2R = math.pi / 180.0
GROUND, RAMPUP, FLIGHT = 0, 1, 2
STATE_NAMES = ("ground", "rampup", "flight")


class McPosControlModule(WorkItemModule):
    """``mc_pos_control``: vehicle_local_position -> vehicle_attitude_setpoint."""

    NAME = "mc_pos_control"
    DESCRIPTION = "multicopter position controller with flight tasks and hover thrust estimator"
    WQ = "wq:nav_and_controllers"
    #: STM32F427: flight task, cascade, attitude from thrust, HTE, 4 publications: ~250 us
    CPU_COST_NS = 250_000
    INTERVAL_LIMIT_US = 10_000
    PARAMS = PARAMS

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.ctrl = PositionControl()
        self.hte = HoverThrustEstimator()
        self.prm: dict[str, float] = {}
        self.state = GROUND
        self.ramp = 0.0
        self.task: _Task | None = None
        self.tasks: dict[str, _Task] = {}
        self.armed = False
        self.landed = True
        self.ground_contact = False
        self.mode: Any = None
        self.triplet: Any = None
        self.manual: Any = None
        self.proj: MapProjection | None = None
        self.ref_alt = 0.0
        self.ref_alt_valid = False
        self.ground_z = 0.0
        self.x = self.y = self.z = self.vx = self.vy = self.vz = 0.0
        self.yaw = 0.0
        self.last_us = 0
        self.active = False
        self.thr_max_land = 1.0
        self.vtol_fw = False         # a VTOL flying as a plane: fw_pos_control_l1's turn
        self.in_transition = False   # a VTOL between the two

    # -- life cycle ----------------------------------------------------------------------------

    def _start(self) -> None:
        orb = self.platform.orb
        assert self.work_item is not None  # ModuleBase.start() made it
        self.sub_lpos = self.subscribe_callback(self.work_item, "vehicle_local_position",
                                                interval_us=self.INTERVAL_LIMIT_US)
        self.sub_att = self.subscribe("vehicle_attitude")
        self.sub_mode = self.subscribe("vehicle_control_mode")
        self.sub_trip = self.subscribe("position_setpoint_triplet")
        self.sub_man = self.subscribe("manual_control_setpoint")
        self.sub_land = self.subscribe("vehicle_land_detected")
        self.sub_param = self.subscribe("parameter_update")
        self.sub_status = self.subscribe("vehicle_status")
        # Offboard: the MAVLink receiver's setpoints (this module publishes none meanwhile)
        self.sub_traj = self.subscribe("trajectory_setpoint")
        self.pub_traj = self.advertise("trajectory_setpoint")
        self.pub_lsp = self.advertise("vehicle_local_position_setpoint")
        self.pub_att = self.advertise("vehicle_attitude_setpoint")
        self.pub_hte = self.advertise("hover_thrust_estimate")
        self.traj_msg = orb.new("trajectory_setpoint")
        self.lsp_msg = orb.new("vehicle_local_position_setpoint")
        self.att_msg = orb.new("vehicle_attitude_setpoint")
        self.hte_msg = orb.new("hover_thrust_estimate")
        self.manual = orb.new("manual_control_setpoint")
        self.tasks = {"auto": TaskAuto(self), "position": TaskManualPosition(self),
                      "altitude": TaskManualAltitude(self), "offboard": TaskOffboard(self),
                      "transition": TaskTransition(self)}
        self._load_params()
        self.hte.reset(self.prm["MPC_THR_HOVER"])

    def _load_params(self) -> None:
        params = self.system.params
        assert params is not None  # parameters are loaded before modules start
        self.prm = {d.name: float(params[d.name]) for d in PARAMS}
        p = self.prm
        c = self.ctrl
        c.xy_p, c.z_p = p["MPC_XY_P"], p["MPC_Z_P"]
        c.vxy_p, c.vxy_i, c.vxy_d = p["MPC_XY_VEL_P_ACC"], p["MPC_XY_VEL_I_ACC"], \
            p["MPC_XY_VEL_D_ACC"]
        c.vz_p, c.vz_i, c.vz_d = p["MPC_Z_VEL_P_ACC"], p["MPC_Z_VEL_I_ACC"], \
            p["MPC_Z_VEL_D_ACC"]
        c.vxy_max, c.vz_up, c.vz_dn = p["MPC_XY_VEL_MAX"], p["MPC_Z_VEL_MAX_UP"], \
            p["MPC_Z_VEL_MAX_DN"]
        c.tilt_max = p["MPC_TILTMAX_AIR"] * _D2R
        c.thr_min, c.thr_max = p["MPC_THR_MIN"], p["MPC_THR_MAX"]
        self.hte.noise = p["HTE_HT_NOISE"]
        self.hte.gate = p["HTE_ACC_GATE"]
        self.hte.std_init = p["HTE_HT_ERR_INIT"]
        if not self.hte.valid:
            c.set_hover_thrust(p["MPC_THR_HOVER"])
        self.man_tilt_max = float(params.get("MPC_MAN_TILT_MAX", 35.0)) * _D2R
        self.man_yaw_max = float(params.get("MPC_MAN_Y_MAX", 150.0)) * _D2R

    # -- helpers for the flight tasks -------------------------------------------------------------

    @property
    def on_ground(self) -> bool:
        return self.state != FLIGHT

    def height_above_ground(self) -> float:
        lp = self.lpos
        if lp.dist_bottom_valid:
            return float(lp.dist_bottom)
        return self.ground_z - self.z

    # -- the loop --------------------------------------------------------------------------------

    def _poll(self) -> None:
        m = self.sub_mode.update()
        if m is not None:
            self.mode = m
            self.armed = bool(m.flag_armed)
        m = self.sub_trip.update()
        if m is not None:
            self.triplet = m
        m = self.sub_man.update()
        if m is not None:
            self.manual = m
        m = self.sub_land.update()
        if m is not None:
            if m.landed and not self.landed and self.state == FLIGHT:
                self.state = GROUND
            self.landed = bool(m.landed)
            self.ground_contact = bool(m.ground_contact or m.maybe_landed)
        if self.sub_param.updated():
            self.sub_param.update()
            self._load_params()
        m = self.sub_status.update()
        if m is not None:
            self.vtol_fw = bool(m.is_vtol) and m.vehicle_type == m.VEHICLE_TYPE_FIXED_WING
            self.in_transition = bool(m.is_vtol and m.in_transition_mode)

    def _select_task(self) -> _Task | None:
        m = self.mode
        if m is not None and m.flag_control_offboard_enabled:
            # PX4: the position controller runs in Offboard whenever offboard_control_mode
            # asks for position, velocity or acceleration control
            return self.tasks["offboard"] if m.flag_multicopter_position_control_enabled \
                else None
        if m is None or not m.flag_control_climb_rate_enabled or self.vtol_fw:
            return None
        if self.in_transition:
            return self.tasks["transition"]
        if m.flag_control_auto_enabled:
            return self.tasks["auto"]
        if m.flag_control_position_enabled and self.lpos.xy_valid:
            return self.tasks["position"]
        return self.tasks["altitude"]

    def run(self) -> None:
        lp = self.sub_lpos.update()
        if lp is None:
            return
        self.lpos = lp
        self._poll()
        t = lp.timestamp_sample
        dt = (t - self.last_us) * 1e-6
        self.last_us = t
        if dt <= 0.0 or dt > 0.1:
            dt = 0.01
        self.x, self.y, self.z = lp.x, lp.y, lp.z
        self.vx, self.vy, self.vz = lp.vx, lp.vy, lp.vz
        att = self.sub_att.copy()
        self.yaw = q_yaw(tuple(att.q)) if att is not None else lp.heading
        if lp.xy_global and (self.proj is None or self.proj.ref_lat != lp.ref_lat
                             or self.proj.ref_lon != lp.ref_lon):
            self.proj = MapProjection(lp.ref_lat, lp.ref_lon)
        self.ref_alt, self.ref_alt_valid = lp.ref_alt, bool(lp.z_global)

        task = self._select_task() if self.armed else None
        if task is None:
            self._deactivate()
            return
        if task is not self.task or not self.active:
            self.task = task
            task.activate()
            if not self.active:
                self.state = GROUND if self.landed else FLIGHT
                self.ctrl.reset()
            self.active = True
        if self.state == GROUND:
            self.ground_z = self.z
        task.update(dt)
        self._takeoff_state(task, dt)
        self._control(task, dt)

    def _deactivate(self) -> None:
        self.active = False
        self.task = None
        self.ctrl.reset()
        self.state = GROUND if self.landed else FLIGHT

    def _takeoff_state(self, task: _Task, dt: float) -> None:
        """Ground -> ramp-up -> flight, as the setpoint asks for a climb."""
        if self.state == GROUND:
            if task.idle:
                return
            if task.wants_takeoff(self.z):
                self.state = RAMPUP
                self.ramp = 0.0
        elif self.state == RAMPUP:
            t_ramp = self.prm["MPC_TKO_RAMP_T"]
            self.ramp = 1.0 if t_ramp <= 0.0 else min(self.ramp + dt / t_ramp, 1.0)
            if self.ramp >= 1.0 or self.z < self.ground_z - 0.3 or not self.landed \
                    and self.vz < -0.2:
                self.state = FLIGHT
                task.activate()  # the trajectory starts from the vehicle's state

    @staticmethod
    def _descending(task: _Task) -> bool:
        return math.isfinite(task.vel[2]) and task.vel[2] > 0.1

    def _control(self, task: _Task, dt: float) -> None:
        c = self.ctrl
        lp = self.lpos
        yaw_sp = task.yaw if math.isfinite(task.yaw) else self.yaw
        if self.state == GROUND:
            # on the ground: motors idle, level, nothing integrates
            c.reset()
            c.thrust[0] = c.thrust[1] = c.thrust[2] = 0.0
            self.thr_max_land = c.thr_max
            tx = ty = tz = 0.0
        else:
            thr_max = None
            integrate_xy = True
            pos_sp, vel_sp, acc_sp = task.pos, task.vel, task.acc
            if self.state == RAMPUP:
                # ask for the takeoff climb rate, let the thrust limit ramp up to it
                thr_max = c.thr_max * self.ramp
                c.int_x = c.int_y = c.int_z = 0.0
                pos_sp = [task.pos[0], task.pos[1], math.nan]
                vel_sp = [task.vel[0], task.vel[1], -self.prm["MPC_TKO_SPEED"]]
                acc_sp = [math.nan, math.nan, math.nan]
            elif self.ground_contact and self._descending(task):
                # touching down: stop pushing sideways and unload the motors within a second
                integrate_xy = False
                c.int_x = c.int_y = 0.0
                self.thr_max_land = max(self.thr_max_land - dt * c.thr_max, c.thr_min)
                thr_max = self.thr_max_land
            else:
                self.thr_max_land = c.thr_max
            c.update(dt, (self.x, self.y, self.z), (self.vx, self.vy, self.vz),
                     (lp.ax, lp.ay, lp.az), pos_sp, vel_sp, acc_sp,
                     integrate_xy=integrate_xy, thr_max_override=thr_max)
            tx, ty, tz = c.thrust
            if self.state == RAMPUP or self.ground_contact and self._descending(task):
                tx = ty = 0.0
                c.thrust[0] = c.thrust[1] = 0.0
            self._hover_thrust(dt, -tz)
        q = attitude_from_thrust(tx, ty, min(-0.001, tz), yaw_sp)
        self._publish(task, q, tx, ty, tz, yaw_sp)

    def _hover_thrust(self, dt: float, thrust_up: float) -> None:
        """Learn the hover thrust in free flight; the controller follows once it converged."""
        lp = self.lpos
        if self.state == FLIGHT and not self.landed and not self.ground_contact \
                and math.hypot(lp.vx, lp.vy) < 10.0:
            self.hte.update(dt, lp.az, self._last_thrust_up)
            if self.hte.valid:
                self.ctrl.set_hover_thrust(self.hte.hover)
        self._last_thrust_up = thrust_up
        m = self.hte_msg
        m.timestamp = self.platform.hrt.absolute_time()
        m.timestamp_sample = lp.timestamp_sample
        m.hover_thrust, m.hover_thrust_var = self.hte.hover, self.hte.var
        m.accel_innov, m.accel_innov_var = self.hte.innov, self.hte.innov_var
        m.accel_innov_test_ratio = self.hte.test_ratio
        m.accel_noise_var = self.hte.acc_var
        m.valid = self.hte.valid
        self.pub_hte.publish(m)

    _last_thrust_up = 0.0

    def _publish(self, task: _Task, q: tuple[float, float, float, float], tx: float, ty: float,
                 tz: float, yaw_sp: float) -> None:
        now = self.platform.hrt.absolute_time()
        c = self.ctrl
        m = self.traj_msg
        m.timestamp = now
        for i in range(3):
            m.position[i], m.velocity[i], m.acceleration[i] = task.pos[i], task.vel[i], \
                task.acc[i]
        m.yaw, m.yawspeed = yaw_sp, task.yawspeed
        if task.name != "offboard":
            self.pub_traj.publish(m)
        s = self.lsp_msg
        s.timestamp = now
        s.x, s.y, s.z = task.pos
        s.vx, s.vy, s.vz = c.vel_sp
        for i in range(3):
            s.acceleration[i] = c.acc_sp[i]
        s.thrust[0], s.thrust[1], s.thrust[2] = tx, ty, tz
        s.yaw, s.yawspeed = yaw_sp, task.yawspeed
        self.pub_lsp.publish(s)
        a = self.att_msg
        a.timestamp = now
        w, x, y, z = q
        a.roll_body = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
        a.pitch_body = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
        a.yaw_body = yaw_sp
        a.yaw_sp_move_rate = task.yawspeed
        a.q_d[0], a.q_d[1], a.q_d[2], a.q_d[3] = w, x, y, z
        a.thrust_body[0] = a.thrust_body[1] = 0.0
        a.thrust_body[2] = -math.sqrt(tx * tx + ty * ty + tz * tz)
        a.reset_integral = self.state == GROUND
        self.pub_att.publish(a)

    def status_lines(self) -> list[str]:
        t = self.task.name if self.task is not None else "none"
        return [(f"task {t} state {STATE_NAMES[self.state]} armed {self.armed} "
                 f"landed {self.landed}"),
                (f"hover thrust {self.hte.hover:.3f} (valid {self.hte.valid}) "
                 f"integrators {self.ctrl.int_x:+.2f} {self.ctrl.int_y:+.2f} "
                 f"{self.ctrl.int_z:+.2f}")]
