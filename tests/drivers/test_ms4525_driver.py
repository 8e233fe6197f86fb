"""The ms4525_airspeed driver and the sensors module's airspeed on an FMUv2 variant carrying the
MS4525DO on I2C1: counts to Pa and degC, SENS_DPRES_OFF, the 100 Hz measure/collect cycle, status
and bus errors counted, and the airspeed's IAS/TAS, confidence and validity checks."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from fmu.board import BOOT_TO_SENSORS_NS, FmuV2Board
from board.i2c import I2cFault
from board.specs import FMU_V2, MS4525DO_AIRSPEED
from firmware.drivers.airspeed.ms4525 import DRV_DIFF_PRESS_DEVTYPE_MS4525, decode
from firmware.drivers.device import DeviceId
from firmware.modules.sensors import PARAMS, SensorsModule
from firmware.modules.sensors.airspeed import RHO0, ias_m_s, tas_m_s
from firmware.platform.params import Params
from firmware.system import System
from hil.turntable import Turntable
from peripherals.ms4525do import counts_from_pressure_pa, counts_from_temperature_c
from tests.fuzzing import fuzz

S = 1_000_000_000
MS = 1_000_000
SPEC = FMU_V2.with_device("I2C1", MS4525DO_AIRSPEED)
Q_PA = 0.5 * RHO0 * 15.0 ** 2          # 15 m/s at sea-level density: 137.8 Pa


class Bench:
    """A still FMU variant with the airspeed sensor, its drivers and the sensors module."""

    def __init__(self, seed: int = 6) -> None:
        self.fmu = FmuV2Board(seed=seed, firmware="sensors", spec=SPEC)
        Turntable(self.fmu.kernel, self.fmu.env)
        self.env = self.fmu.env
        self.env.diff_pressure_pa = Q_PA
        self.p = self.fmu.platform
        self.params = Params(self.p, list(PARAMS))
        self.mod = SensorsModule(System(self.p, self.params))
        self.mod.start()
        self.run_s(BOOT_TO_SENSORS_NS / S + 0.6)
        self.drv = self.fmu.drivers["ms4525_airspeed"]
        self.drv.params = self.params           # as the rcS boot hands the system's params
        self.chip = self.fmu.devices["ms4525"]

    def run_s(self, seconds: float) -> None:
        k = self.fmu.kernel
        k.run(k.now_ns + int(seconds * S))

    def last(self, topic: str):
        return self.p.orb.node(topic, 0).last

    def count(self, topic: str) -> int:
        return self.p.orb.node(topic, 0).publish_count


@pytest.fixture(scope="module")
def bench() -> Bench:
    return Bench()


def test_the_variant_carries_the_sensor_and_the_stock_board_does_not():
    assert "ms4525_airspeed" in SPEC.driver_modules()
    assert "ms4525_airspeed" not in FMU_V2.driver_modules()
    place = SPEC.place("ms4525_airspeed")
    assert (place.bus, place.address, place.external) == ("I2C1", 0x28, True)


def test_differential_pressure_at_100_hz_in_pa_and_degc(bench):
    n0 = bench.count("differential_pressure")
    bench.run_s(1.0)
    assert 95 <= bench.count("differential_pressure") - n0 <= 101   # 10 ms + bus time
    m = bench.last("differential_pressure")
    assert m.differential_pressure_raw_pa == pytest.approx(Q_PA, abs=4.0)   # noise ~1 count
    assert m.differential_pressure_filtered_pa == pytest.approx(Q_PA, abs=1.5)
    assert m.temperature == pytest.approx(bench.env.temperature_c, abs=0.2)
    assert DeviceId.decode(m.device_id) == DeviceId(1, 1, 0x28, DRV_DIFF_PRESS_DEVTYPE_MS4525)
    assert m.error_count == 0 and bench.drv.error_count == 0


def test_the_airspeed_is_ias_and_tas_from_the_baro_density(bench):
    bench.run_s(0.3)
    a = bench.last("airspeed")
    air = bench.last("vehicle_air_data")
    assert a.indicated_airspeed_m_s == pytest.approx(15.0, abs=0.1)
    rho = air.baro_pressure_pa / (287.1 * (a.air_temperature_celsius + 273.15))
    assert a.true_airspeed_m_s == pytest.approx(a.indicated_airspeed_m_s * math.sqrt(RHO0 / rho),
                                                rel=1e-4)
    assert a.true_airspeed_m_s > a.indicated_airspeed_m_s         # 488 m: thinner air
    assert a.confidence == 1.0
    assert a.air_temperature_celsius == pytest.approx(bench.env.temperature_c, abs=0.2)


def test_sens_dpres_off_is_removed_at_once(bench):
    bench.params.set("SENS_DPRES_OFF", 20.0)
    try:
        bench.run_s(0.05)
        m = bench.last("differential_pressure")
        assert m.differential_pressure_raw_pa == pytest.approx(Q_PA - 20.0, abs=4.0)
        assert "offset 20.00 Pa" in bench.drv.status()
    finally:
        bench.params.set("SENS_DPRES_OFF", 0.0)


def test_stale_and_fault_status_are_counted_and_not_published(bench):
    drv, chip = bench.drv, bench.chip
    for field, perf in (("stale", drv.perf_stale), ("diag_fault", drv.perf_fault)):
        err0, pub0, perf0 = drv.error_count, bench.count("differential_pressure"), perf.events
        setattr(chip.faults, field, True)
        bench.run_s(0.2)
        setattr(chip.faults, field, False)
        assert bench.count("differential_pressure") - pub0 <= 1    # at most one in flight
        assert drv.error_count - err0 >= 15 and perf.events - perf0 >= 15
        bench.run_s(0.1)
        assert bench.count("differential_pressure") > pub0 + 5      # and back
        assert bench.last("differential_pressure").error_count == drv.error_count


def test_a_silent_sensor_times_out_to_confidence_zero_and_comes_back(bench):
    bus = bench.fmu.i2c["I2C1"]
    err0 = bench.drv.error_count
    bus.set_fault(I2cFault(nak_rate=1.0))
    bench.run_s(0.5)
    assert bench.drv.error_count - err0 >= 20                       # every NAK counted
    a = bench.last("airspeed")
    assert a.confidence == 0.0                                       # 300 ms without data
    n = bench.count("airspeed")
    bench.run_s(0.3)
    assert 2 <= bench.count("airspeed") - n <= 4                     # re-sent every 100 ms
    bus.set_fault(None)
    bench.run_s(0.3)
    # back, with PX4's error density: every error counted raised it, each good sample lowers it
    assert 0.0 < bench.last("airspeed").confidence < 1.0
    bench.run_s(1.1)
    assert bench.last("airspeed").confidence == 1.0


def test_a_frozen_sensor_is_stuck_after_100_equal_samples(bench):
    bench.chip.faults.frozen = True
    bench.run_s(0.9)
    assert bench.last("airspeed").confidence > 0.0                  # 90 equal: not yet
    bench.run_s(0.3)
    assert bench.last("airspeed").confidence == 0.0
    assert "STUCK" in bench.mod.airspeed.status_line()
    bench.chip.faults.frozen = False
    bench.run_s(0.1)
    assert bench.last("airspeed").confidence > 0.5


def _fly_over_ground(bench: Bench, vx: float) -> None:
    """The estimator's velocity, as ekf2 would publish it (this bench runs no estimator)."""
    if not bench.p.orb.exists("vehicle_local_position"):
        bench.lpos = bench.p.orb.advertise("vehicle_local_position", 0)
        bench.lpos_msg = bench.p.orb.new("vehicle_local_position")
    m = bench.lpos_msg
    m.timestamp = bench.p.time_us()
    m.v_xy_valid = True
    m.vx, m.vy = vx, 0.0
    bench.lpos.publish(m)


