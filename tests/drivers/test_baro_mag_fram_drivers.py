"""MS5611, HMC5883L and FRAM drivers against their models, over the emulated buses only."""

from __future__ import annotations

import math

import numpy as np
import pytest

from board.i2c import I2cBus
from board.kernel import Kernel
from board.spi import SpiBus
from firmware.drivers.barometer.ms5611 import Ms5611Driver
from firmware.drivers.device import BUS_TYPE_I2C, BUS_TYPE_SPI, DeviceId
from firmware.drivers.magnetometer.hmc5883 import Hmc5883Driver
from firmware.drivers.mtd.fram import FramMtd
from firmware.platform import Platform
from firmware.platform.uorb import Subscription
from peripherals.errors import rng_for
from peripherals.fm25v01 import Fm25v01
from peripherals.hmc5883 import Hmc5883
from peripherals.ms5611 import DEFAULT_PROM, Ms5611
from peripherals.physics import Environment

S = 1_000_000_000
MS = 1_000_000


def collect(kernel: Kernel, platform: Platform, topic: str, duration_ns: int) -> list:
    """Run and gather every message of ``topic`` (instance 0), polling at 1 kHz."""
    sub = Subscription(platform.orb, topic)
    out: list = []

    def poll() -> None:
        while (msg := sub.update()) is not None:
            out.append(msg)

    timer = kernel.call_every(MS, poll)
    kernel.run(kernel.now_ns + duration_ns)
    timer.cancel()
    poll()
    return out


def dmesg(platform: Platform) -> str:
    return platform.dmesg_text()


# -- MS5611 ------------------------------------------------------------------------------------

@pytest.fixture
def env() -> Environment:
    return Environment(pressure_pa=98_765.4, board_temperature_c=31.7,
                       mag_gauss=(0.21, -0.05, 0.43))


@pytest.fixture
def spi1(kernel: Kernel) -> SpiBus:
    return SpiBus(kernel, "spi1", pclk_hz=84_000_000)


def baro(kernel, platform, spi1, env, prom=None, **kw):
    chip = Ms5611(kernel, env, rng_for(11, "ms5611"), prom=prom)
    spi1.attach("PD7", chip)
    drv = Ms5611Driver(platform, spi1.device("PD7"), **kw)
    return chip, drv


@pytest.mark.parametrize("pressure, temp_c", [(98_765.4, 31.7), (90_000.0, -20.0),
                                              (101_325.0, 5.0)])
def test_ms5611_round_trip_over_one_second(kernel, platform, spi1, env, pressure, temp_c):
    env.pressure_pa, env.board_temperature_c = pressure, temp_c
    _chip, drv = baro(kernel, platform, spi1, env)
    assert drv.start()
    msgs = collect(kernel, platform, "sensor_baro", S)
    assert 72 <= len(msgs) <= 76                       # 3 pressures per 40 ms: 75 Hz
    p = np.array([m.pressure for m in msgs])
    t = np.array([m.temperature for m in msgs])
    assert abs(p.mean() - pressure) < 1.5              # 2.7 Pa rms at OSR 1024, 75 samples
    assert 1.0 < p.std() < 6.0
    assert abs(t.mean() - temp_c) < 0.02
    m = msgs[-1]
    assert DeviceId.decode(m.device_id) == DeviceId(BUS_TYPE_SPI, 1, 3, 0x3D)
    assert m.error_count == 0 and drv.error_count == 0
    assert drv.prom == list(DEFAULT_PROM)


def test_ms5611_osr_4096_is_quieter(kernel, platform, spi1, env):
    _chip, drv = baro(kernel, platform, spi1, env, osr=4096)
    assert drv.start()
    p = np.array([m.pressure for m in collect(kernel, platform, "sensor_baro", S)])
    assert abs(p.mean() - env.pressure_pa) < 1.0 and p.std() < 2.5


