"""The ``sensors`` module: calibrated, voted sensor data for the controllers and the estimator.

As in PX4 it is one work item whose parts are classes, each in its own file:

* :class:`VehicleAngularVelocity` (``vehicle_angular_velocity``, the rate controller's input),
* :class:`VehicleIMU` (the gyro and accelerometer integrated into ``sensor_combined``),
* :class:`VehicleAcceleration` (``vehicle_acceleration``),
* :class:`VehicleAirData` and :class:`VehicleMagnetometer` (``vehicle_air_data``,
  ``vehicle_magnetometer``),
* the voters, one :class:`SensorGroup` per sensor kind (voter.py).

This module is the work item that drives them, because on the host (as on the STM32) one work
item run is the unit of cost:

* it wakes on the *selected* gyro (callback subscription, moved with the selection) once
  ``round(IMU_GYRO_RATEMAX interval / gyro interval)`` samples are queued (PX4's rule: one
  for the MPU6000, whose FIFO is read at the same limit, three for a 1 kHz gyro at the
  default 400 Hz), and from a 10 ms HRT watchdog only if no run
  happened for 10 ms (a silent gyro is still noticed);
* each run walks the gyro and accelerometer queues sample by sample: calibration, then
  VehicleAngularVelocity and VehicleIMU at the full raw rate. ``sensor_combined`` closes every
  1/IMU_INTEG_RATE (4 ms) at the gyro sample that completes it, with the accelerometer samples
  up to that time (250 Hz whatever the wake-up rate), as does ``vehicle_acceleration``;
  ``vehicle_angular_velocity`` is published after the run's last sample;
* the selected barometer's and magnetometer's samples go to VehicleAirData and
  VehicleMagnetometer; an airspeed sensor's ``differential_pressure`` goes to :class:`Airspeed`
  (``airspeed``: airspeed.py), which advertises nothing on a board without one;
* every 10 ms the voters look at every instance (timeout, frozen data, disagreement), select,
  fail over (``[sensors] gyro #0 failed, switching to #1`` in dmesg) and ``sensors_status_*``
  are published (every 100 ms and on a change).

``sensors_status_imu`` instance 0 describes the gyros and instance 1 the accelerometers (the
message has one set of per-sensor fields; gyro and accel are voted independently, as in PX4
before vehicle_imu). The gyro bias ekf2 estimates (``estimator_sensor_bias``) is removed from
``vehicle_angular_velocity`` when it belongs to the selected gyro.
"""

from __future__ import annotations

import math
from typing import Any, Final

from firmware.modules.sensors.airspeed import Airspeed
from firmware.modules.sensors.calibration import Calibration, board_rotation
from firmware.modules.sensors.params import N_ACCEL_CAL, N_BARO_CAL, N_GYRO_CAL, N_MAG_CAL, PARAMS
from firmware.modules.sensors.vehicle_acceleration import VehicleAcceleration
from firmware.modules.sensors.vehicle_air_data import VehicleAirData, isa_altitude_m
from firmware.modules.sensors.vehicle_angular_velocity import VehicleAngularVelocity
from firmware.modules.sensors.vehicle_imu import VehicleIMU
from firmware.modules.sensors.vehicle_magnetometer import VehicleMagnetometer
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

