"""TEST-ONLY stand-in for sensors + ekf2: publishes the estimator's topics from world truth.

It lets the controllers be developed and tested before the real estimator exists, with the same
topics and rates the real one uses: ``vehicle_angular_velocity`` at 1 kHz (the MPU6000 rate),
``vehicle_attitude`` at 250 Hz and ``vehicle_local_position`` at 100 Hz (with the reference
point, ref_lat/lon/alt, of the world's start point). Horizontal position is the map projection
of the true latitude/longitude around that reference, as an EKF fusing GPS computes it, so the
navigation frame of the test and of the controllers is the same.

This reads the world directly (a back door no firmware may use); it lives in tests/ for that
reason.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from firmware.modules.mc_pos_control.geo import MapProjection
from firmware.platform import Platform
from firmware.platform.workqueue import WorkItem
from common.truth import Truth
from common.units import G0_M_S2

__all__ = ["TruthEstimator"]



class TruthEstimator(WorkItem):
    """A 1 kHz work item copying truth into vehicle_angular_velocity/attitude/local_position."""

    def __init__(self, platform: Platform, truth: Callable[[], Truth],
                 ref: tuple[float, float, float], att_div: int = 4, pos_div: int = 10) -> None:
        super().__init__(platform, "truth_estimator", "wq:INS0")
        self.truth = truth
        orb = platform.orb
        self.pub_rate = orb.advertise("vehicle_angular_velocity")
        self.pub_att = orb.advertise("vehicle_attitude")
        self.pub_pos = orb.advertise("vehicle_local_position")
        self.m_rate = orb.new("vehicle_angular_velocity")
        self.m_att = orb.new("vehicle_attitude")
        self.m_pos = orb.new("vehicle_local_position")
        self.ref_lat, self.ref_lon, self.ref_alt = ref
        self.proj = MapProjection(self.ref_lat, self.ref_lon)
        self.att_div, self.pos_div = att_div, pos_div
        self.n = 0
        self.last_rate = (0.0, 0.0, 0.0)

    def start(self) -> None:
        self.schedule_on_interval(1000)

    def run(self) -> None:
        tr = self.truth()
        now = self.platform.hrt.absolute_time()
        t_s = tr.t_ns // 1000
        m = self.m_rate
        m.timestamp, m.timestamp_sample = now, t_s
        p, q, r = tr.gyro_rad_s
        lp, lq, lr = self.last_rate
        m.xyz[0], m.xyz[1], m.xyz[2] = p, q, r
        m.xyz_derivative[0], m.xyz_derivative[1], m.xyz_derivative[2] = \
            (p - lp) * 1000.0, (q - lq) * 1000.0, (r - lr) * 1000.0
        self.last_rate = (p, q, r)
        self.pub_rate.publish(m)
        self.n += 1
        if self.n % self.att_div == 0:
            a = self.m_att
            a.timestamp, a.timestamp_sample = now, t_s
            a.q[0], a.q[1], a.q[2], a.q[3] = tr.q_nb
            self.pub_att.publish(a)
        if self.n % self.pos_div == 0:
            self._publish_position(tr, now, t_s)

    def _publish_position(self, tr: Truth, now: int, t_s: int) -> None:
        lp = self.m_pos
        lp.timestamp, lp.timestamp_sample = now, t_s
        x, y = self.proj.project(tr.lat_deg, tr.lon_deg)
        lp.x, lp.y, lp.z = x, y, self.ref_alt - tr.alt_m
        lp.vx, lp.vy, lp.vz = tr.vel_ned_m_s
        lp.z_deriv = tr.vel_ned_m_s[2]
        # acceleration in NED = R(q) * specific force + gravity
        w, qx, qy, qz = tr.q_nb
        fx, fy, fz = tr.accel_body_m_s2
        tx = 2.0 * (qy * fz - qz * fy)
        ty = 2.0 * (qz * fx - qx * fz)
        tz = 2.0 * (qx * fy - qy * fx)
        lp.ax = fx + w * tx + (qy * tz - qz * ty)
        lp.ay = fy + w * ty + (qz * tx - qx * tz)
        lp.az = fz + w * tz + (qx * ty - qy * tx) + G0_M_S2
        lp.heading = tr.euler_rad[2]
        lp.xy_valid = lp.z_valid = lp.v_xy_valid = lp.v_z_valid = True
        lp.xy_global = lp.z_global = True
        lp.ref_timestamp = 1
        lp.ref_lat, lp.ref_lon, lp.ref_alt = self.ref_lat, self.ref_lon, self.ref_alt
        lp.dist_bottom = tr.agl_m
        lp.dist_bottom_valid = False  # the F450 has no range finder
        lp.eph, lp.epv, lp.evh, lp.evv = 0.5, 0.5, 0.1, 0.1
        lp.vxy_max = lp.vz_max = lp.hagl_min = lp.hagl_max = math.nan
        self.pub_pos.publish(lp)


# -- a flight rig: Sil + truth estimator + the control modules + a stub commander/navigator ------

#: The control modules by shell name (mc_rate_control is not in FMU_V2_MODULES yet).
CONTROL_MODULES = {
    "mc_rate_control": "firmware.modules.mc_rate_control:McRateControlModule",
    "mc_att_control": "firmware.modules.mc_att_control:McAttControlModule",
    "mc_pos_control": "firmware.modules.mc_pos_control:McPosControlModule",
    "land_detector": "firmware.modules.land_detector:LandDetectorModule",
}


class FlightRig:
    """World + FMU (no sensor drivers) + truth estimator + control modules + test-side stubs.

    The stubs publish what the commander and navigator will: ``actuator_armed``,
    ``vehicle_control_mode``, ``position_setpoint_triplet`` and ``manual_control_setpoint``.
    """

    def __init__(self, params: dict[str, float] | None = None, agl_m: float = 0.0,
                 modules: tuple[str, ...] = tuple(CONTROL_MODULES), seed: int = 0,
                 host_clock: Callable[[], float] | None = None) -> None:
        from firmware.platform.module import ModuleRegistry
        from firmware.platform.params import Params
        from firmware.system import System
        from hil.sil import Sil
        from hil.world import World

        self.sil = Sil(seed=seed, world=World(seed=seed, agl_m=agl_m), firmware="none")
        p = self.platform = self.sil.fmu.platform
        reg = ModuleRegistry(None, CONTROL_MODULES)
        self.params = Params(p, reg.param_defs(list(CONTROL_MODULES)))
        for k, v in (params or {}).items():
            self.params.set(k, v, notify=False)
        self.system = System(p, self.params, modules=reg, host_clock=host_clock)
        w = self.sil.world
        self.ref = (w._lat0, w._lon0, w._alt0)
        self.est = TruthEstimator(p, w.truth, self.ref)
        self.est.start()
        orb = p.orb
        self.pub_armed = orb.advertise("actuator_armed")
        self.pub_mode = orb.advertise("vehicle_control_mode")
        self.pub_trip = orb.advertise("position_setpoint_triplet")
        self.pub_man = orb.advertise("manual_control_setpoint")
        self.armed_msg = orb.new("actuator_armed")
        self.mode_msg = orb.new("vehicle_control_mode")
        self.trip_msg = orb.new("position_setpoint_triplet")
        self.man_msg = orb.new("manual_control_setpoint")
        for name in modules:
            if self.system.modules.start(name) != 0:
                raise RuntimeError(f"{name} did not start: {self.system.console_lines[-3:]}")
        if self.system.profiler is not None:
            self.system.profiler.attach(p)

    def host_seconds(self) -> dict[str, float]:
        """Host time spent in each work item's run() so far (needs ``host_clock``)."""
        prof = self.system.profiler
        out: dict[str, float] = {}
        if prof is None:
            return out
        for wq in self.platform.wq:
            for item in wq.items:
                s = prof.host_s(item)
                if s is not None:
                    out[item.name] = out.get(item.name, 0.0) + s
        return out

    # -- the stubs ---------------------------------------------------------------------------

    def now_us(self) -> int:
        return self.platform.hrt.absolute_time()

    def arm(self, armed: bool = True) -> None:
        m = self.armed_msg
        m.timestamp, m.armed, m.ready_to_arm = self.now_us(), armed, True
        self.pub_armed.publish(m)
        self.mode_msg.flag_armed = armed
        self.pub_mode.publish(self.mode_msg)

    def set_mode(self, mode: str) -> None:
        """``auto``, ``position``, ``altitude``, ``stabilized`` or ``acro`` control flags."""
        m = self.mode_msg
        m.timestamp = self.now_us()
        manual = mode in ("position", "altitude", "stabilized", "acro")
        m.flag_control_manual_enabled = manual
        m.flag_control_auto_enabled = mode == "auto"
        m.flag_control_rates_enabled = True
        m.flag_control_attitude_enabled = mode != "acro"
        pos = mode in ("auto", "position")
        alt = pos or mode == "altitude"
        m.flag_multicopter_position_control_enabled = pos
        m.flag_control_position_enabled = pos
        m.flag_control_velocity_enabled = pos
        m.flag_control_altitude_enabled = alt
        m.flag_control_climb_rate_enabled = alt
        m.flag_control_acceleration_enabled = False
        self.pub_mode.publish(m)

    def set_sticks(self, roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.0,
                   throttle: float = 0.0) -> None:
        m = self.man_msg
        m.timestamp = m.timestamp_sample = self.now_us()
        m.valid, m.data_source = True, 1
        m.roll, m.pitch, m.yaw, m.throttle = roll, pitch, yaw, throttle
        self.pub_man.publish(m)

    def set_setpoint(self, kind: int, north_m: float = 0.0, east_m: float = 0.0,
                     alt_rel_m: float = 0.0) -> None:
        """current = (type, local north/east from the reference, altitude above it)."""
        lat, lon = self.est.proj.reproject(north_m, east_m)
        m = self.trip_msg
        m.timestamp = self.now_us()
        c = m.current
        c.timestamp, c.valid, c.type = m.timestamp, True, kind
        c.lat, c.lon, c.alt = lat, lon, self.ref[2] + alt_rel_m
        c.yaw, c.yaw_valid = math.nan, False
        c.acceptance_radius, c.cruising_speed = 1.0, -1.0
        self.pub_trip.publish(m)

    def topic(self, name: str):
        return self.platform.orb.node(name).last

    def run(self, seconds: float, every: Callable[[FlightRig], None] | None = None,
            every_n: int = 10) -> None:
        """Run the closed loop; ``every`` is called each ``every_n`` world steps (ms)."""
        sil = self.sil
        steps = round(seconds * 1000)
        for i in range(steps):
            sil.step()
            if every is not None and i % every_n == 0:
                every(self)
