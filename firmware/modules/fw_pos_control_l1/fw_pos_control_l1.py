"""Fixed-wing position control (PX4's ``fw_pos_control_l1``): L1 guidance + TECS.

Runs on every ``vehicle_local_position`` (at most 50 Hz) on the navigation queue and publishes
``vehicle_attitude_setpoint`` (roll from L1, pitch and throttle (``thrust_body[0]``) from TECS,
yaw the navigation bearing), ``position_controller_status`` (the L1 switch distance the
navigator accepts waypoints at) and ``tecs_status``.

Auto modes fly the navigator's ``position_setpoint_triplet.current``:

* POSITION: the line previous -> current waypoint (from where the waypoint became current when
  there is no previous one) at its altitude and cruising speed/throttle (else FW_AIRSPD_TRIM,
  FW_THR_CRUISE);
* LOITER: the circle around it (its loiter radius, negative = counter-clockwise, else
  FW_LOITER_R) at its altitude;
* TAKEOFF: runway or launch (:mod:`.takeoff`); climb-out (full throttle, minimum airspeed,
  pitch at least FW_TKO_PITCH_MIN, roll within 15 deg) while the altitude error exceeds
  FW_CLMBOUT_DIFF; the track: toward the setpoint when it is away from the start, else the
  setpoint's yaw (the runway heading) from the start;
* LAND: approach on the line previous -> touchdown, glide slope, flare, throttle limit
  (:mod:`.landing`); on the ground: throttle off, wings level;
* IDLE: throttle off, wings level (PX4).

Manual modes with altitude control: ALTCTL (pitch stick = climb/sink rate up to FW_T_CLMB_MAX /
FW_T_SINK_MAX, altitude held at centre; throttle stick = airspeed between FW_AIRSPD_MIN, TRIM and
MAX; roll stick = roll up to FW_MAN_R_MAX) and POSCTL (as ALTCTL, and with the roll and yaw
sticks centred, the track is held on the heading it had, L1 on that line).

Airspeed from the ``airspeed`` topic while valid, else TECS's airspeed-less mode.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Final

from common.mathlib import constrain
from firmware.lib.l1 import L1Control, wrap_pi
from firmware.lib.tecs import Tecs, TecsParams
from firmware.modules.fw_att_control.airspeed_input import AirspeedInput
from firmware.modules.fw_pos_control_l1.landing import (
    APP_ON_SLOPE,
    FLARE_BELOW_GROUND_M,
    Approach,
    flare_time_constant,
    slope_aim_shift_m,
    slope_altitude,
)
from firmware.modules.fw_pos_control_l1.params import PARAMS, apply_tecs_params
from firmware.modules.fw_pos_control_l1.state import Out as _Out
from firmware.modules.fw_pos_control_l1.state import State as _State
from firmware.modules.fw_pos_control_l1.state import fill_tecs_status
from firmware.modules.fw_pos_control_l1.takeoff import LaunchDetector, RunwayTakeoff
from common.quaternion import q_from_euler, q_to_euler
from firmware.modules.mc_pos_control.geo import MapProjection
from firmware.platform.module import WorkItemModule
from common.units import G0_M_S2

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["PARAMS", "FwPosControlL1Module"]

_D2R: Final = math.pi / 180.0

SP_POSITION: Final = 0
SP_LOITER: Final = 2
SP_TAKEOFF: Final = 3
SP_LAND: Final = 4
SP_IDLE: Final = 5

CTRL_NONE: Final = 0
CTRL_AUTO: Final = 1
CTRL_ALTITUDE: Final = 2
CTRL_POSITION: Final = 3

#: roll limit (rad) while climbing out below the climb-out altitude (PX4: 15 deg)
_CLIMBOUT_ROLL: Final = 15.0 * _D2R
#: a takeoff setpoint closer than this to the start is a direction (the yaw), not a place
_TKO_NEAR_M: Final = 50.0
#: stick deadzone of the altitude and position modes
_DEADZONE: Final = 0.05


class FwPosControlL1Module(WorkItemModule):
    """``fw_pos_control_l1``: position, setpoints and sticks -> vehicle_attitude_setpoint."""

    NAME = "fw_pos_control_l1"
    DESCRIPTION = "fixed-wing position controller (L1 + TECS)"
    WQ = "wq:nav_and_controllers"
    #: STM32F427: L1 trig, TECS, projections, ~150 us per run
    CPU_COST_NS = 150_000
    INTERVAL_LIMIT_US = 20_000
    PARAMS = PARAMS

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.l1 = L1Control()
        self.tecs = Tecs(TecsParams())
        self.runway = RunwayTakeoff()
        self.launch = LaunchDetector()
        self.ctrl = CTRL_NONE
        self.armed = False
        self.landed = True
        self.fixed_wing = True
        self.proj: MapProjection | None = None
        self.ref = (math.nan, math.nan)
        self.last_us = 0
        self.att = (0.0, 0.0, 0.0)
        self.q: tuple[float, float, float, float] = (1.0, 0.0, 0.0, 0.0)
        self.global_alt = math.nan
        # per-setpoint memory: where the current setpoint became current, landing state
        self.sp_key: tuple[float, float, float, int] = (math.nan, math.nan, math.nan, -1)
        self.sp_start_ne = (0.0, 0.0)
        self.sp_start_alt = 0.0
        self.sp_start_yaw = 0.0
        self.flaring = False
        self.flare_tc = 3.0
        self.land_line_locked = False
        self.approach = Approach()
        self.hold_alt = math.nan
        self.hold_line: tuple[tuple[float, float], tuple[float, float]] | None = None
        self.tecs_mode = 0
        self.reset_integral = False

    # -- life cycle --------------------------------------------------------------------------

    def _start(self) -> None:
        orb = self.platform.orb
        self.pub_att_sp = self.advertise("vehicle_attitude_setpoint")
        self.att_sp = orb.new("vehicle_attitude_setpoint")
        self.pub_tecs = self.advertise("tecs_status")
        self.tecs_msg = orb.new("tecs_status")
        self.pub_pcs = self.advertise("position_controller_status")
        self.pcs = orb.new("position_controller_status")
        item = self.work_item
        assert item is not None  # started: the module's work item exists
        self.sub_lpos = self.subscribe_callback(item, "vehicle_local_position",
                                                interval_us=self.INTERVAL_LIMIT_US)
        self.sub_gpos = self.subscribe("vehicle_global_position")
        self.sub_att = self.subscribe("vehicle_attitude")
        self.sub_trip = self.subscribe("position_setpoint_triplet")
        self.sub_mode = self.subscribe("vehicle_control_mode")
        self.sub_status = self.subscribe("vehicle_status")
        self.sub_manual = self.subscribe("manual_control_setpoint")
        self.sub_land = self.subscribe("vehicle_land_detected")
        self.sub_armed = self.subscribe("actuator_armed")
        self.sub_param = self.subscribe("parameter_update")
        self.airspeed = AirspeedInput(self)
        self.trip = orb.new("position_setpoint_triplet")
        self.manual = orb.new("manual_control_setpoint")
        self.perf_loop = self.perf_alloc("count", "cycles")
        self._load_params()

    def _load_params(self) -> None:
        p = self.param
        self.pv: dict[str, Any] = {d.name: p(d.name) for d in PARAMS}
        v = self.pv
        self.l1.set_period(v["FW_L1_PERIOD"])
        self.l1.set_damping(v["FW_L1_DAMPING"])
        self.l1.set_roll_limit(v["FW_R_LIM"] * _D2R)
        apply_tecs_params(v, self.tecs.p)
        self.airspeed.use = int(v["FW_ARSP_MODE"]) == 0

    # -- inputs ------------------------------------------------------------------------------

    def _poll(self) -> None:
        m = self.sub_mode.update()
        if m is not None:
            if m.flag_control_auto_enabled and m.flag_control_position_enabled:
                self.ctrl = CTRL_AUTO
            elif m.flag_control_manual_enabled and m.flag_control_position_enabled:
                self.ctrl = CTRL_POSITION
            elif m.flag_control_manual_enabled and m.flag_control_altitude_enabled:
                self.ctrl = CTRL_ALTITUDE
            else:
                self.ctrl = CTRL_NONE
        m = self.sub_status.update()
        if m is not None:
            self.fixed_wing = (not m.is_vtol
                               or m.vehicle_type == m.VEHICLE_TYPE_FIXED_WING)
        m = self.sub_land.update()
        if m is not None:
            self.landed = bool(m.landed)
        m = self.sub_armed.update()
        if m is not None:
            self.armed = bool(m.armed)
        m = self.sub_manual.update()
        if m is not None:
            self.manual = m
        m = self.sub_trip.update()
        if m is not None:
            self.trip = m
        m = self.sub_gpos.update()
        if m is not None:
            self.global_alt = float(m.alt)
        m = self.sub_att.update()
        if m is not None:
            self.q = (float(m.q[0]), float(m.q[1]), float(m.q[2]), float(m.q[3]))
            self.att = q_to_euler(self.q)
        if self.sub_param.updated():
            self.sub_param.update()
            self._load_params()

    def _ne(self, lat: float, lon: float) -> tuple[float, float]:
        assert self.proj is not None
        return self.proj.project(lat, lon)

    def _body_accel_x(self, ax: float, ay: float, az: float) -> float:
        """The kinematic acceleration along the body x axis (NED accel rotated into body)."""
        w, x, y, z = self.q
        return ((w * w + x * x - y * y - z * z) * ax + 2.0 * (x * y + w * z) * ay
                + 2.0 * (x * z - w * y) * az)

    # -- the loop ----------------------------------------------------------------------------

    def run(self) -> None:
        lp = self.sub_lpos.update()
        if lp is None:
            return
        self._poll()
        now = self.platform.hrt.absolute_time()
        self.airspeed.update(now)
        t = int(lp.timestamp_sample)
        dt = (t - self.last_us) * 1e-6
        self.last_us = t
        if dt <= 0.0 or dt > 0.5:
            dt = 0.02
        if not self.fixed_wing or self.ctrl == CTRL_NONE or not lp.xy_valid or not lp.z_valid:
            self._reset()
            return
        if (lp.ref_lat, lp.ref_lon) != self.ref or self.proj is None:
            self.ref = (float(lp.ref_lat), float(lp.ref_lon))
            self.proj = MapProjection(self.ref[0], self.ref[1])
        alt = (self.global_alt if math.isfinite(self.global_alt)
               else float(lp.ref_alt) - float(lp.z))
        st = _State(pos=(float(lp.x), float(lp.y)), vel=(float(lp.vx), float(lp.vy)),
                    alt=alt, climb=-float(lp.vz),
                    accel_x=self._body_accel_x(float(lp.ax), float(lp.ay), float(lp.az)),
                    yaw=self.att[2], now=now, dt=dt)
        self.tecs_mode = 0
        self.reset_integral = False
        if self.ctrl == CTRL_AUTO:
            out = self._auto(st)
        else:
            out = self._manual_alt(st, self.ctrl == CTRL_POSITION)
        if out is None:
            return
        self._publish(st, out)
        self.perf_loop.count()

    def _reset(self) -> None:
        self.tecs.reset()
        self.runway.reset()
        self.launch.reset()
        self.sp_key = (math.nan, math.nan, math.nan, -1)
        self.hold_alt = math.nan
        self.hold_line = None
        self.flaring = False

    # -- TECS glue ---------------------------------------------------------------------------

    def _tecs(self, st: _State, hgt_sp: float, v_sp: float, thr_min: float, thr_max: float,
              thr_cruise: float, pitch_min: float, pitch_max: float, climbout: bool = False,
              speed_weight: float | None = None, alt_tc: float | None = None) -> None:
        v = self.pv
        asp = self.airspeed
        self.tecs.update(st.dt, altitude_m=st.alt, height_rate_m_s=st.climb,
                         tas_m_s=asp.true_m_s if asp.valid else math.nan,
                         airspeed_valid=asp.valid, accel_x_m_s2=st.accel_x,
                         pitch_rad=self.att[1], roll_rad=self.att[0], hgt_sp_m=hgt_sp,
                         tas_sp_m_s=v_sp, throttle_min=thr_min, throttle_max=thr_max,
                         throttle_cruise=thr_cruise, pitch_min_rad=pitch_min,
                         pitch_max_rad=pitch_max, climbout=climbout,
                         climbout_pitch_min_rad=v["FW_TKO_PITCH_MIN"] * _D2R,
                         speed_weight=speed_weight, alt_tc_s=alt_tc,
                         eas2tas=(asp.true_m_s / asp.indicated_m_s
                                  if asp.valid and asp.indicated_m_s > 3.0 else 1.0))
        if self.tecs.underspeed:
            self.tecs_mode = 1
        elif climbout:
            self.tecs_mode = 2

    def _limits(self) -> tuple[float, float, float, float]:
        v = self.pv
        return (float(v["FW_THR_MIN"]), float(v["FW_THR_MAX"]), v["FW_P_LIM_MIN"] * _D2R,
                v["FW_P_LIM_MAX"] * _D2R)

    # -- auto --------------------------------------------------------------------------------

    def _new_setpoint(self, st: _State, cur: Any) -> None:
        """Remember where the current setpoint became current (the line's start when there is
        no previous waypoint, the landing's entry altitude, the takeoff's runway)."""
        a = float(cur.alt)
        key = (float(cur.lat), float(cur.lon), a if math.isfinite(a) else -1e9, int(cur.type))
        if key == self.sp_key:
            return
        old, self.sp_key = self.sp_key, key
        if old[3] == key[3] and old[0] == key[0] and old[1] == key[1]:
            return   # only the altitude changed: the same takeoff run, approach or flare
        self.sp_start_ne = st.pos
        self.sp_start_alt = st.alt
        self.sp_start_yaw = st.yaw
        self.flaring = False
        self.land_line_locked = False
        self.approach.reset()
        if cur.type == SP_TAKEOFF:
            self.runway.reset()
            self.launch.reset()

    def _auto(self, st: _State) -> _Out | None:
        trip = self.trip
        cur = trip.current
        v = self.pv
        thr_min, thr_max, p_min, p_max = self._limits()
        if not cur.valid or not (math.isfinite(cur.lat) and math.isfinite(cur.lon)) \
                or (int(cur.type) == SP_LAND and not math.isfinite(float(cur.alt))):
            return self._hold(st)   # nowhere to go (or no ground to land on)
        self.hold_alt = math.nan
        self._new_setpoint(st, cur)
        target = self._ne(cur.lat, cur.lon)
        prev = trip.previous
        prev_ne = (self._ne(prev.lat, prev.lon) if prev.valid and math.isfinite(prev.lat)
                   else self.sp_start_ne)
        v_sp = cur.cruising_speed if cur.cruising_speed > 0.0 else v["FW_AIRSPD_TRIM"]
        thr_cruise = (cur.cruising_throttle if cur.cruising_throttle > 0.0
                      else v["FW_THR_CRUISE"])
        t = int(cur.type)
        if t == SP_IDLE:
            self.l1.navigate_level_flight(st.yaw)
            return self._idle(st)
        if t == SP_TAKEOFF:
            return self._takeoff(st, cur, target, thr_cruise)
        if t == SP_LAND:
            return self._land(st, cur, target, prev_ne)
        if self.landed and not self.armed:
            self.l1.navigate_level_flight(st.yaw)
            return self._idle(st)
        if t == SP_LOITER:
            r = float(cur.loiter_radius)
            radius = abs(r) if math.isfinite(r) and abs(r) > 0.5 else v["FW_LOITER_R"]
            direction = int(getattr(cur, "loiter_direction", 0)) or (-1 if r < 0.0 else 1)
            self.l1.navigate_loiter(target, st.pos, radius, direction, st.vel, st.yaw)
        else:
            self.l1.navigate_waypoints(prev_ne, target, st.pos, st.vel, st.yaw)
        self._tecs(st, self._alt_sp(cur, st), v_sp, thr_min, thr_max, thr_cruise, p_min, p_max)
        return _Out(self.l1.nav_roll(), self.tecs.pitch_sp, self.l1.nav_bearing_rad,
                    self.tecs.throttle_sp, target)

    def _alt_sp(self, cur: Any, st: _State) -> float:
        """The setpoint's altitude; a NaN one (PX4: "keep the altitude") holds the altitude
        the aircraft had when the setpoint became current."""
        a = float(cur.alt)
        return a if math.isfinite(a) else self.sp_start_alt

    def _hold(self, st: _State) -> _Out:
        """No usable setpoint: on the ground idle; in the air wings level on the heading at
        the altitude it had, at trim speed, until the navigator says otherwise (gliding down
        with the motor off, PX4's IDLE, is for an IDLE setpoint only)."""
        if self.landed or not self.armed:
            self.l1.navigate_level_flight(st.yaw)
            return self._idle(st)
        if not math.isfinite(self.hold_alt):   # continue from the demand TECS was flying
            self.hold_alt = self.tecs.hgt_sp_adj if self.tecs.initialised else st.alt
        v = self.pv
        thr_min, thr_max, p_min, p_max = self._limits()
        self.l1.navigate_level_flight(st.yaw)
        self._tecs(st, self.hold_alt, v["FW_AIRSPD_TRIM"], thr_min, thr_max,
                   v["FW_THR_CRUISE"], p_min, p_max)
        return _Out(0.0, self.tecs.pitch_sp, st.yaw, self.tecs.throttle_sp, None)

    def _idle(self, st: _State) -> _Out:
        self.tecs.reset()
        self.reset_integral = True
        return _Out(0.0, 0.0, st.yaw, 0.0, None)

    def _takeoff(self, st: _State, cur: Any, target: tuple[float, float],
                 thr_cruise: float) -> _Out | None:
        v = self.pv
        thr_min, thr_max, p_min, p_max = self._limits()
        start = self.sp_start_ne
        far = math.hypot(target[0] - start[0], target[1] - start[1]) > _TKO_NEAR_M
        yaw_valid = bool(cur.yaw_valid) or math.isfinite(float(cur.yaw))
        hdg = float(cur.yaw) if yaw_valid and math.isfinite(float(cur.yaw)) else self.sp_start_yaw
        if far and int(v["RWTO_HDG"]) == 1:
            hdg = math.atan2(target[1] - start[1], target[0] - start[0])
        line_end = (target if far else
                    (start[0] + 5000.0 * math.cos(hdg), start[1] + 5000.0 * math.sin(hdg)))
        alt_err = self._alt_sp(cur, st) - st.alt
        climbout = alt_err > v["FW_CLMBOUT_DIFF"]
        if not self.armed:
            self.l1.navigate_level_flight(st.yaw)
            return self._idle(st)
        wheel = False
        roll_lim = _CLIMBOUT_ROLL if climbout else self.l1.roll_lim_rad
        if int(v["RWTO_TKOFF"]) == 1:
            rw = self.runway
            if not rw.initialised:
                rw.init(st.now, st.alt, hdg)
            asp = self.airspeed
            speed = asp.indicated_m_s if asp.valid else math.hypot(*st.vel)
            state = rw.update(st.now, speed, st.alt, v["FW_AIRSPD_MIN"] * v["RWTO_AIRSPD_SCL"],
                              v["RWTO_RAMP_TIME"], v["RWTO_NAV_ALT"])
            if rw.on_ground:
                self.l1.navigate_heading(rw.heading_rad, st.yaw, st.vel)
                self.tecs.reset()
                self.reset_integral = True
                thr = rw.throttle(st.now, v["RWTO_RAMP_TIME"], v["RWTO_MAX_THR"],
                                  v["FW_THR_IDLE"])
                return _Out(0.0, v["RWTO_PSP"] * _D2R, rw.heading_rad, thr, target, wheel=True)
            if state != 3:  # rotated, below RWTO_NAV_ALT: runway heading, roll limited
                self.l1.navigate_heading(rw.heading_rad, st.yaw, st.vel)
                roll_lim = min(roll_lim, v["RWTO_MAX_ROLL"] * _D2R)
                p_max = min(p_max, v["RWTO_MAX_PITCH"] * _D2R)
                climbout = True
            else:
                self.l1.navigate_waypoints(start, line_end, st.pos, st.vel, st.yaw)
            thr_max = min(thr_max, v["RWTO_MAX_THR"])
        else:
            if int(v["LAUN_ALL_ON"]) == 1:
                self.launch.update(st.now, st.dt, self._specific_force_x(st),
                                   v["LAUN_CAT_A"], v["LAUN_CAT_T"])
                if not self.launch.motor_on(st.now, v["LAUN_CAT_MDEL"]):
                    # waiting for the throw: idle motor, wings level, launch attitude
                    self.l1.navigate_level_flight(st.yaw)
                    self.tecs.reset()
                    self.reset_integral = True
                    thr = 0.0 if self.launch.detected_us < 0 else v["FW_THR_IDLE"]
                    return _Out(0.0, v["FW_TKO_PITCH_MIN"] * _D2R, st.yaw, thr, target)
            self.l1.navigate_waypoints(start, line_end, st.pos, st.vel, st.yaw)
        self._tecs(st, self._alt_sp(cur, st), v["FW_AIRSPD_TRIM"], thr_min, thr_max, thr_cruise,
                   p_min, p_max, climbout=climbout)
        roll = constrain(self.l1.nav_roll(), -roll_lim, roll_lim)
        return _Out(roll, self.tecs.pitch_sp, self.l1.nav_bearing_rad, self.tecs.throttle_sp,
                    target, wheel=wheel)

    def _specific_force_x(self, st: _State) -> float:
        """What an accelerometer on the body x axis reads: kinematic minus gravity's part."""
        w, x, y, z = self.q
        return st.accel_x - G0_M_S2 * 2.0 * (x * z - w * y)

    def _land(self, st: _State, cur: Any, target: tuple[float, float],
              prev_ne: tuple[float, float]) -> _Out:
        v = self.pv
        thr_min, thr_max, p_min, p_max = self._limits()
        land_alt = float(cur.alt)
        if self.landed or not self.armed:
            self.l1.navigate_level_flight(st.yaw)
            self.tecs.reset()
            self.reset_integral = True
            return _Out(0.0, v["FW_LND_FL_PMIN"] * _D2R if self.armed else 0.0, st.yaw, 0.0,
                        target, wheel=self.armed)
        # the approach line, previous -> touchdown, extended past it for the rollout
        ln, le = target[0] - prev_ne[0], target[1] - prev_ne[1]
        length = math.hypot(ln, le)
        if length < 1.0:  # no line: from where the landing began
            ln, le = target[0] - self.sp_start_ne[0], target[1] - self.sp_start_ne[1]
            length = math.hypot(ln, le)
        if length < 1.0:
            ln, le, length = math.cos(st.yaw), math.sin(st.yaw), 1.0
        un, ue = ln / length, le / length
        slope = v["FW_LND_ANG"] * _D2R
        flare_alt = float(v["FW_LND_FLALT"])
        v_app = v["FW_AIRSPD_MIN"] * v["FW_LND_AIRSPD_SC"]
        shift = slope_aim_shift_m(flare_alt, slope, v_app)
        slope_len = max(self.sp_start_alt - land_alt, 0.0) / math.tan(slope) + shift + 50.0
        dist = (target[0] - st.pos[0]) * un + (target[1] - st.pos[1]) * ue  # along track, >0
        wp_dist = math.hypot(target[0] - st.pos[0], target[1] - st.pos[1])
        phase = APP_ON_SLOPE
        if not self.flaring and not self.land_line_locked:
            phase = self.approach.update(st.pos, st.vel, target, (un, ue), slope_len,
                                         max(self.l1.l1_distance_m, 30.0))
        if phase == APP_ON_SLOPE and (wp_dist < v["FW_LND_HHDIST"] or dist < 0.0):
            self.land_line_locked = True     # short final: hold the line through the rollout
        if self.land_line_locked:
            far = max(length, 100.0)
            self.l1.navigate_waypoints((target[0] - un * far, target[1] - ue * far),
                                       (target[0] + un * 1000.0, target[1] + ue * 1000.0),
                                       st.pos, st.vel, st.yaw)
        else:
            self.l1.navigate_waypoints(self.approach.line_a, self.approach.line_b, st.pos,
                                       st.vel, st.yaw)
        tl_alt = float(v["FW_LND_TLALT"]) if v["FW_LND_TLALT"] >= 0.0 else flare_alt
        h = st.alt - land_alt
        if h < tl_alt and phase == APP_ON_SLOPE:
            thr_max = min(thr_max, float(v["FW_THR_LND_MAX"]))
            self.tecs_mode = 4
        if not self.flaring and h < flare_alt and phase == APP_ON_SLOPE:
            self.flaring = True
            self.flare_tc = flare_time_constant(flare_alt, max(-st.climb, 0.0))
        roll_lim = self.l1.roll_lim_rad
        if self.flaring:
            self._tecs(st, land_alt - FLARE_BELOW_GROUND_M, v["FW_AIRSPD_MIN"], thr_min,
                       min(thr_max, thr_min), thr_min, v["FW_LND_FL_PMIN"] * _D2R,
                       v["FW_LND_FL_PMAX"] * _D2R, speed_weight=0.0, alt_tc=self.flare_tc)
            roll_lim = _CLIMBOUT_ROLL
        else:
            hgt_sp = (slope_altitude(land_alt, dist - shift, slope, self.sp_start_alt)
                      if phase == APP_ON_SLOPE else self.sp_start_alt)
            self._tecs(st, hgt_sp, v_app, thr_min, thr_max, v["FW_THR_CRUISE"], p_min, p_max)
        if self.tecs_mode == 0:
            self.tecs_mode = 3
        roll = constrain(self.l1.nav_roll(), -roll_lim, roll_lim)
        if self.flaring:
            # from the flare on, the rudder (and on the ground the steered wheel) holds the
            # runway's bearing: ailerons cannot steer a rollout
            return _Out(roll, self.tecs.pitch_sp, math.atan2(ue, un), self.tecs.throttle_sp,
                        target, wheel=True)
        return _Out(roll, self.tecs.pitch_sp, self.l1.nav_bearing_rad, self.tecs.throttle_sp,
                    target)

    # -- altitude and position modes ---------------------------------------------------------

    def _manual_alt(self, st: _State, position: bool) -> _Out | None:
        v = self.pv
        man = self.manual
        thr_min, thr_max, p_min, p_max = self._limits()
        if self.landed or not self.armed:
            self._reset()
            self.l1.navigate_level_flight(st.yaw)
            return self._idle(st)
        # altitude: the pitch stick commands a climb or sink rate, centred holds
        if not math.isfinite(self.hold_alt):
            self.hold_alt = st.alt
        pitch_stick = -float(man.pitch)       # stick back (negative) = climb
        if abs(pitch_stick) > _DEADZONE:
            rate = pitch_stick * (v["FW_T_CLMB_MAX"] if pitch_stick > 0 else v["FW_T_SINK_MAX"])
            self.hold_alt = constrain(self.hold_alt + rate * st.dt, st.alt - 15.0, st.alt + 15.0)
        # airspeed: throttle stick, centre = trim
        s = constrain(0.5 * (float(man.throttle) + 1.0), 0.0, 1.0)
        lo, trim, hi = v["FW_AIRSPD_MIN"], v["FW_AIRSPD_TRIM"], v["FW_AIRSPD_MAX"]
        v_sp = lo + (trim - lo) * s * 2.0 if s < 0.5 else trim + (hi - trim) * (s - 0.5) * 2.0
        sticks_centred = abs(float(man.roll)) < _DEADZONE and abs(float(man.yaw)) < _DEADZONE
        if position and sticks_centred:
            if self.hold_line is None:
                a = st.pos
                self.hold_line = (a, (a[0] + 3000.0 * math.cos(st.yaw),
                                      a[1] + 3000.0 * math.sin(st.yaw)))
            self.l1.navigate_waypoints(self.hold_line[0], self.hold_line[1], st.pos, st.vel,
                                       st.yaw)
            roll = self.l1.nav_roll()
            bearing = self.l1.nav_bearing_rad
        else:
            self.hold_line = None
            roll = float(man.roll) * v["FW_MAN_R_MAX"] * _D2R
            bearing = st.yaw
        self._tecs(st, self.hold_alt, v_sp, thr_min, thr_max, v["FW_THR_CRUISE"], p_min, p_max)
        return _Out(roll, self.tecs.pitch_sp, bearing, self.tecs.throttle_sp, None)

    # -- outputs -----------------------------------------------------------------------------

    def _publish(self, st: _State, out: _Out) -> None:
        now = st.now
        m = self.att_sp
        m.timestamp = now
        m.roll_body, m.pitch_body, m.yaw_body = out.roll, out.pitch, wrap_pi(out.yaw)
        w, x, y, z = q_from_euler(out.roll, out.pitch, m.yaw_body)
        m.q_d[0], m.q_d[1], m.q_d[2], m.q_d[3] = w, x, y, z
        m.yaw_sp_move_rate = 0.0
        m.thrust_body[0], m.thrust_body[1], m.thrust_body[2] = out.throttle, 0.0, 0.0
        m.reset_integral = self.reset_integral
        m.fw_control_yaw_wheel = out.wheel
        self.pub_att_sp.publish(m)
        c = self.pcs
        c.timestamp = now
        c.nav_roll, c.nav_pitch = out.roll, out.pitch
        c.nav_bearing, c.target_bearing = self.l1.nav_bearing_rad, self.l1.target_bearing_rad
        c.xtrack_error = self.l1.crosstrack_error_m
        c.wp_dist = (math.hypot(out.target[0] - st.pos[0], out.target[1] - st.pos[1])
                     if out.target is not None else math.nan)
        c.acceptance_radius = self.l1.switch_distance(500.0)
        c.yaw_acceptance = c.altitude_acceptance = math.nan
        c.type = int(self.trip.current.type) if self.ctrl == CTRL_AUTO else 0
        self.pub_pcs.publish(c)
        t = self.tecs_msg
        fill_tecs_status(t, self.tecs.status, now, out.throttle, out.pitch, self.airspeed.valid,
                         self.tecs_mode)
        self.pub_tecs.publish(t)

    def status_lines(self) -> list[str]:
        names = {CTRL_NONE: "none", CTRL_AUTO: "auto", CTRL_ALTITUDE: "altitude",
                 CTRL_POSITION: "position"}
        m = self.att_sp
        return [f"control {names.get(self.ctrl, '?')} armed {self.armed} landed {self.landed} "
                f"airspeed {'valid' if self.airspeed.valid else 'invalid'}, "
                f"{self.tecs.gated_samples} samples rejected by TECS as implausible",
                (f"setpoint roll {math.degrees(m.roll_body):+.1f} deg pitch "
                 f"{math.degrees(m.pitch_body):+.1f} deg throttle {m.thrust_body[0]:.2f}"),
                (f"L1 distance {self.l1.l1_distance_m:.1f} m xtrack "
                 f"{self.l1.crosstrack_error_m:+.1f} m")]