def test_a_zero_reading_while_moving_fast_fails_the_consistency_check(bench):
    bench.params.set("ASPD_FS_T_START", 1.0)
    _fly_over_ground(bench, 16.0)                  # 1 m/s tailwind: consistent
    bench.run_s(0.5)
    assert bench.mod.airspeed.consistent and bench.last("airspeed").confidence > 0.5
    bench.chip.faults.port_blocked = "zero"
    bench.run_s(1.5)
    assert bench.last("airspeed").indicated_airspeed_m_s < 3.0
    assert bench.last("airspeed").confidence > 0.5                  # not for ASPD_FS_T_STOP yet
    bench.run_s(1.0)
    # ASPD_FS_T_STOP (2 s) after the filtered reading fell 5 m/s below the ground speed
    assert bench.last("airspeed").confidence == 0.0
    assert "INCONSISTENT" in bench.mod.airspeed.status_line()
    bench.chip.faults.port_blocked = ""
    bench.run_s(0.8)
    assert bench.last("airspeed").confidence == 0.0                 # ASPD_FS_T_START: 1 s
    bench.run_s(0.5)
    assert bench.last("airspeed").confidence > 0.5
    _fly_over_ground(bench, 0.0)                                    # a headwind never fails it
    bench.params.set("ASPD_FS_T_START", 10.0)


