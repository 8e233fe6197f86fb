"""The ``sensors`` module: calibrated, voted sensor data for the controllers and the estimator.

It does in one work item what PX4 spreads over ``sensors``, ``VehicleAngularVelocity``,
``VehicleIMU``, ``VehicleAirData`` and ``VehicleMagnetometer``, because on the host one work
item run is the unit of cost:

* the item wakes on the *selected* gyro (callback subscription, moved with the selection) once
  ``round(IMU_GYRO_RATEMAX interval / gyro interval)`` samples are queued (PX4's rule: one
  for the MPU6000, whose FIFO is read at the same limit, three for a 1 kHz gyro at the
  default 400 Hz), and from a 10 ms HRT watchdog only if no run
  happened for 10 ms (a silent gyro is still noticed);
* each run walks the gyro and accelerometer queues sample by sample: calibration, rotation,
  the IMU_GYRO_CUTOFF low-pass and the derivative at the full raw rate;
  ``vehicle_angular_velocity`` is published from the last sample, at most every
  RATEMAX interval less half a sample (the rate controller's loop rate). ``sensor_combined``
  closes every 1/IMU_INTEG_RATE (4 ms) at the gyro sample that completes it, with the
  accelerometer samples up to that time (250 Hz whatever the wake-up rate), as does
  ``vehicle_acceleration``;
* the selected barometer and magnetometer are averaged over 1/SENS_BARO_RATE and
  1/SENS_MAG_RATE into ``vehicle_air_data`` (ISA altitude from SENS_BARO_QNH) and
  ``vehicle_magnetometer``;
* every 10 ms the :class:`SensorGroup` voters look at every instance (timeout, frozen data,
  disagreement), select, fail over (``[sensors] gyro #0 failed, switching to #1`` in dmesg) and
  ``sensors_status_*`` are published (every 100 ms and on a change).

``sensors_status_imu`` instance 0 describes the gyros and instance 1 the accelerometers (the
message has one set of per-sensor fields; gyro and accel are voted independently, as in PX4
before vehicle_imu). The gyro bias ekf2 estimates (``estimator_sensor_bias``) is removed from
``vehicle_angular_velocity`` when it belongs to the selected gyro.
"""

from __future__ import annotations

import math
from typing import Any, Final

from firmware.modules.sensors.calibration import Calibration, board_rotation
from firmware.modules.sensors.filters import LowPass2p3
from firmware.modules.sensors.params import N_ACCEL_CAL, N_BARO_CAL, N_GYRO_CAL, N_MAG_CAL, PARAMS
from firmware.modules.sensors.voter import Event, SensorGroup
from firmware.platform.module import WorkItemModule
from firmware.platform.uorb import ORB_MULTI_MAX_INSTANCES, SubscriptionCallback

__all__ = ["SensorsModule", "isa_altitude_m"]

#: health checks and watchdog wake-up, us
CHECK_INTERVAL_US: Final = 10_000
STATUS_INTERVAL_US: Final = 100_000
#: magnetometers and barometers are looked at every 5th check (50 ms)
SLOW_CHECK_DIVIDER: Final = 5
#: timeouts (PX4 treats an IMU silent for 20 ms as failed; baro and mag are slower sensors)
IMU_TIMEOUT_US: Final = 20_000
BARO_TIMEOUT_US: Final = 300_000
MAG_TIMEOUT_US: Final = 300_000
#: disagreement thresholds for failover, twice PX4's pre-arm limits (COM_ARM_IMU_GYR 0.25 rad/s,
#: COM_ARM_IMU_ACC 0.7 m/s^2, COM_ARM_MAG_ANG 45 deg); baro in Pa (~ 25 m)
GYRO_LIMIT_RAD_S: Final = 0.5
ACCEL_LIMIT_M_S2: Final = 1.4
MAG_LIMIT_RAD: Final = math.radians(45.0)
BARO_LIMIT_PA: Final = 300.0