_DEFAULTS: Final = {d.name: d.default for d in PARAMS}


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
                   "vehicle_magnetometer, airspeed")
    PARAMS = PARAMS
    WQ = "wq:INS0"
    #: modelled STM32F427 time of a run that handles one gyro sample (calibrate, filter,
    #: publish); runs that also integrate/vote/average cost more (set per run)
    CPU_COST_NS = 18_000
    #: each further gyro sample of a run (calibrate and filter, no publication)
    COST_SAMPLE_NS = 8_000
    COST_COMBINED_NS = 30_000
    COST_CHECK_NS = 25_000
    COST_AIRSPEED_NS = 15_000

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

        # the parts, fed the selected sensor of each kind (advertised in PX4's start order)
        now = self.platform.time_us()
        self._gyro_idx = self._accel_idx = self._baro_idx = self._mag_idx = 0
        self.angular_velocity = VehicleAngularVelocity(
            self.advertise("vehicle_angular_velocity"), orb.new("vehicle_angular_velocity"),
            self._gyro_cbs[0])
        self.acceleration = VehicleAcceleration(self.advertise("vehicle_acceleration"),
                                                orb.new("vehicle_acceleration"))
        self.imu = VehicleIMU(self.advertise("sensor_combined"), orb.new("sensor_combined"))
        self.air_data = VehicleAirData(self.advertise("vehicle_air_data"),
                                       orb.new("vehicle_air_data"), now)
        self.magnetometer = VehicleMagnetometer(self.advertise("vehicle_magnetometer"),
                                                orb.new("vehicle_magnetometer"), now)
        self._pub_status = {"gyro": self.advertise("sensors_status_imu", 0),
                            "accel": self.advertise("sensors_status_imu", 1),
                            "mag": self.advertise("sensors_status_mag"),
                            "baro": self.advertise("sensors_status_baro")}
        self._m_status = orb.new("sensors_status_imu")
        self.airspeed = Airspeed(self.subscribe, lambda topic: self.advertise(topic),
                                 orb.new("airspeed"))
        self.perf_combined = self.perf_alloc("interval", "sensor_combined")
        self.perf_failover = self.perf_alloc("count", "failovers")

        self._gyro_cbs[0].register_callback()
        self._next_check = self._next_status = now
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
        self.acceleration.cutoff_hz = float(get("IMU_ACCEL_CUTOFF"))
        self.imu.integ_us = int(1_000_000 / max(1, int(get("IMU_INTEG_RATE"))))
        self.air_data.qnh_pa = float(get("SENS_BARO_QNH")) * 100.0
        self.air_data.interval_us = int(1_000_000 / float(get("SENS_BARO_RATE")))
        self.magnetometer.interval_us = int(1_000_000 / float(get("SENS_MAG_RATE")))
        self.airspeed.set_params(get)
        self.angular_velocity.set_params(float(get("IMU_GYRO_CUTOFF")),
                                         float(get("IMU_DGYRO_CUTOFF")),
                                         float(get("IMU_GYRO_RATEMAX")))

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
        avel = self.angular_velocity
        imu = self.imu
        # The accelerometer samples of this run, consumed up to each integration boundary.
        asub = self._accel_subs[self._accel_idx]
        accel = asub.update_all()
        n_acc = len(accel)
        ai = 0
        gsub = self._gyro_cbs[self._gyro_idx]
        gcal = self._gyro_cals[self._gyro_idx]
        t = -1
        n = 0
        for msg in gsub.update_all():
            if gcal.identity:
                x, y, z = msg.x, msg.y, msg.z
            else:
                x, y, z = gcal.apply(msg.x, msg.y, msg.z)
            t = msg.timestamp_sample
            imu.integrate_gyro(x, y, z, avel.update(x, y, z, t), t)
            n += 1
            if imu.due(avel.dt_avg_us):
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
            # published once all queued samples are filtered, at most at IMU_GYRO_RATEMAX
            avel.publish_if_due(now, t)
        elif imu.gyro_dt_us and imu.due(avel.dt_avg_us):
            self._publish_combined()
            cost += self.COST_COMBINED_NS
        bsub = self._baro_subs[self._baro_idx]
        offset_pa = self._baro_cals[self._baro_idx].pressure_offset_pa
        for msg in bsub.update_all():
            self.air_data.add(msg, offset_pa)
        msub = self._mag_subs[self._mag_idx]
        mcal = self._mag_cals[self._mag_idx]
        for msg in msub.update_all():
            x, y, z = mcal.apply(msg.x, msg.y, msg.z)
            self.magnetometer.add(x, y, z, msg.timestamp_sample)
        self.air_data.publish_if_due(now, self.baro.instances[self._baro_idx])
        self.magnetometer.publish_if_due(now, self.mag.instances[self._mag_idx])
        if self.airspeed.update(now):
            cost += self.COST_AIRSPEED_NS
        if now >= self._next_check:
            self._next_check = now + CHECK_INTERVAL_US
            self._check(now)
            cost += self.COST_CHECK_NS
        if item is not None:
            item.cpu_cost_ns = cost

    def _on_bias(self, msg: Any) -> None:
        """The estimator's gyro bias, removed from vehicle_angular_velocity when it belongs to
        the selected gyro (sensor_combined stays raw: the estimator models the bias itself)."""
        gid = self.gyro.instances[self._gyro_idx].device_id
        if msg.gyro_bias_valid and msg.gyro_device_id == gid and gid:
            bx, by, bz = msg.gyro_bias
            self.angular_velocity.set_bias(bx, by, bz)
        else:
            self.angular_velocity.set_bias(0.0, 0.0, 0.0)

    def _on_accel(self, msg: Any) -> None:
        cal = self._accel_cals[self._accel_idx]
        if cal.identity:
            x, y, z = msg.x, msg.y, msg.z
        else:
            x, y, z = cal.apply(msg.x, msg.y, msg.z)
        self.imu.integrate_accel(x, y, z, msg)

    def _publish_combined(self) -> None:
        imu = self.imu
        if imu.publish(self.gyro.instances[self._gyro_idx].device_id,
                       self.accel.instances[self._accel_idx].device_id):
            self.perf_combined.count()
            self.acceleration.update(imu.ax, imu.ay, imu.az, imu.gyro_dt_us, imu.gyro_t,
                                     self.platform.time_us())
        imu.reset()

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
                self.angular_velocity.select(cb)
        elif group is self.accel:
            sub = self._accel_subs[new]
            sub.last_gen = max(0, sub.node.generation - 1)
            self._accel_idx = new
            self.imu.accel_selected()
        elif group is self.baro:
            sub = self._baro_subs[new]
            sub.last_gen = sub.node.generation
            self._baro_idx = new
            self.air_data.reset()
        elif group is self.mag:
            sub = self._mag_subs[new]
            sub.last_gen = sub.node.generation
            self._mag_idx = new
            self.magnetometer.reset()

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
        avel = self.angular_velocity
        out.append(f"gyro rate {1e6 / avel.dt_avg_us:.0f} Hz, cutoff {avel.cutoff_hz} Hz,"
                   f" integration {self.imu.integ_us} us")
        cb = self._gyro_cbs[self._gyro_idx]
        out.append(f"vehicle_angular_velocity: IMU_GYRO_RATEMAX {avel.ratemax_hz:.0f} Hz, "
                   f"every {cb.required_updates} samples, >= {avel.interval_us} us apart")
        if self.airspeed.published:
            out.append(self.airspeed.status_line())
        return out
