"""The sensors module on the emulated FMUv2: calibration, board rotation, rates, voting/failover.

The board runs its real drivers (``firmware="sensors"``: no startup script), held still on the
turntable, and the module is started on a System of its own parameters.
"""

from __future__ import annotations

import math

import pytest

from fmu.board import FmuV2Board
from common.rotation import rotation_matrix
from firmware.modules.sensors import PARAMS, SensorsModule, isa_altitude_m
from firmware.platform.params import Params
from firmware.platform.uorb import Subscription
from firmware.system import System
from hil.turntable import Turntable

S = 1_000_000_000


class Bench:
    """A still FMU on the turntable with the sensors module running."""

    def __init__(self, roll_deg: float = 20.0, pitch_deg: float = -10.0, yaw_deg: float = 40.0,
                 seed: int = 4) -> None:
        self.fmu = FmuV2Board(seed=seed, firmware="sensors")
        Turntable(self.fmu.kernel, self.fmu.env, roll_deg=roll_deg, pitch_deg=pitch_deg,
                  yaw_deg=yaw_deg)
        self.p = self.fmu.platform
        self.params = Params(self.p, list(PARAMS))
        self.system = System(self.p, self.params)
        self.mod = SensorsModule(self.system)
        self.mod.start()

    def run_s(self, seconds: float) -> None:
        k = self.fmu.kernel
        k.run(k.now_ns + int(seconds * S))

    def node(self, topic: str, instance: int = 0):
        return self.p.orb.node(topic, instance)

    def mean(self, topic: str, field: str, seconds: float, instance: int = 0) -> list[float]:
        """Mean of a vector (or scalar) field over the next ``seconds``, every message."""
        sub = Subscription(self.p.orb, topic, instance)
        sub.copy()
        acc: list[float] = []
        n = 0
        end = self.fmu.kernel.now_ns + int(seconds * S)
        while self.fmu.kernel.now_ns < end:
            self.fmu.kernel.run(self.fmu.kernel.now_ns + 1_000_000)
            msg = sub.update()
            while msg is not None:
                v = getattr(msg, field)
                v = list(v) if isinstance(v, (list, tuple)) else [v]
                acc = v if not acc else [a + b for a, b in zip(acc, v)]
                n += 1
                msg = sub.update()
        assert n, f"no {topic} published"
        return [a / n for a in acc]

    def count(self, topic: str, seconds: float, instance: int = 0) -> int:
        node = self.node(topic, instance)
        before = node.publish_count
        self.run_s(seconds)
        return node.publish_count - before

    def set(self, **values: float) -> None:
        for name, value in values.items():
            self.params.set(name, value, notify=False)
        self.params.notify()


@pytest.fixture(scope="module")
def bench() -> Bench:
    b = Bench()
    b.run_s(1.5)
    return b


def _close(a: list[float], b: list[float], tol: float) -> bool:
    return all(abs(x - y) <= tol for x, y in zip(a, b))


def test_outputs_and_rates_follow_the_sensors(bench: Bench) -> None:
    topics = ("sensor_gyro", "vehicle_angular_velocity", "sensor_combined", "vehicle_air_data",
              "vehicle_magnetometer")
    before = {t: bench.node(t).publish_count for t in topics}
    bench.run_s(2.0)
    n = {t: (bench.node(t).publish_count - before[t]) / 2.0 for t in topics}
    # vehicle_angular_velocity: IMU_GYRO_RATEMAX 400 Hz on a 1 kHz gyro (MPU6000) is one
    # message per 3 samples (PX4 rounds 2.5 samples up), 333 Hz
    assert abs(n["sensor_gyro"] - 1000) <= 3
    assert abs(n["vehicle_angular_velocity"] - n["sensor_gyro"] / 3) <= 2
    assert abs(n["sensor_combined"] - 250) <= 2  # IMU_INTEG_RATE
    assert abs(n["vehicle_air_data"] - 20) <= 1  # SENS_BARO_RATE
    assert abs(n["vehicle_magnetometer"] - 15) <= 1  # SENS_MAG_RATE
    comb = bench.node("sensor_combined").last
    assert 3900 <= comb.gyro_integral_dt <= 4100
    assert comb.gyro_device_id == bench.node("sensor_gyro", 0).last.device_id
    # the external compass (HMC5883 on the GPS mast) is preferred, as in PX4
    mag = bench.node("vehicle_magnetometer").last
    assert bench.node("sensor_mag", 1).last.is_external
    assert mag.device_id == bench.node("sensor_mag", 1).last.device_id
    status = bench.node("sensors_status_mag").last
    assert status.device_id_primary == mag.device_id and all(status.healthy[:2])
    imu = bench.node("sensors_status_imu").last
    assert imu.failover_count == 0 and all(imu.healthy[:2])