def test_ias_and_tas_formulas():
    assert ias_m_s(Q_PA) == pytest.approx(15.0)
    assert ias_m_s(-30.0) == 0.0 and ias_m_s(float("nan")) == 0.0  # never negative
    assert tas_m_s(15.0, 101325.0, 15.0) == pytest.approx(15.0, rel=2e-3)   # ISA sea level
    assert tas_m_s(15.0, 0.5 * 101325.0, 15.0) == pytest.approx(15.0 * math.sqrt(2), rel=2e-3)
    assert math.isnan(tas_m_s(15.0, 0.0, 15.0))


def test_decode_the_datasheet_packet_and_its_bad_forms():
    def packet(status: int, p_pa: float, t_c: float) -> bytes:
        p = counts_from_pressure_pa(-p_pa)             # the pitot as plumbed on the kit
        t = counts_from_temperature_c(t_c) << 5
        return bytes((status << 6 | p >> 8, p & 0xFF, t >> 8, t & 0xFF))

    s = decode(packet(0, 250.0, 30.0))
    assert not s.why and s.diff_pressure_pa == pytest.approx(250.0, abs=0.6)
    assert s.temperature_c == pytest.approx(30.0, abs=0.1)
    assert decode(packet(2, 0, 20)).why == "stale data"
    assert decode(packet(3, 0, 20)).why == "fault detected"
    assert decode(packet(1, 0, 20)).why == "reserved status 1"
    assert "invalid" in decode(packet(0, 0, 150.0)).why                # T count 2047
    assert "3 bytes" in decode(b"\0\0\0").why


@fuzz(examples=300)
@given(st.binary(min_size=0, max_size=6))
def test_decode_never_raises_and_flags_what_it_cannot_use(data):
    s = decode(data)
    if len(data) != 4:
        assert s.why
        return
    if not s.why:
        assert data[0] >> 6 == 0
        assert abs(s.diff_pressure_pa) <= 1.25 * 6894.757 + 1e-6     # 0..16383 counts
        assert -50.0 <= s.temperature_c < 150.0


def test_the_logger_records_both_topics_at_their_profile_rates(bench, tmp_path):
    import pyulog

    from firmware.modules.logger import Logger

    lg = Logger(bench.p, tmp_path / "log", profile="default")
    lg.start()
    bench.run_s(1.0)
    lg.stop()
    u = pyulog.ULog(str(lg.log_files[0]))
    dp = u.get_dataset("differential_pressure").data
    air = u.get_dataset("airspeed").data
    assert 9 <= len(dp["timestamp"]) <= 11 and 9 <= len(air["timestamp"]) <= 11   # 10 Hz
    assert abs(dp["differential_pressure_filtered_pa"][-1] - Q_PA) < 2.0
    assert abs(air["indicated_airspeed_m_s"][-1] - 15.0) < 0.2