def test_ms5611_bad_crc_refused_with_reason(kernel, platform, spi1, env):
    prom = list(DEFAULT_PROM)
    prom[7] = 0x0005
    _, drv = baro(kernel, platform, spi1, env, prom=tuple(prom))
    assert not drv.start()
    assert "CRC-4 mismatch: computed 0x0, word 7 holds 0x5" in dmesg(platform)


def test_ms5611_all_zero_prom_refused(kernel, platform, spi1, env):
    _, drv = baro(kernel, platform, spi1, env, prom=(0,) * 8)
    assert not drv.start()
    assert "PROM reads all zero" in dmesg(platform)


def test_ms5611_absent_refused(kernel, platform, spi1, env):
    drv = Ms5611Driver(platform, spi1.device("PD7"))
    assert not drv.start()
    assert "no device answering" in dmesg(platform)


def test_ms5611_absent_while_running_counted_and_recovered(kernel, platform, spi1, env):
    chip, drv = baro(kernel, platform, spi1, env)
    assert drv.start()
    kernel.run(200 * MS)
    chip.faults.absent = True
    kernel.run(kernel.now_ns + 100 * MS)
    assert drv.perf_bad_transfer.events >= 5 and drv.perf_reset.events >= 5
    chip.faults.absent = False
    n0 = drv.error_count
    msgs = collect(kernel, platform, "sensor_baro", 300 * MS)
    assert msgs and msgs[-1].error_count == n0
    assert abs(msgs[-1].pressure - env.pressure_pa) < 15


def test_ms5611_power_cycle_gives_not_ready(kernel, platform, spi1, env):
    chip, drv = baro(kernel, platform, spi1, env)
    assert drv.start()
    kernel.run(105 * MS)
    chip.power_cycle()
    kernel.run(kernel.now_ns + 50 * MS)
    assert drv.perf_not_ready.events == 1 and drv.perf_reset.events == 1


def test_ms5611_frozen_detected(kernel, platform, spi1, env):
    chip, drv = baro(kernel, platform, spi1, env)
    assert drv.start()
    kernel.run(100 * MS)
    chip.faults.frozen = True
    kernel.run(kernel.now_ns + 300 * MS)
    assert drv.stuck and drv.perf_stuck.events > 0
    assert "pressure stuck" in dmesg(platform)


def test_ms5611_bias_step_detected(kernel, platform, spi1, env):
    chip, drv = baro(kernel, platform, spi1, env)
    assert drv.start()
    kernel.run(100 * MS)
    chip.faults.bias_step = (1200.0, 0.0, 0.0)
    msgs = collect(kernel, platform, "sensor_baro", 100 * MS)
    assert drv.perf_step.events == 1
    assert "pressure step +1200 Pa" in dmesg(platform) or "pressure step +119" in dmesg(platform)
    assert abs(msgs[-1].pressure - env.pressure_pa - 1200) < 15


def test_ms5611_random_data_out_of_range_counted(kernel, platform, spi1, env):
    chip, drv = baro(kernel, platform, spi1, env)
    assert drv.start()
    chip.faults.random_data = True
    kernel.run(500 * MS)
    assert drv.perf_range.events > 0 and drv.error_count > 0


# -- HMC5883L ----------------------------------------------------------------------------------

@pytest.fixture
def i2c1(kernel: Kernel) -> I2cBus:
    return I2cBus(kernel, "i2c1", clock_hz=400_000)


def mag(kernel, platform, i2c1, env, **kw):
    chip = Hmc5883(kernel, env, rng_for(12, "hmc5883"))
    i2c1.attach(0x1E, chip)
    return chip, Hmc5883Driver(platform, i2c1.device(0x1E), **kw)


def test_hmc5883_publishes_the_environment_field(kernel, platform, i2c1, env):
    _chip, drv = mag(kernel, platform, i2c1, env)
    assert drv.start()
    msgs = collect(kernel, platform, "sensor_mag", S)
    assert 135 <= len(msgs) <= 150                     # 150 Hz minus the bus time per cycle
    xyz = np.array([(m.x, m.y, m.z) for m in msgs])
    assert np.allclose(xyz.mean(axis=0), env.mag_gauss, atol=0.0015)
    m = msgs[-1]
    assert m.is_external and math.isnan(m.temperature) and m.error_count == 0
    assert DeviceId.decode(m.device_id) == DeviceId(BUS_TYPE_I2C, 1, 0x1E, 0x01)