def test_defaults_leave_data_unchanged(bench: Bench) -> None:
    env = bench.fmu.env
    # specific force of the still board: the turntable's gravity reaction in board axes
    acc = bench.mean("sensor_combined", "accelerometer_m_s2", 0.5)
    assert _close(acc, list(env.accel_m_s2), 0.15), (acc, env.accel_m_s2)
    vacc = bench.mean("vehicle_acceleration", "xyz", 0.5)
    assert _close(vacc, list(env.accel_m_s2), 0.15)
    gyro = bench.mean("vehicle_angular_velocity", "xyz", 0.3)
    assert _close(gyro, [0.0, 0.0, 0.0], 0.03)
    air = bench.node("vehicle_air_data").last
    assert abs(air.baro_alt_meter - 488.0) < 3.0  # the turntable's site altitude (ISA)
    assert abs(air.baro_alt_meter - isa_altitude_m(air.baro_pressure_pa)) < 1e-6
    assert 0.9 < air.rho < 1.3
    mag = bench.node("vehicle_magnetometer").last
    assert _close(list(mag.magnetometer_ga), list(env.mag_gauss), 0.03)


def test_calibration_offsets_and_scales_are_applied() -> None:
    b = Bench(seed=5)
    b.run_s(1.0)
    acc0 = b.mean("sensor_combined", "accelerometer_m_s2", 0.6)
    gyr0 = b.mean("vehicle_angular_velocity", "xyz", 0.6)
    mag0 = b.mean("vehicle_magnetometer", "magnetometer_ga", 0.6)
    p0 = b.mean("vehicle_air_data", "baro_pressure_pa", 0.6)[0]
    accel_id = b.node("sensor_accel", 0).last.device_id
    gyro_id = b.node("sensor_gyro", 0).last.device_id
    mag_id = b.node("sensor_mag", 1).last.device_id
    baro_id = b.node("sensor_baro", 0).last.device_id
    # slot 1 for the accel and slot 2 for the mag: a slot is found by device id, not index
    b.set(CAL_ACC1_ID=accel_id, CAL_ACC1_XOFF=0.5, CAL_ACC1_YOFF=-0.3, CAL_ACC1_ZSCALE=1.1,
          CAL_GYRO0_ID=gyro_id, CAL_GYRO0_ZOFF=0.05,
          CAL_MAG2_ID=mag_id, CAL_MAG2_XOFF=0.1, CAL_MAG2_YSCALE=2.0,
          CAL_BARO0_ID=baro_id, CAL_BARO0_OFF=100.0)
    b.run_s(0.1)
    acc1 = b.mean("sensor_combined", "accelerometer_m_s2", 0.6)
    gyr1 = b.mean("vehicle_angular_velocity", "xyz", 0.6)
    mag1 = b.mean("vehicle_magnetometer", "magnetometer_ga", 0.6)
    p1 = b.mean("vehicle_air_data", "baro_pressure_pa", 0.6)[0]
    assert _close(acc1, [acc0[0] - 0.5, acc0[1] + 0.3, acc0[2] * 1.1], 0.05), (acc0, acc1)
    assert _close(gyr1, [gyr0[0], gyr0[1], gyr0[2] - 0.05], 0.005), (gyr0, gyr1)
    assert _close(mag1, [mag0[0] - 0.1, mag0[1] * 2.0, mag0[2]], 0.01), (mag0, mag1)
    assert abs(p1 - (p0 - 100.0)) < 3.0
    assert b.node("vehicle_magnetometer").last.calibration_count == 3  # slot 2 in use
    status = "\n".join(b.mod.status_lines())
    assert "cal slot 1" in status and "cal slot 2" in status


def test_board_rotation_turns_internal_sensors_into_the_body_frame() -> None:
    b = Bench(seed=6)
    b.run_s(1.0)
    acc0 = b.mean("sensor_combined", "accelerometer_m_s2", 0.5)
    mag0 = b.mean("vehicle_magnetometer", "magnetometer_ga", 0.5)
    b.set(SENS_BOARD_ROT=2)  # ROTATION_YAW_90: the FMU is mounted turned right by 90 deg
    b.run_s(0.1)
    acc1 = b.mean("sensor_combined", "accelerometer_m_s2", 0.5)
    vacc = b.mean("vehicle_acceleration", "xyz", 0.5)
    mag1 = b.mean("vehicle_magnetometer", "magnetometer_ga", 0.5)
    r = rotation_matrix(2)
    want = [sum(r[i][j] * acc0[j] for j in range(3)) for i in range(3)]
    assert _close(acc1, want, 0.1), (acc0, acc1, want)
    assert _close(vacc, want, 0.1)
    # the external compass sits on the vehicle, not the board: CAL_MAGn_ROT, not the board's
    assert _close(mag1, mag0, 0.02)
    # a fine trim (SENS_BOARD_Z_OFF) adds to it
    b.set(SENS_BOARD_Z_OFF=-90.0)
    b.run_s(0.1)
    acc2 = b.mean("sensor_combined", "accelerometer_m_s2", 0.5)
    assert _close(acc2, acc0, 0.1)


