"""The ``ekf2`` module: attitude, velocity and position from IMU, baro, magnetometer and GPS.

Scheduling: a callback on ``sensor_combined`` (250 Hz). Every sample propagates the nominal state
(:meth:`Ekf.propagate`, plain floats) and publishes ``vehicle_attitude``; every EKF2_PREDICT_US
(10 ms, 100 Hz) the covariance is predicted and new baro, magnetometer and GPS data are fused,
then ``vehicle_local_position`` and ``vehicle_global_position`` are published;
``estimator_status`` and ``estimator_sensor_bias`` (the gyro and accelerometer biases, which
the sensors module removes from ``vehicle_angular_velocity``) at 10 Hz.

Start-up:

1. tilt alignment: 0.5 s of accelerometer data averaged gives roll and pitch (and, if the
   vehicle is still, the mean gyro rate initialises the gyro bias, 1-sigma 3 mrad/s);
2. yaw alignment: the tilt-compensated magnetometer heading plus EKF2_MAG_DECL (east positive);
   the local height datum is the first baro altitude (z = 0 there);
3. until GPS is used, a "fake" position fusion (0.5 m, 5 Hz) holds the horizontal position,
   which keeps the tilt observable while the vehicle stands still;
4. GPS: after the receiver meets the EKF2_REQ_* checks continuously for EKF2_REQ_GPS_H, the
   origin (ref_lat/lon) is the GPS position, ref_alt the GPS altitude of z = 0, position and
   velocity are reset to GPS and GPS velocity and position are fused from then on.

Innovation checks: each measurement's test ratio is innovation^2 / (gate^2 * S); above 1 it is
rejected, its bit set in ``innovation_check_flags`` and a warning goes to dmesg (once per run of
rejections).

Resets (each counted in estimator_status.reset_count_* and logged):

* GPS position (velocity) rejected or not fused for EKF2_NOAID_TOUT while GPS is good: the
  horizontal position (velocity) is reset to GPS -- the way out after a GPS jump that was real;
* baro height rejected for EKF2_NOAID_TOUT: height reset to the baro height;
* GPS lost for EKF2_NOAID_TOUT: GPS fusion stops (dead reckoning is flagged meanwhile), the
  position is held by fake fusion, and GPS restarts after passing its checks again (position
  and velocity reset to it, the origin is kept);
* a numerical fault (non-finite variance): the covariance is re-initialised and
  ``filter_fault_flags`` says so;
* the alignment itself is the first quaternion reset (``quat_reset_counter``).
"""

from __future__ import annotations

import math
from typing import Any, Final

from firmware.modules.ekf2.aiding import (
    INNOV_HGT,
    INNOV_POS_NE,
    INNOV_VEL_D,
    INNOV_VEL_NE,
    INNOV_YAW,
    AidSource,
    PreflightChecks,
)
from firmware.modules.ekf2.core import I_POS, I_THETA, I_VEL, Ekf, NoiseParams
from firmware.modules.ekf2.gps import GpsChecks, LocalProjection
from firmware.modules.ekf2.params import PARAMS
from common.quaternion import Quat, dcm, q_from_euler, q_to_euler, q_yaw, wrap_pi
from firmware.modules.ekf2.status import fill_estimator_status
from firmware.platform.module import WorkItemModule
from common.units import G0_M_S2

__all__ = ["Ekf2Module"]

_DEFAULTS: Final = {d.name: d.default for d in PARAMS}
ALIGN_US: Final = 500_000
#: the vehicle counts as still during alignment if no gyro sample exceeds this
STILL_RATE_RAD_S: Final = 0.03
STILL_BIAS_SIGMA: Final = 0.003
FAKE_POS_INTERVAL_US: Final = 200_000
FAKE_POS_NOISE_M: Final = 0.5
STATUS_INTERVAL_US: Final = 100_000
#: no GPS fusion for this long: dead reckoning (flag); no baro for this long: height timeout
DEAD_RECKONING_US: Final = 1_000_000
BARO_TIMEOUT_US: Final = 1_000_000