def test_hmc5883_self_test_passes(kernel, platform, i2c1, env):
    _chip, drv = mag(kernel, platform, i2c1, env, self_test=True)
    assert drv.start()
    msgs = collect(kernel, platform, "sensor_mag", 300 * MS)
    assert drv.self_test_passed
    assert np.allclose(drv.self_test_field_ga, (1.16, 1.16, 1.08), atol=0.01)
    assert "self-test passed" in dmesg(platform)
    assert np.allclose((msgs[-1].x, msgs[-1].y, msgs[-1].z), env.mag_gauss, atol=0.01)


def test_hmc5883_self_test_fails_on_a_dead_strap(kernel, platform, i2c1, env):
    chip, drv = mag(kernel, platform, i2c1, env, self_test=True)
    chip.faults.frozen = True          # the bias makes no difference: the strap is dead
    assert drv.start()
    kernel.run(300 * MS)
    assert drv.self_test_passed is False
    assert "self-test FAILED" in dmesg(platform)


def test_hmc5883_wrong_id_refused(kernel, platform, i2c1, env):
    chip, drv = mag(kernel, platform, i2c1, env)
    chip.faults.wrong_id = 0x483434
    assert not drv.start()
    assert "wrong ID b'H44'" in dmesg(platform) and "expected b'H43'" in dmesg(platform)


def test_hmc5883_absent_refused(kernel, platform, i2c1, env):
    drv = Hmc5883Driver(platform, i2c1.device(0x1E))
    assert not drv.start()
    assert "no ACK at I2C address 0x1E" in dmesg(platform)


def test_hmc5883_nak_while_running_counted(kernel, platform, i2c1, env):
    chip, drv = mag(kernel, platform, i2c1, env)
    assert drv.start()
    kernel.run(100 * MS)
    chip.faults.absent = True
    kernel.run(kernel.now_ns + 100 * MS)
    assert drv.perf_bad_transfer.events >= 20
    assert "no ACK from 0x1E 10 times in a row" in dmesg(platform)
    chip.faults.absent = False
    msgs = collect(kernel, platform, "sensor_mag", 100 * MS)
    assert msgs and msgs[-1].error_count == drv.error_count > 0


def test_hmc5883_overflow_reported_not_published(kernel, platform, i2c1, env):
    _chip, drv = mag(kernel, platform, i2c1, env)
    assert drv.start()
    kernel.run(100 * MS)
    env.mag_gauss = (3.0, 0.0, 0.0)                    # beyond +-1.9 Ga
    msgs = collect(kernel, platform, "sensor_mag", 100 * MS)
    assert drv.perf_range.events > 10 and len(msgs) <= 1
    assert "overflow on X" in dmesg(platform)


def test_hmc5883_frozen_detected(kernel, platform, i2c1, env):
    chip, drv = mag(kernel, platform, i2c1, env)
    assert drv.start()
    kernel.run(100 * MS)
    chip.faults.frozen = True
    kernel.run(kernel.now_ns + 300 * MS)
    assert drv.stuck and "field stuck" in dmesg(platform)


# -- FRAM --------------------------------------------------------------------------------------

@pytest.fixture
def spi2(kernel: Kernel) -> SpiBus:
    return SpiBus(kernel, "spi2", pclk_hz=42_000_000)


def fram(kernel, platform, spi2, path=None):
    chip = Fm25v01(kernel, path=path)
    spi2.attach("PD10", chip)
    return chip, FramMtd(platform, spi2.device("PD10"))