def test_primary_imu_dropping_off_the_bus_fails_over_within_bounded_time() -> None:
    b = Bench(seed=7)
    b.run_s(2.0)
    gyro_ids = [b.node("sensor_gyro", i).last.device_id for i in range(2)]
    assert b.node("sensor_combined").last.gyro_device_id == gyro_ids[0]
    t_fault_us = b.p.time_us()
    b.fmu.devices["mpu6000"].faults.absent = True  # the chip stops answering on SPI
    b.run_s(0.3)
    lines = [(t, text) for t, _sev, mod, text in b.p.dmesg if mod == "sensors"]
    gyro_fail = [(t, text) for t, text in lines
                 if text.startswith("gyro #0 failed, switching to #1")]
    accel_fail = [(t, text) for t, text in lines
                  if text.startswith("accel #0 failed, switching to #1")]
    assert gyro_fail and accel_fail, lines
    latency_us = gyro_fail[0][0] - t_fault_us
    assert 0 < latency_us <= 40_000, latency_us  # 20 ms timeout + 10 ms check period
    assert "[sensors] gyro #0 failed, switching to #1" in b.p.dmesg_text()
    st = b.node("sensors_status_imu").last
    assert st.failover_count == 1 and not st.healthy[0] and st.healthy[1]
    assert st.device_id_primary == gyro_ids[1]
    assert b.node("sensors_status_imu", 1).last.failover_count == 1  # accelerometers
    comb = b.node("sensor_combined").last
    assert comb.gyro_device_id == gyro_ids[1]
    assert comb.accel_device_id == b.node("sensor_accel", 1).last.device_id
    # the rate output now follows the L3GD20 (760 Hz): IMU_GYRO_RATEMAX 400 Hz is one
    # message per 2 samples, 380 Hz
    n_gyro = b.node("sensor_gyro", 1).publish_count
    n_avel = b.node("vehicle_angular_velocity").publish_count
    b.run_s(1.0)
    d_gyro = b.node("sensor_gyro", 1).publish_count - n_gyro
    d_avel = b.node("vehicle_angular_velocity").publish_count - n_avel
    assert abs(d_gyro - 760) < 10 and abs(d_avel - d_gyro / 2) <= 2, (d_gyro, d_avel)
    # and stays sane: gravity still seen by the LSM303D, rates still ~0
    acc = b.mean("sensor_combined", "accelerometer_m_s2", 0.3)
    assert abs(math.sqrt(sum(a * a for a in acc)) - 9.81) < 0.3
    assert b.mod.gyro.instances[0].fault.startswith("timeout")


def test_frozen_compass_is_dropped_for_the_internal_one() -> None:
    b = Bench(seed=8)
    b.run_s(1.5)
    internal = b.node("sensor_mag", 0).last.device_id
    t_fault_us = b.p.time_us()
    b.fmu.devices["hmc5883"].faults.frozen = True  # the selected (external) compass sticks
    b.run_s(1.5)
    fails = [t for t, _s, m, text in b.p.dmesg
             if m == "sensors" and text.startswith("mag #1 failed, switching to #0")]
    assert fails and fails[0] - t_fault_us < 1_000_000
    st = b.node("sensors_status_mag").last
    assert st.device_id_primary == internal and st.failover_count == 1 and not st.healthy[1]
    assert b.node("vehicle_magnetometer").last.device_id == internal


def test_gyro_ratemax_sets_the_rate_controller_loop_rate() -> None:
    """IMU_GYRO_RATEMAX 1000 on the 1 kHz MPU6000: a vehicle_angular_velocity per sample; the
    default 400 wakes the module every 3rd sample (PX4 rounds 2.5 up)."""
    b = Bench(seed=5)
    b.params.set("IMU_GYRO_RATEMAX", 1000)
    b.run_s(0.5)
    n0 = b.node("vehicle_angular_velocity").publish_count
    g0 = b.node("sensor_gyro").publish_count
    b.run_s(1.0)
    d_avel = b.node("vehicle_angular_velocity").publish_count - n0
    d_gyro = b.node("sensor_gyro").publish_count - g0
    assert abs(d_avel - d_gyro) <= 2, (d_avel, d_gyro)
    assert any("every 1 samples" in line for line in b.mod.status_lines())