_T0_K: Final = 288.15
_LAPSE_K_M: Final = 0.0065
_ISA_EXP: Final = 0.190263          # R L / (g M) of the ISA troposphere
_R_AIR: Final = 287.05              # J/(kg K)
_KELVIN: Final = 273.15


_DEFAULTS: Final = {d.name: d.default for d in PARAMS}


def isa_altitude_m(pressure_pa: float, qnh_pa: float = 101325.0) -> float:
    """Altitude of a static pressure in the ISA troposphere, referenced to ``qnh_pa``."""
    return _T0_K / _LAPSE_K_M * (1.0 - (pressure_pa / qnh_pa) ** _ISA_EXP)


def _xyz(msg: Any) -> tuple[float, float, float]:
    return msg.x, msg.y, msg.z


def _baro(msg: Any) -> tuple[float, float]:
    return msg.pressure, msg.temperature


def _clips(msg: Any) -> bool:
    c = msg.clip_counter
    return bool(c[0] or c[1] or c[2])


class SensorsModule(WorkItemModule):
    NAME = "sensors"
    DESCRIPTION = ("Sensor hub: calibration, board rotation, redundancy voting and failover, "
                   "vehicle_angular_velocity, sensor_combined, vehicle_air_data, "
                   "vehicle_magnetometer")
    PARAMS = PARAMS
    WQ = "wq:INS0"
    #: modelled STM32F427 time of a run that handles one gyro sample (calibrate, filter,
    #: publish); runs that also integrate/vote/average cost more (set per run)
    CPU_COST_NS = 18_000
    #: each further gyro sample of a run (calibrate and filter, no publication)
    COST_SAMPLE_NS = 8_000
    COST_COMBINED_NS = 30_000
    COST_CHECK_NS = 25_000

    # -- start / stop ------------------------------------------------------------------------

    def _start(self) -> None:
        orb = self.platform.orb
        item = self.work_item
        assert item is not None
        n = ORB_MULTI_MAX_INSTANCES
        self._gyro_cbs = [SubscriptionCallback(item, orb, "sensor_gyro", i) for i in range(n)]
        self.subscriptions.extend(self._gyro_cbs)
        self._accel_subs = [self.subscribe("sensor_accel", i) for i in range(n)]
        self._mag_subs = [self.subscribe("sensor_mag", i) for i in range(n)]
        self._baro_subs = [self.subscribe("sensor_baro", i) for i in range(n)]
        self._param_sub = self.subscribe("parameter_update")
        self._bias_sub = self.subscribe("estimator_sensor_bias")
        self._gyro_cals = [Calibration("GYRO", N_GYRO_CAL) for _ in range(n)]
        self._accel_cals = [Calibration("ACC", N_ACCEL_CAL) for _ in range(n)]
        self._mag_cals = [Calibration("MAG", N_MAG_CAL) for _ in range(n)]
        self._baro_cals = [Calibration("BARO", N_BARO_CAL) for _ in range(n)]
        self.gyro = SensorGroup("gyro", [s.node for s in self._gyro_cbs], self._gyro_cals, _xyz,
                                IMU_TIMEOUT_US, 20, GYRO_LIMIT_RAD_S)
        self.accel = SensorGroup("accel", [s.node for s in self._accel_subs], self._accel_cals,
                                 _xyz, IMU_TIMEOUT_US, 20, ACCEL_LIMIT_M_S2)
        self.mag = SensorGroup("mag", [s.node for s in self._mag_subs], self._mag_cals, _xyz,
                               MAG_TIMEOUT_US, 10, MAG_LIMIT_RAD, angle_limit=True)
        self.baro = SensorGroup("baro", [s.node for s in self._baro_subs], self._baro_cals,
                                _baro, BARO_TIMEOUT_US, 20, BARO_LIMIT_PA)
        self._groups = (self.gyro, self.accel, self.mag, self.baro)

        self._pub_avel = self.advertise("vehicle_angular_velocity")
        self._pub_acc = self.advertise("vehicle_acceleration")
        self._pub_comb = self.advertise("sensor_combined")
        self._pub_air = self.advertise("vehicle_air_data")
        self._pub_mag = self.advertise("vehicle_magnetometer")
        self._pub_status = {"gyro": self.advertise("sensors_status_imu", 0),
                            "accel": self.advertise("sensors_status_imu", 1),
                            "mag": self.advertise("sensors_status_mag"),
                            "baro": self.advertise("sensors_status_baro")}
        self._m_avel = orb.new("vehicle_angular_velocity")
        self._m_acc = orb.new("vehicle_acceleration")
        self._m_comb = orb.new("sensor_combined")
        self._m_air = orb.new("vehicle_air_data")
        self._m_mag = orb.new("vehicle_magnetometer")
        self._m_status = orb.new("sensors_status_imu")
        self.perf_combined = self.perf_alloc("interval", "sensor_combined")
        self.perf_failover = self.perf_alloc("count", "failovers")

        # gyro pipeline state (the selected gyro)
        self._gyro_idx = 0
        self._gyro_cbs[0].register_callback()
        self._lpf = LowPass2p3(1000.0, 40.0)
        self._gyro_t = -1
        self._gyro_dt_avg = 1000.0
        self._rate_unknown = True
        self._filter_primed = False
        self._avel_last_us = 0          # timestamp_sample of the last vehicle_angular_velocity
        self._avel_interval_us = 0      # its minimum interval (from IMU_GYRO_RATEMAX)
        self._bgx = self._bgy = self._bgz = 0.0
        self._fx = self._fy = self._fz = 0.0
        self._dx = self._dy = self._dz = 0.0
        # integration state
        self._gix = self._giy = self._giz = 0.0
        self._gi_dt = 0
        self._gi_t = 0
        self._accel_idx = 0
        self._accel_seen = False
        self._accel_t = -1
        self._aix = self._aiy = self._aiz = 0.0
        self._ai_dt = 0
        self._ai_t = 0
        self._ai_clip = 0
        self._ax = self._ay = 0.0
        self._az = -9.80665
        self._vax = self._vay = 0.0
        self._vaz = -9.80665
        # baro / mag averaging
        self._baro_idx = self._bts = self._bn = 0
        self._bp = self._bt = 0.0
        self._mag_idx = self._mts = self._mn = 0
        self._mx = self._my = self._mz = 0.0
        now = self.platform.time_us()
        self._next_check = self._next_status = self._next_air = self._next_mag = now
        self._n_checks = 0
        self._last_run_us = now
        self._load_params()
        # An HRT callout, not a run: gyro runs do the checks when due (PX4's backup schedule).
        self._watchdog_call = self.platform.hrt.call_every(CHECK_INTERVAL_US, CHECK_INTERVAL_US,
                                                           self._watchdog)

    def _watchdog(self) -> None:
        if self.platform.time_us() - self._last_run_us >= CHECK_INTERVAL_US:
            self.work_item.schedule_now()  # type: ignore[union-attr]

    def _stop(self) -> None:
        self._watchdog_call.cancel()

    def _load_params(self) -> None:
        self._load_calibrations()
        get = self._getter()
        self._gyro_cutoff = float(get("IMU_GYRO_CUTOFF"))
        self._dgyro_cutoff = float(get("IMU_DGYRO_CUTOFF"))
        self._accel_cutoff = float(get("IMU_ACCEL_CUTOFF"))
        self._integ_us = int(1_000_000 / max(1, int(get("IMU_INTEG_RATE"))))
        self._qnh_pa = float(get("SENS_BARO_QNH")) * 100.0
        self._air_us = int(1_000_000 / float(get("SENS_BARO_RATE")))
        self._mag_us = int(1_000_000 / float(get("SENS_MAG_RATE")))
        self._gyro_ratemax = float(get("IMU_GYRO_RATEMAX"))
        self._set_gyro_rate(self._gyro_dt_avg)

    def _set_gyro_rate(self, dt_us: float) -> None:
        """Filter coefficients for a gyro sample interval (start, rate change, failover)."""
        self._lpf.set_cutoff(1e6 / dt_us, self._gyro_cutoff)
        self._filter_primed = False
        dt_s = dt_us * 1e-6
        k = self._dgyro_cutoff
        self._d_alpha = 1.0 if k <= 0.0 else dt_s / (dt_s + 1.0 / (6.283185307179586 * k))
        self._set_publish_rate(dt_us)

    def _set_publish_rate(self, dt_us: float) -> None:
        """PX4's rule for IMU_GYRO_RATEMAX: wake after the number of samples closest to the
        configured interval, publish no closer than that interval less half a sample."""
        rmax = self._gyro_ratemax
        if rmax <= 0.0:
            samples, interval = 1, 0
        else:
            configured = 1e6 / rmax
            samples = math.floor(configured / dt_us + 0.5)  # roundf: halves round up
            interval = min(10_000, max(125, math.floor(configured - dt_us / 2.0 + 0.5)))
        self._avel_interval_us = interval
        self._gyro_cbs[self._gyro_idx].set_required_updates(samples)

    def _getter(self) -> Any:
        params = self.system.params

        def get(name: str) -> float:
            return params[name] if params is not None and name in params else _DEFAULTS[name]

        return get

    def _load_calibrations(self) -> None:
        """Calibration slots by device id; called again when a new device shows up."""
        get = self._getter()
        rot = board_rotation(get)
        for group in self._groups:
            group.new_device = False
            for s in group.instances:
                s.cal.load(get, rot)

    # -- the work item -----------------------------------------------------------------------

    def run(self) -> None:
        item = self.work_item
        cost = self.CPU_COST_NS
        self._last_run_us = now = self.platform.time_us()
        if self._param_sub.updated():
            self._param_sub.copy()
            self._load_params()
        if self._bias_sub.updated():
            self._on_bias(self._bias_sub.copy())
        # The accelerometer samples of this run, consumed up to each integration boundary.
        asub = self._accel_subs[self._accel_idx]
        accel = asub.update_all()
        n_acc = len(accel)
        ai = 0
        gsub = self._gyro_cbs[self._gyro_idx]
        t = -1
        n = 0
        for msg in gsub.update_all():
            t = self._on_gyro(msg)
            n += 1
            if self._gi_dt >= self._integ_us - (self._gyro_dt_avg * 0.5):
                while ai < n_acc and accel[ai].timestamp_sample <= t:
                    self._on_accel(accel[ai])
                    ai += 1
                self._publish_combined()
                cost += self.COST_COMBINED_NS
        while ai < n_acc:
            self._on_accel(accel[ai])
            ai += 1
        if n:
            cost += (n - 1) * self.COST_SAMPLE_NS
            # publish once all queued samples are filtered, at most at IMU_GYRO_RATEMAX
            iv = self._avel_interval_us
            last = self._avel_last_us
            if t >= last + iv:
                self._publish_avel(now, t)
                nxt = last + iv
                # PX4: constrain(last + interval, t - interval, t), so no drift and no burst
                self._avel_last_us = min(t, max(nxt, t - iv))
        elif self._gi_dt and self._gi_dt >= self._integ_us - (self._gyro_dt_avg * 0.5):
            self._publish_combined()
            cost += self.COST_COMBINED_NS
        bsub = self._baro_subs[self._baro_idx]
        for msg in bsub.update_all():
            self._on_baro(msg)
        msub = self._mag_subs[self._mag_idx]
        for msg in msub.update_all():
            self._on_mag(msg)
        if self._bn and now >= self._next_air:
            self._publish_air(now)
        if self._mn and now >= self._next_mag:
            self._publish_mag(now)
        if now >= self._next_check:
            self._next_check = now + CHECK_INTERVAL_US
            self._check(now)
            cost += self.COST_CHECK_NS
        if item is not None:
            item.cpu_cost_ns = cost

    # -- gyro / accel ----------------------------------------------------------------------------

    def _on_gyro(self, msg: Any) -> int:
        """Calibrate, integrate, filter and differentiate one gyro sample; its sample time."""
        cal = self._gyro_cals[self._gyro_idx]
        if cal.identity:
            x, y, z = msg.x, msg.y, msg.z
        else:
            x, y, z = cal.apply(msg.x, msg.y, msg.z)
        t = msg.timestamp_sample
        dt = t - self._gyro_t
        self._gyro_t = t
        avg = self._gyro_dt_avg
        if 0 < dt < 20_000:
            if self._rate_unknown:
                avg = dt
                self._rate_unknown = False
            avg += 0.02 * (dt - avg)
            self._gyro_dt_avg = avg
            if abs(self._lpf.sample_hz * avg - 1e6) > 0.05e6:  # rate changed by > 5 %
                self._set_gyro_rate(avg)
        else:
            dt = int(avg)
        # integrate (rectangular: the sample is the mean rate over its interval)
        self._gix += x * dt
        self._giy += y * dt
        self._giz += z * dt
        self._gi_dt += dt
        self._gi_t = t
        # rate-controller output: bias removed, low-pass and filtered derivative
        x -= self._bgx
        y -= self._bgy
        z -= self._bgz
        lpf = self._lpf
        if not self._filter_primed:
            lpf.reset(x, y, z)
            self._fx, self._fy, self._fz = x, y, z
            self._filter_primed = True
        fx, fy, fz = lpf.apply(x, y, z)
        a = self._d_alpha
        inv = 1e6 / dt
        self._dx += a * ((fx - self._fx) * inv - self._dx)
        self._dy += a * ((fy - self._fy) * inv - self._dy)
        self._dz += a * ((fz - self._fz) * inv - self._dz)
        self._fx, self._fy, self._fz = fx, fy, fz
        return t

    def _publish_avel(self, now: int, t: int) -> None:
        m = self._m_avel
        m.timestamp = now
        m.timestamp_sample = t
        xyz = m.xyz
        xyz[0], xyz[1], xyz[2] = self._fx, self._fy, self._fz
        d = m.xyz_derivative
        d[0], d[1], d[2] = self._dx, self._dy, self._dz
        self._pub_avel.publish(m)

    def _on_bias(self, msg: Any) -> None:
        """The estimator's gyro bias, removed from vehicle_angular_velocity when it belongs to
        the selected gyro (sensor_combined stays raw: the estimator models the bias itself)."""
        gid = self.gyro.instances[self._gyro_idx].device_id
        if msg.gyro_bias_valid and msg.gyro_device_id == gid and gid:
            self._bgx, self._bgy, self._bgz = msg.gyro_bias
        else:
            self._bgx = self._bgy = self._bgz = 0.0

    def _on_accel(self, msg: Any) -> None:
        cal = self._accel_cals[self._accel_idx]
        if cal.identity:
            x, y, z = msg.x, msg.y, msg.z
        else:
            x, y, z = cal.apply(msg.x, msg.y, msg.z)
        t = msg.timestamp_sample
        dt = t - self._accel_t
        self._accel_t = t
        if not 0 < dt < 20_000:
            dt = 1000 * max(1, msg.samples) if self._ai_dt == 0 else 0
            if dt == 0:
                return
        self._aix += x * dt
        self._aiy += y * dt
        self._aiz += z * dt
        self._ai_dt += dt
        self._ai_t = t
        c = msg.clip_counter
        if c[0] or c[1] or c[2]:
            self._ai_clip |= (1 if c[0] else 0) | (2 if c[1] else 0) | (4 if c[2] else 0)

    def _publish_combined(self) -> None:
        gdt = self._gi_dt
        inv = 1.0 / gdt
        m = self._m_comb
        g = m.gyro_rad
        g[0], g[1], g[2] = self._gix * inv, self._giy * inv, self._giz * inv
        m.gyro_integral_dt = gdt
        adt = self._ai_dt
        if not adt and not self._accel_seen:
            # no accelerometer yet: nothing to publish (a made-up specific force would
            # mislead the estimator's alignment)
            self._gix = self._giy = self._giz = 0.0
            self._gi_dt = 0
            return
        if adt:
            self._accel_seen = True
            ainv = 1.0 / adt
            self._ax, self._ay, self._az = self._aix * ainv, self._aiy * ainv, self._aiz * ainv
            m.accelerometer_timestamp_relative = self._ai_t - self._gi_t
        else:  # no new accel sample in this interval: hold the last one
            m.accelerometer_timestamp_relative = m.RELATIVE_TIMESTAMP_INVALID
        m.timestamp = self._gi_t
        a = m.accelerometer_m_s2
        a[0], a[1], a[2] = self._ax, self._ay, self._az
        m.accelerometer_integral_dt = adt if adt else gdt
        m.accelerometer_clipping = self._ai_clip
        m.gyro_device_id = self.gyro.instances[self._gyro_idx].device_id
        m.accel_device_id = self.accel.instances[self._accel_idx].device_id
        self._pub_comb.publish(m)
        self.perf_combined.count()
        # vehicle_acceleration: first-order low-pass of the same averages, at this rate
        k = self._accel_cutoff
        dt_s = gdt * 1e-6
        alpha = 1.0 if k <= 0.0 else dt_s / (dt_s + 1.0 / (6.283185307179586 * k))
        self._vax += alpha * (self._ax - self._vax)
        self._vay += alpha * (self._ay - self._vay)
        self._vaz += alpha * (self._az - self._vaz)
        va = self._m_acc
        va.timestamp = self.platform.time_us()
        va.timestamp_sample = self._gi_t
        xyz = va.xyz
        xyz[0], xyz[1], xyz[2] = self._vax, self._vay, self._vaz
        self._pub_acc.publish(va)
        self._gix = self._giy = self._giz = 0.0
        self._gi_dt = 0
        self._aix = self._aiy = self._aiz = 0.0
        self._ai_dt = 0
        self._ai_clip = 0

    # -- baro / mag --------------------------------------------------------------------------------

    def _on_baro(self, msg: Any) -> None:
        self._bp += msg.pressure - self._baro_cals[self._baro_idx].pressure_offset_pa
        self._bt += msg.temperature
        self._bts += msg.timestamp_sample
        self._bn += 1

    def _publish_air(self, now: int) -> None:
        n = self._bn
        p = self._bp / n
        temp = self._bt / n
        m = self._m_air
        m.timestamp = now
        m.timestamp_sample = self._bts // n
        s = self.baro.instances[self._baro_idx]
        m.baro_device_id = s.device_id
        m.baro_alt_meter = isa_altitude_m(p, self._qnh_pa)
        m.baro_temp_celcius = temp
        m.baro_pressure_pa = p
        m.rho = p / (_R_AIR * (temp + _KELVIN))
        m.calibration_count = s.cal.slot + 1
        self._pub_air.publish(m)
        self._bp = self._bt = 0.0
        self._bts = self._bn = 0
        self._next_air = max(self._next_air + self._air_us, now - self._air_us)

    def _on_mag(self, msg: Any) -> None:
        x, y, z = self._mag_cals[self._mag_idx].apply(msg.x, msg.y, msg.z)
        self._mx += x
        self._my += y
        self._mz += z
        self._mts += msg.timestamp_sample
        self._mn += 1

    def _publish_mag(self, now: int) -> None:
        n = self._mn
        m = self._m_mag
        m.timestamp = now
        m.timestamp_sample = self._mts // n
        s = self.mag.instances[self._mag_idx]
        m.device_id = s.device_id
        v = m.magnetometer_ga
        v[0], v[1], v[2] = self._mx / n, self._my / n, self._mz / n
        m.calibration_count = s.cal.slot + 1
        self._pub_mag.publish(m)
        self._mx = self._my = self._mz = 0.0
        self._mts = self._mn = 0
        self._next_mag = max(self._next_mag + self._mag_us, now - self._mag_us)

    # -- voting --------------------------------------------------------------------------------------

    def _check(self, now: int) -> None:
        self.gyro.observe(now, _clips)
        self.accel.observe(now, _clips)
        self._n_checks += 1
        if self._n_checks % SLOW_CHECK_DIVIDER == 0:  # slow sensors, slow timeouts
            self.mag.observe(now)
            self.baro.observe(now)
        if (self.gyro.new_device or self.accel.new_device or self.mag.new_device
                or self.baro.new_device):
            self._load_calibrations()
        changed = False
        for group in self._groups:
            ev = group.select()
            if ev is not None:
                changed = True
                self._on_event(group, ev)
        if changed or now >= self._next_status:
            self._next_status = now + STATUS_INTERVAL_US
            for group in self._groups:
                self._publish_status(group, now)

    def _on_event(self, group: SensorGroup, ev: Event) -> None:
        kind, old, new, reason = ev
        if kind == "failover":
            self.perf_failover.count()
            if new >= 0:
                self.warn(f"{group.name} #{old} failed, switching to #{new} ({reason})")
            else:
                self.error(f"{group.name} #{old} failed, no healthy {group.name} left ({reason})")
        elif old >= 0:
            self.info(f"{group.name}: switching from #{old} to #{new}")
        if new < 0:
            return
        if group is self.gyro:
            if new != self._gyro_idx:
                self._gyro_cbs[self._gyro_idx].unregister_callback()
                cb = self._gyro_cbs[new]
                cb.last_gen = max(0, cb.node.generation - 1)  # the latest sample only
                cb.register_callback()
                self._gyro_idx = new
                self._avel_last_us = 0
                self._set_publish_rate(self._gyro_dt_avg)
                self._gyro_t = -1
                self._rate_unknown = True  # measured from the new gyro's first two samples
                self._bgx = self._bgy = self._bgz = 0.0  # that bias was the old gyro's
        elif group is self.accel:
            sub = self._accel_subs[new]
            sub.last_gen = max(0, sub.node.generation - 1)
            self._accel_idx = new
            self._accel_t = -1
        elif group is self.baro:
            sub = self._baro_subs[new]
            sub.last_gen = sub.node.generation
            self._baro_idx = new
            self._bp = self._bt = 0.0
            self._bts = self._bn = 0
        elif group is self.mag:
            sub = self._mag_subs[new]
            sub.last_gen = sub.node.generation
            self._mag_idx = new
            self._mx = self._my = self._mz = 0.0
            self._mts = self._mn = 0

    def _publish_status(self, group: SensorGroup, now: int) -> None:
        m = self._m_status
        m.timestamp = now
        cur = group.current
        m.device_id_primary = cur.device_id if cur is not None else 0
        for i, s in enumerate(group.instances):
            m.device_ids[i] = s.device_id
            m.inconsistency[i] = s.inconsistency
            m.healthy[i] = s.healthy
            m.priority[i] = max(0, s.priority) if s.seen else 0
            m.enabled[i] = s.seen and s.priority > 0
        m.failover_count = min(255, group.failover_count)
        self._pub_status[group.name].publish(m)

    # -- shell -------------------------------------------------------------------------------------

    def status_lines(self) -> list[str]:
        out = []
        for group in self._groups:
            out.append(f"{group.name}: selected #{group.selected}, "
                       f"{group.failover_count} failovers")
            for s in group.instances:
                if not s.seen:
                    continue
                mark = "*" if s.index == group.selected else " "
                out.append(f" {mark} #{s.index} id {s.device_id} prio {s.priority} "
                           f"{'healthy' if s.healthy else 'UNHEALTHY: ' + s.fault} "
                           f"cal slot {s.cal.slot} inconsistency {s.inconsistency:.4g} "
                           f"errors {s.error_count}")
        out.append(f"gyro rate {1e6 / self._gyro_dt_avg:.0f} Hz, cutoff {self._gyro_cutoff} Hz,"
                   f" integration {self._integ_us} us")
        cb = self._gyro_cbs[self._gyro_idx]
        out.append(f"vehicle_angular_velocity: IMU_GYRO_RATEMAX {self._gyro_ratemax:.0f} Hz, "
                   f"every {cb.required_updates} samples, >= {self._avel_interval_us} us apart")
        return out