def test_fram_round_trip_and_partitions(kernel, platform, spi2):
    _chip, mtd = fram(kernel, platform, spi2)
    assert mtd.start()
    assert mtd.size == 16384
    data = bytes(range(256)) * 3
    assert mtd.write(0x0100, data, verify=True)
    assert mtd.read(0x0100, len(data)) == data
    params, wps = mtd.partition("params"), mtd.partition("waypoints")
    assert (params.offset, params.size, wps.offset, wps.size) == (0, 0x2000, 0x2000, 0x2000)
    assert wps.write(0, b"wp0")
    assert mtd.read(0x2000, 3) == b"wp0"
    assert params.read(0, 4) == b"\xff" * 4            # virgin
    assert params.read(0x1FFE, 4) is None              # crosses the partition end
    assert "outside partition params" in dmesg(platform)
    with pytest.raises(KeyError, match="no partition 'logs'"):
        mtd.partition("logs")
    assert mtd.perf_write.events == 2 and mtd.perf_errors.events == 1


def test_fram_write_persists_for_a_new_model(kernel, platform, spi2, tmp_path):
    path = tmp_path / "fram.bin"
    _chip, mtd = fram(kernel, platform, spi2, path)
    assert mtd.start() and mtd.partition("params").write(0, b"\x2b\x00\x00\x00")
    spi2.detach("PD10")
    _chip2, mtd2 = fram(kernel, Platform(kernel), spi2, path)
    assert mtd2.start() and mtd2.partition("params").read(0, 4) == b"\x2b\x00\x00\x00"


def test_fram_protected_write_refused(kernel, platform, spi2):
    _chip, mtd = fram(kernel, platform, spi2)
    assert mtd.start() and mtd.set_block_protect(2)
    assert not mtd.partition("waypoints").write(0, b"x")
    assert "hits block-protected range 0x2000-0x3FFF" in dmesg(platform)
    assert mtd.partition("params").write(0, b"ok")
    assert mtd.set_block_protect(0) and mtd.write(0x2000, b"x")


def test_fram_absent_and_wrong_id_refused(kernel, platform, spi2):
    mtd = FramMtd(platform, spi2.device("PD10"))
    assert not mtd.start()
    assert "RDID reads all 0xFF" in dmesg(platform)
    chip, mtd = fram(kernel, platform, spi2)
    chip.faults.wrong_id = 0x1F
    assert not mtd.start()
    assert "not a Cypress/Ramtron FRAM" in dmesg(platform)
    assert mtd.read(0, 1) is None and "driver not started" in dmesg(platform)


def test_fram_faults_while_running(kernel, platform, spi2):
    chip, mtd = fram(kernel, platform, spi2)
    assert mtd.start()
    chip.faults.absent = True
    assert mtd.read(0, 8) is None and not mtd.write(0, b"x")
    assert "reserved bits set: device absent?" in dmesg(platform)
    chip.faults.absent = False
    chip.faults.frozen = True
    assert not mtd.write(0x10, b"\x01\x02", verify=True)
    assert "verify failed at 0x0010: wrote 0x01, read 0xFF" in dmesg(platform)


def test_same_seed_same_samples(env):
    """Two boards built alike publish bit-identical baro and mag streams."""
    runs = []
    for _ in range(2):
        kernel = Kernel("fmu")
        platform = Platform(kernel)
        spi1 = SpiBus(kernel, "spi1", pclk_hz=84_000_000)
        i2c1 = I2cBus(kernel, "i2c1")
        _, bdrv = baro(kernel, platform, spi1, env)
        _, mdrv = mag(kernel, platform, i2c1, env)
        assert bdrv.start() and mdrv.start()
        sub_b = Subscription(platform.orb, "sensor_baro")
        sub_m = Subscription(platform.orb, "sensor_mag")
        seen: list = []

        def poll(sub_b=sub_b, sub_m=sub_m, seen=seen) -> None:
            for sub in (sub_b, sub_m):
                while (msg := sub.update()) is not None:
                    seen.append(msg.pack())

        kernel.call_every(MS, poll)
        kernel.run(200 * MS)
        runs.append(seen)
    assert runs[0] == runs[1] and len(runs[0]) > 40