class Ekf2Module(WorkItemModule):
    NAME = "ekf2"
    DESCRIPTION = "Extended Kalman filter: attitude, velocity, position (IMU, baro, mag, GPS)"
    PARAMS = PARAMS
    WQ = "wq:INS1"
    #: modelled STM32F427 time: an IMU-rate output step, and a 100 Hz filter update (PX4's
    #: ekf2 takes a few hundred microseconds per update on an F4)
    CPU_COST_NS = 30_000
    COST_UPDATE_NS = 400_000

    def _start(self) -> None:
        orb = self.platform.orb
        item = self.work_item
        assert item is not None
        self._imu_sub = self.subscribe_callback(item, "sensor_combined")
        self._air_sub = self.subscribe("vehicle_air_data")
        self._mag_sub = self.subscribe("vehicle_magnetometer")
        self._gps_sub = self.subscribe("sensor_gps")
        self._param_sub = self.subscribe("parameter_update")
        self._pub_att = self.advertise("vehicle_attitude")
        self._pub_lpos = self.advertise("vehicle_local_position")
        self._pub_gpos = self.advertise("vehicle_global_position")
        self._pub_status = self.advertise("estimator_status")
        self._pub_bias = self.advertise("estimator_sensor_bias")
        self._m_bias = orb.new("estimator_sensor_bias")
        self._m_att = orb.new("vehicle_attitude")
        self._m_lpos = orb.new("vehicle_local_position")
        self._m_gpos = orb.new("vehicle_global_position")
        self._m_status = orb.new("estimator_status")
        self.perf_update = self.perf_alloc("interval", "update")
        self.noise = NoiseParams()
        self.ekf = Ekf(self.noise)
        self._load_params()
        self.ekf.init_covariance()
        self.gps_checks = GpsChecks()
        self.proj = LocalProjection()
        self.preflight = PreflightChecks()
        self.src_vel = AidSource("GPS velocity")
        self.src_vel_d = AidSource("GPS vertical velocity")
        self.src_pos = AidSource("GPS position")
        self.src_hgt = AidSource("baro height")
        self.src_yaw = AidSource("mag heading")
        self.tilt_aligned = False
        self.yaw_aligned = False
        self.gps_in_use = False
        self.mag_disturbed = False
        self.ref_alt = 0.0
        self.ref_timestamp = 0
        self.geoid_sep_m = 0.0
        self.baro_offset: float | None = None
        self._align = [0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0]  # n, a(3), g(3), max|g|, t0
        self._align_accel_id = -1
        self._mag_ref: tuple[float, float] | None = None  # strength, inclination at alignment
        self._last_mag: Any = None
        self._hold = (0.0, 0.0)
        self._next_fake = 0
        self._next_status = 0
        self._t = 0
        self._last_gps_us = -1
        self._last_baro_us = -1
        self.innov_flags = 0
        self.resets = {"vel_ne": 0, "vel_d": 0, "pos_ne": 0, "pos_d": 0, "quat": 0}
        self._q_reset_delta: Quat = (1.0, 0.0, 0.0, 0.0)
        self._faults = 0
        self._ids = [0, 0, 0, 0]  # accel, gyro, baro, mag device ids
        self._updates = 0

    def _load_params(self) -> None:
        params = self.system.params

        def get(name: str) -> float:
            return params[name] if params is not None and name in params else _DEFAULTS[name]

        self.p = {name: get(name) for name in _DEFAULTS}
        n = self.noise
        n.gyro = self.p["EKF2_GYR_NOISE"]
        n.accel = self.p["EKF2_ACC_NOISE"]
        n.gyro_bias = self.p["EKF2_GYR_B_NOISE"]
        n.accel_bias = self.p["EKF2_ACC_B_NOISE"]
        n.gyro_bias_init = self.p["EKF2_GBIAS_INIT"]
        n.accel_bias_init = self.p["EKF2_ABIAS_INIT"]
        n.tilt_init = self.p["EKF2_ANGERR_INIT"]
        self.ekf.set_noise(n)
        self._predict_us = int(self.p["EKF2_PREDICT_US"])
        self._decl = math.radians(self.p["EKF2_MAG_DECL"])

    # -- the work item ---------------------------------------------------------------------------

    def run(self) -> None:
        item = self.work_item
        assert item is not None
        item.cpu_cost_ns = self.CPU_COST_NS
        if self._param_sub.updated():
            self._param_sub.copy()
            self._load_params()
        imu = self._imu_sub.update()
        if imu is None:
            return
        dt_us = imu.gyro_integral_dt
        if not 0 < dt_us <= 50_000:
            return
        dt = dt_us * 1e-6
        g = imu.gyro_rad
        a = imu.accelerometer_m_s2
        t = imu.timestamp
        self._t = t
        self._ids[0], self._ids[1] = imu.accel_device_id, imu.gyro_device_id
        if not self.tilt_aligned:
            self._align_step(g, a, t)
            return
        ekf = self.ekf
        ekf.propagate(g[0], g[1], g[2], a[0], a[1], a[2], dt, t)
        self._publish_attitude(t)
        if ekf.pending_dt * 1e6 >= self._predict_us - dt_us // 2:
            item.cpu_cost_ns += self.COST_UPDATE_NS
            self._update(t)

    # -- alignment ---------------------------------------------------------------------------------

    def _align_step(self, g: list[float], a: list[float], t: int) -> None:
        al = self._align
        if self._ids[0] != self._align_accel_id:  # the accelerometer changed: start again
            self._align_accel_id = self._ids[0]
            al[:] = [0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0]
        if al[0] == 0:
            al[8] = t
        al[0] += 1
        al[1] += a[0]
        al[2] += a[1]
        al[3] += a[2]
        al[4] += g[0]
        al[5] += g[1]
        al[6] += g[2]
        al[7] = max(al[7], abs(g[0]), abs(g[1]), abs(g[2]))
        mag = self._mag_sub.update() or self._last_mag
        self._last_mag = mag
        use_mag = int(self.p["EKF2_MAG_TYPE"]) != 5
        if t - al[8] < ALIGN_US or (use_mag and mag is None):
            return
        n = al[0]
        ax, ay, az = al[1] / n, al[2] / n, al[3] / n
        if abs(math.sqrt(ax * ax + ay * ay + az * az) - G0_M_S2) > 2.0:
            al[:] = [0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0]  # not at rest: again
            return
        roll = math.atan2(-ay, -az)
        pitch = math.atan2(ax, math.sqrt(ay * ay + az * az))
        yaw = 0.0
        ekf = self.ekf
        if use_mag:
            m = mag.magnetometer_ga
            r = dcm(q_from_euler(roll, pitch, 0.0))
            mn = r[0] * m[0] + r[1] * m[1] + r[2] * m[2]
            me = r[3] * m[0] + r[4] * m[1] + r[5] * m[2]
            md = r[6] * m[0] + r[7] * m[1] + r[8] * m[2]
            yaw = wrap_pi(self._decl - math.atan2(me, mn))
            self._mag_ref = (math.sqrt(mn * mn + me * me + md * md),
                             math.atan2(md, math.hypot(mn, me)))
            self.yaw_aligned = True
        q = q_from_euler(roll, pitch, yaw)
        ekf.set_attitude(q)
        ekf.init_covariance()
        if use_mag:
            ekf.P[I_THETA + 2, I_THETA + 2] = self.p["EKF2_HEAD_NOISE"] ** 2
        if al[7] < STILL_RATE_RAD_S:
            # still: the mean rate over the alignment is the gyro bias (plus the earth's
            # rate, 7e-5 rad/s), known to the noise over ~125 samples
            ekf.bgx, ekf.bgy, ekf.bgz = al[4] / n, al[5] / n, al[6] / n
            for i in range(9, 12):
                ekf.P[i, i] = STILL_BIAS_SIGMA ** 2
        self.tilt_aligned = True
        self.resets["quat"] += 1
        self._q_reset_delta = q
        self._next_fake = t
        self.info(f"tilt aligned (roll {math.degrees(roll):.1f}, pitch "
                  f"{math.degrees(pitch):.1f} deg), yaw {math.degrees(yaw):.1f} deg "
                  f"{'from mag' if use_mag else 'unknown (no mag)'}")

    # -- the 100 Hz filter update -------------------------------------------------------------------

    def _update(self, t: int) -> None:
        ekf = self.ekf
        self.perf_update.count()
        ekf.predict_covariance()
        self._updates += 1
        air = self._air_sub.update()
        if air is not None:
            self._fuse_baro(air, t)
        mag = self._mag_sub.update()
        if mag is not None:
            self._fuse_heading(mag, t)
        gps = self._gps_sub.update()
        if gps is not None:
            self._on_gps(gps, t)
        if self.gps_in_use and self.src_pos.since_fused_us(t) > self.p["EKF2_NOAID_TOUT"] \
                and self.src_vel.since_fused_us(t) > self.p["EKF2_NOAID_TOUT"]:
            self.gps_in_use = False
            self._hold = (ekf.pn, ekf.pe)
            self.warn("GPS fusion stopped: no usable GPS data, holding position")
        if not self.gps_in_use and t >= self._next_fake:
            self._next_fake = t + FAKE_POS_INTERVAL_US
            var = FAKE_POS_NOISE_M ** 2
            ekf.fuse(I_POS, self._hold[0] - ekf.pn, var)
            ekf.fuse(I_POS + 1, self._hold[1] - ekf.pe, var)
            ekf.inject()
        if ekf.fused:  # the prediction was conditioned already; only a fusion needs it again
            ekf.condition()
        self._faults |= ekf.fault
        ekf.fault = 0
        self._publish_position(t)
        if t >= self._next_status:
            self._next_status = t + STATUS_INTERVAL_US
            self._publish_status(t)

    def _fuse_baro(self, air: Any, t: int) -> None:
        ekf = self.ekf
        self._ids[2] = air.baro_device_id
        h = air.baro_alt_meter
        if self.baro_offset is None:
            self.baro_offset = h + ekf.pd
        meas = self.baro_offset - h  # down, m
        ts = air.timestamp_sample - int(self.p["EKF2_BARO_DELAY"] * 1000)
        innov = meas - ekf.at(ts)[2]
        var = self.p["EKF2_BARO_NOISE"] ** 2
        ratio = ekf.test_ratio(I_POS + 2, innov, var, self.p["EKF2_BARO_GATE"])
        src = self.src_hgt
        src.innov = innov
        src.active = True
        self._last_baro_us = t
        self.preflight.hgt_innov(innov, 0.05)
        if ratio <= 1.0:
            ekf.fuse(I_POS + 2, innov, var)
            ekf.inject()
            src.accepted(t, ratio)
            self.innov_flags &= ~INNOV_HGT
            return
        self.innov_flags |= INNOV_HGT
        if src.reject(t, ratio):
            self.warn(f"baro height rejected, test ratio {ratio:.1f}")
        if src.rejected_for_us(t) > self.p["EKF2_NOAID_TOUT"]:
            ekf.reset_height(meas, var)
            self.resets["pos_d"] += 1
            src.accepted(t, 0.0)
            self.info("height reset to baro")

    def _fuse_heading(self, mag: Any, t: int) -> None:
        self._last_mag = mag
        self._ids[3] = mag.device_id
        if int(self.p["EKF2_MAG_TYPE"]) == 5:
            self.src_yaw.active = False
            return
        ekf = self.ekf
        m = mag.magnetometer_ga
        r = ekf.R
        mn = r[0] * m[0] + r[1] * m[1] + r[2] * m[2]
        me = r[3] * m[0] + r[4] * m[1] + r[5] * m[2]
        md = r[6] * m[0] + r[7] * m[1] + r[8] * m[2]
        # field checks against the field seen at alignment
        disturbed = False
        if self._mag_ref is not None and int(self.p["EKF2_MAG_CHECK"]):
            strength = math.sqrt(mn * mn + me * me + md * md)
            incl = math.atan2(md, math.hypot(mn, me))
            disturbed = (abs(strength - self._mag_ref[0]) > self.p["EKF2_MAG_CHK_STR"] or
                         abs(incl - self._mag_ref[1]) > math.radians(self.p["EKF2_MAG_CHK_INC"]))
        if disturbed != self.mag_disturbed:
            self.mag_disturbed = disturbed
            if disturbed:
                self.warn("magnetic field disturbed: heading fusion stopped")
            else:
                self.info("magnetic field back to normal: heading fusion resumed")
        ts = mag.timestamp_sample - int(self.p["EKF2_MAG_DELAY"] * 1000)
        # the yaw the measurement implies, compared at the measurement's time (see core docs)
        innov = wrap_pi(self._decl - math.atan2(me, mn) + q_yaw(ekf.q) - ekf.at(ts)[6])
        var = self.p["EKF2_HEAD_NOISE"] ** 2
        ratio = ekf.test_ratio(I_THETA + 2, innov, var, self.p["EKF2_HDG_GATE"])
        src = self.src_yaw
        src.innov = innov
        src.active = not disturbed
        self.preflight.heading_innov(innov, 1.0 / 15.0)
        if ratio <= 1.0 and not disturbed:
            ekf.fuse(I_THETA + 2, innov, var)
            ekf.inject()
            src.accepted(t, ratio)
            self.innov_flags &= ~INNOV_YAW
            return
        self.innov_flags |= INNOV_YAW
        if src.reject(t, ratio) and not disturbed:
            self.warn(f"mag heading rejected, test ratio {ratio:.1f}")
        elif disturbed:
            src.test_ratio = max(ratio, 1.0 + 1e-6)

    # -- GPS -----------------------------------------------------------------------------------------

    def _on_gps(self, gps: Any, t: int) -> None:
        p = self.p
        self._last_gps_us = t
        fails = self.gps_checks.update(gps, t, int(p["EKF2_GPS_CHECK"]), p["EKF2_REQ_EPH"],
                                       p["EKF2_REQ_EPV"], p["EKF2_REQ_SACC"],
                                       int(p["EKF2_REQ_NSATS"]), p["EKF2_REQ_PDOP"])
        ts = gps.timestamp_sample - int(p["EKF2_GPS_DELAY"] * 1000)
        if not self.gps_in_use:
            if fails or self.gps_checks.passed_for_us(t) < p["EKF2_REQ_GPS_H"] * 1e6:
                return
            self._start_gps(gps, ts, t)
            return
        if gps.fix_type < 3:
            return  # nothing to fuse; the no-aiding timeout stops GPS use if it lasts
        ekf = self.ekf
        hist = ekf.at(ts)
        ctrl = int(p["EKF2_GPS_CTRL"])
        flags = self.innov_flags
        if ctrl & 4 and gps.vel_ned_valid:
            var = max(gps.s_variance_m_s, p["EKF2_GPS_V_NOISE"]) ** 2
            gate = p["EKF2_GPS_V_GATE"]
            i_n, i_e, i_d = (gps.vel_n_m_s - hist[3], gps.vel_e_m_s - hist[4],
                             gps.vel_d_m_s - hist[5])
            self.preflight.vel_innov(i_n, i_e, i_d, 0.2)
            r_h = max(ekf.test_ratio(I_VEL, i_n, var, gate),
                      ekf.test_ratio(I_VEL + 1, i_e, var, gate))
            r_d = ekf.test_ratio(I_VEL + 2, i_d, var * 2.25, gate)
            self.src_vel.innov = math.hypot(i_n, i_e)
            self.src_vel_d.innov = i_d
            if r_h <= 1.0:
                ekf.fuse(I_VEL, i_n, var)
                ekf.fuse(I_VEL + 1, i_e, var)
                self.src_vel.accepted(t, r_h)
                flags &= ~INNOV_VEL_NE
            else:
                flags |= INNOV_VEL_NE
                if self.src_vel.reject(t, r_h):
                    self.warn(f"GPS velocity rejected, test ratio {r_h:.1f}")
            if r_d <= 1.0:
                ekf.fuse(I_VEL + 2, i_d, var * 2.25)
                self.src_vel_d.accepted(t, r_d)
                flags &= ~INNOV_VEL_D
            else:
                flags |= INNOV_VEL_D
                if self.src_vel_d.reject(t, r_d):
                    self.warn(f"GPS vertical velocity rejected, test ratio {r_d:.1f}")
        if ctrl & 1:
            var = max(gps.eph, p["EKF2_GPS_P_NOISE"]) ** 2
            gate = p["EKF2_GPS_P_GATE"]
            pn, pe = self.proj.project(gps.latitude_deg, gps.longitude_deg)
            i_n, i_e = pn - hist[0], pe - hist[1]
            r = max(ekf.test_ratio(I_POS, i_n, var, gate),
                    ekf.test_ratio(I_POS + 1, i_e, var, gate))
            self.src_pos.innov = math.hypot(i_n, i_e)
            if r <= 1.0:
                ekf.fuse(I_POS, i_n, var)
                ekf.fuse(I_POS + 1, i_e, var)
                self.src_pos.accepted(t, r)
                flags &= ~INNOV_POS_NE
            else:
                flags |= INNOV_POS_NE
                if self.src_pos.reject(t, r):
                    self.warn(f"GPS position rejected, test ratio {r:.1f} "
                              f"(innovation {math.hypot(i_n, i_e):.1f} m)")
        self.innov_flags = flags
        ekf.inject()
        tout = p["EKF2_NOAID_TOUT"]
        if not fails:
            if self.src_pos.rejected_for_us(t) > tout:
                pn, pe = self.proj.project(gps.latitude_deg, gps.longitude_deg)
                ekf.reset_position_ne(pn + ekf.pn - hist[0], pe + ekf.pe - hist[1],
                                      max(gps.eph, p["EKF2_GPS_P_NOISE"]) ** 2)
                self.resets["pos_ne"] += 1
                self.src_pos.accepted(t, 0.0)
                self.innov_flags &= ~INNOV_POS_NE
                self.warn("GPS position rejected for too long: position reset to GPS")
            if self.src_vel.rejected_for_us(t) > tout:
                ekf.reset_velocity_ne(gps.vel_n_m_s, gps.vel_e_m_s,
                                      max(gps.s_variance_m_s, p["EKF2_GPS_V_NOISE"]) ** 2)
                self.resets["vel_ne"] += 1
                self.src_vel.accepted(t, 0.0)
                self.innov_flags &= ~INNOV_VEL_NE
                self.warn("GPS velocity rejected for too long: velocity reset to GPS")

    def _start_gps(self, gps: Any, ts: int, t: int) -> None:
        ekf = self.ekf
        hist = ekf.at(ts)
        first = not self.proj.valid
        if first:
            self.proj.init(gps.latitude_deg, gps.longitude_deg)
            self.ref_alt = gps.altitude_msl_m + hist[2]
            self.geoid_sep_m = gps.altitude_ellipsoid_m - gps.altitude_msl_m
            self.ref_timestamp = t
        pn, pe = self.proj.project(gps.latitude_deg, gps.longitude_deg)
        p = self.p
        ekf.reset_position_ne(pn + ekf.pn - hist[0], pe + ekf.pe - hist[1],
                              max(gps.eph, p["EKF2_GPS_P_NOISE"]) ** 2)
        vvar = max(gps.s_variance_m_s, p["EKF2_GPS_V_NOISE"]) ** 2
        if gps.vel_ned_valid:
            ekf.reset_velocity_ne(gps.vel_n_m_s, gps.vel_e_m_s, vvar)
            ekf.reset_velocity_d(gps.vel_d_m_s, vvar)
            self.resets["vel_ne"] += 1
            self.resets["vel_d"] += 1
        self.resets["pos_ne"] += 1
        self.gps_in_use = True
        for src in (self.src_pos, self.src_vel, self.src_vel_d):
            src.accepted(t, 0.0)
            src.active = True
        if first:
            self.info(f"GPS checks passed: origin set to {gps.latitude_deg:.7f} "
                      f"{gps.longitude_deg:.7f}, {self.ref_alt:.1f} m AMSL; fusing GPS")
        else:
            self.info("GPS checks passed: GPS fusion resumed, position reset to GPS")

    # -- outputs ---------------------------------------------------------------------------------

    def _publish_attitude(self, t: int) -> None:
        m = self._m_att
        m.timestamp = self.platform.time_us()
        m.timestamp_sample = t
        q = m.q
        q[0], q[1], q[2], q[3] = self.ekf.q
        d = m.delta_q_reset
        d[0], d[1], d[2], d[3] = self._q_reset_delta
        m.quat_reset_counter = self.resets["quat"] & 0xFF
        self._pub_att.publish(m)

    def _publish_position(self, t: int) -> None:
        ekf = self.ekf
        d = ekf.P.diagonal().tolist()
        var_vn, var_ve, var_vd, var_pn, var_pe, var_pd = d[3:9]
        m = self._m_lpos
        m.timestamp = self.platform.time_us()
        m.timestamp_sample = t
        dr = self.gps_in_use and min(self.src_pos.since_fused_us(t),
                                     self.src_vel.since_fused_us(t)) > DEAD_RECKONING_US
        m.xy_valid = m.v_xy_valid = self.gps_in_use
        z_ok = self.baro_offset is not None and t - self._last_baro_us < BARO_TIMEOUT_US
        m.z_valid = m.v_z_valid = z_ok
        m.x, m.y, m.z = ekf.pn, ekf.pe, ekf.pd
        m.vx, m.vy, m.vz = ekf.vn, ekf.ve, ekf.vd
        m.z_deriv = ekf.vd
        m.ax, m.ay, m.az = ekf.acc_ned
        m.heading = q_yaw(ekf.q)
        m.xy_global = m.z_global = self.proj.valid
        m.ref_timestamp = self.ref_timestamp
        m.ref_lat, m.ref_lon, m.ref_alt = self.proj.lat0, self.proj.lon0, self.ref_alt
        m.dist_bottom = -ekf.pd
        m.dist_bottom_valid = z_ok
        m.eph = eph = math.sqrt(var_pn + var_pe)
        m.epv = epv = math.sqrt(var_pd)
        m.evh = math.sqrt(var_vn + var_ve)
        m.evv = math.sqrt(var_vd)
        m.dead_reckoning = dr
        m.vxy_max = m.vz_max = m.hagl_min = m.hagl_max = math.nan
        self._pub_lpos.publish(m)
        if not self.proj.valid:
            return
        g = self._m_gpos
        g.timestamp = m.timestamp
        g.timestamp_sample = t
        g.lat, g.lon = self.proj.reproject(ekf.pn, ekf.pe)
        g.alt = self.ref_alt - ekf.pd
        g.alt_ellipsoid = g.alt + self.geoid_sep_m
        g.eph, g.epv = eph, epv
        g.terrain_alt = self.ref_alt
        g.terrain_alt_valid = True
        g.dead_reckoning = dr
        self._pub_gpos.publish(g)

    def _publish_status(self, t: int) -> None:
        fill_estimator_status(self, self._m_status, t)
        self._faults = 0
        self._pub_status.publish(self._m_status)
        ekf = self.ekf
        d = ekf.P.diagonal().tolist()
        b = self._m_bias
        b.timestamp = self._m_status.timestamp
        b.timestamp_sample = t
        b.gyro_device_id, b.accel_device_id = self._ids[1], self._ids[0]
        b.gyro_bias[:] = [ekf.bgx, ekf.bgy, ekf.bgz]
        b.gyro_bias_variance[:] = d[9:12]
        b.accel_bias[:] = [ekf.bax, ekf.bay, ekf.baz]
        b.accel_bias_variance[:] = d[12:15]
        # trusted once the filter has had time to learn them (1-sigma below 5 mrad/s)
        b.gyro_bias_valid = self.tilt_aligned and max(d[9:12]) < 0.005 ** 2
        b.accel_bias_valid = self.tilt_aligned and max(d[12:15]) < 0.1 ** 2
        self._pub_bias.publish(b)

    def status_lines(self) -> list[str]:
        ekf = self.ekf
        out = [(f"aligned: tilt {self.tilt_aligned}, yaw {self.yaw_aligned}; GPS in use "
                f"{self.gps_in_use}; {self._updates} filter updates")]
        if self.tilt_aligned:
            r, pch, y = (math.degrees(v) for v in q_to_euler(ekf.q))
            out.append(f"attitude roll {r:.2f} pitch {pch:.2f} yaw {y:.2f} deg")
            out.append(f"pos {ekf.pn:.2f} {ekf.pe:.2f} {ekf.pd:.2f} m, vel {ekf.vn:.2f} "
                       f"{ekf.ve:.2f} {ekf.vd:.2f} m/s")
            out.append(f"gyro bias {ekf.bgx:.4f} {ekf.bgy:.4f} {ekf.bgz:.4f} rad/s, accel bias "
                       f"{ekf.bax:.3f} {ekf.bay:.3f} {ekf.baz:.3f} m/s^2")
        for src in (self.src_vel, self.src_vel_d, self.src_pos, self.src_hgt, self.src_yaw):
            out.append(f"{src.name}: test ratio {src.test_ratio:.2f}, "
                       f"{'REJECTED' if src.rejected else 'ok'}, {src.rejections} rejections")
        out.append(f"resets {self.resets}")
        return out

