"""MPU-6000 driver on the emulated board: real SPI bus, GPIO/EXTI, platform, one kernel.

The driver only reaches the chip through the bus and the DRDY pin; tests set the physical input
(``env``) and the chip's faults, never the driver's view.
"""

from __future__ import annotations

import statistics
from itertools import pairwise

import pytest

from board.gpio import Gpio
from board.kernel import NS_PER_MS, NS_PER_S, Kernel
from board.spi import SpiBus
from firmware.drivers.device import BUS_TYPE_SPI, DeviceId
from firmware.drivers.imu.mpu6000 import (
    DRV_IMU_DEVTYPE_MPU6000,
    FIFO_READ,
    Mpu6000Driver,
    fifo_records_per_read,
    gyro_rate_limit,
)
from firmware.platform import Platform
from firmware.platform.workqueue import WorkItem
from peripherals.errors import rng_for
from peripherals.mpu6000 import Mpu6000
from peripherals.physics import Environment
from common.units import G0_M_S2



class Rig:
    """FMUv2's SPI1 with the MPU-6000 on PC2 and its INT on PD15, booted for 100 ms."""

    def __init__(self, pin: bool = True, rotation: int = 0, max_rate_hz: float = 1000.0,
                 **chip_kw) -> None:
        self.kernel = k = Kernel("fmu")
        self.platform = Platform(k)
        self.env = Environment()
        gpio = Gpio(k)
        self.pin = gpio.pin("PD15") if pin else None
        self.chip = Mpu6000(k, self.env, rng_for(3, "mpu6000"), drdy_pin=gpio.pin("PD15"),
                            rotation=rotation, **chip_kw)
        bus = SpiBus(k, "spi1")
        bus.attach("PC2", self.chip)
        self.driver = Mpu6000Driver(self.platform, bus.device("PC2", mode=3),
                                    drdy_pin=self.pin, rotation=rotation,
                                    max_rate_hz=max_rate_hz)
        self.gyro: list = []
        self.accel: list = []
        gnode = self.platform.orb.node("sensor_gyro", 0)
        anode = self.platform.orb.node("sensor_accel", 0)
        gnode.callbacks.append(lambda: self.gyro.append(gnode.last))
        anode.callbacks.append(lambda: self.accel.append(anode.last))
        k.run(100 * NS_PER_MS)  # power-up time of the chip

    def start(self) -> bool:
        ok: list[bool] = []
        self.kernel.call_later(0, lambda: ok.append(self.driver.start()))
        self.kernel.run(self.kernel.now_ns)
        return ok[0]

    def run_s(self, s: float) -> None:
        self.kernel.run_for(int(s * NS_PER_S))

    def started(self) -> Rig:
        assert self.start()
        self.run_s(0.3)  # reset 100 ms + wait 100 ms + configure
        assert self.driver.state == FIFO_READ
        self.gyro.clear()
        self.accel.clear()
        return self

    def dmesg(self) -> str:
        return self.platform.dmesg_text()


def mean(msgs: list, axis: str) -> float:
    return statistics.fmean(getattr(m, axis) for m in msgs)


# -- normal operation ------------------------------------------------------------------------

def test_still_board_gravity_zero_rate_at_1khz() -> None:
    rig = Rig().started()
    rig.run_s(1.0)
    assert len(rig.gyro) == pytest.approx(1000, rel=0.01)
    assert len(rig.accel) == len(rig.gyro)
    assert mean(rig.accel, "z") == pytest.approx(-G0_M_S2, abs=0.1)
    assert abs(mean(rig.accel, "x")) < 0.1 and abs(mean(rig.accel, "y")) < 0.1
    for axis in "xyz":
        assert abs(mean(rig.gyro, axis)) < 0.01
    g = rig.gyro[-1]
    assert DeviceId.decode(g.device_id) == DeviceId(BUS_TYPE_SPI, 1, 0, DRV_IMU_DEVTYPE_MPU6000)
    assert rig.accel[-1].device_id == g.device_id
    assert g.temperature == pytest.approx(35.0, abs=0.01)
    assert g.samples == 8 and g.error_count == 0 and g.clip_counter == [0, 0, 0]
    assert 0 <= g.timestamp - g.timestamp_sample < 200
    stamps = [m.timestamp_sample for m in rig.gyro]
    assert {b - a for a, b in pairwise(stamps)} == {1000}
    assert rig.driver.perf_bad_transfer.events == rig.driver.perf_bad_register.events == 0
    assert "started" in rig.dmesg()


@pytest.mark.parametrize(("rate_hz", "records"), [
    (400, 20), (1000, 8), (800, 12), (333, 24), (250, 32), (100, 32), (2000, 4), (4000, 4),
    (0, 8)])
def test_fifo_read_interval_follows_px4s_rule(rate_hz: float, records: int) -> None:
    # PX4's ConfigureSampleRate: a multiple of 500 us (roundf, halves up), at most 32 records;
    # 0 is 1 kHz. 800 Hz is 2.5 steps of 500 us: rounded up to 1.5 ms.
    assert fifo_records_per_read(rate_hz) == records


def test_a_negative_rate_limit_is_refused() -> None:
    with pytest.raises(ValueError, match="positive"):
        fifo_records_per_read(-400)


def test_the_rate_limit_comes_from_imu_gyro_ratemax() -> None:
    assert gyro_rate_limit({"IMU_GYRO_RATEMAX": 250}) == 250.0
    assert gyro_rate_limit({}) == 0.0 and gyro_rate_limit(None) == 0.0


def test_reads_twenty_records_every_2500_us_at_400_hz() -> None:
    rig = Rig(max_rate_hz=400).started()
    rig.run_s(1.0)
    assert len(rig.gyro) == pytest.approx(400, rel=0.01)
    assert {m.samples for m in rig.gyro} == {20}
    stamps = [m.timestamp_sample for m in rig.gyro]
    assert {b - a for a, b in pairwise(stamps)} == {2500}
    assert mean(rig.accel, "z") == pytest.approx(-G0_M_S2, abs=0.1)
    assert rig.driver.perf_bad_transfer.events == 0  # 2.5 accel readings per read are fine
    assert "20 records" in rig.driver.status()


def test_rotating_board() -> None:
    rig = Rig().started()
    rig.env.gyro_rad_s = (0.0, 0.0, 1.0)
    rig.run_s(0.2)
    assert mean(rig.gyro[50:], "z") == pytest.approx(1.0, rel=0.01)
    assert abs(mean(rig.gyro[50:], "x")) < 0.01


def test_mounting_rotation_is_undone_by_the_driver() -> None:
    rig = Rig(rotation=2).started()  # ROTATION_YAW_90 on both sides
    rig.env.gyro_rad_s = (0.5, 0.0, 0.0)
    rig.run_s(0.1)
    assert mean(rig.gyro[50:], "x") == pytest.approx(0.5, rel=0.01)
    assert abs(mean(rig.gyro[50:], "y")) < 0.01


def test_polls_at_1khz_without_a_drdy_pin() -> None:
    rig = Rig(pin=False).started()
    rig.run_s(0.5)
    assert len(rig.gyro) == pytest.approx(500, rel=0.01)
    assert mean(rig.accel, "z") == pytest.approx(-G0_M_S2, abs=0.1)


# -- refusing to start -------------------------------------------------------------------------

def test_wrong_who_am_i_refuses_to_start() -> None:
    rig = Rig()
    rig.chip.faults.wrong_id = 0x70
    assert not rig.start()
    assert "not starting: WHO_AM_I read 0x70, expected 0x68" in rig.dmesg()
    assert not rig.driver.running


def test_unknown_product_id_refuses_to_start() -> None:
    rig = Rig(product_id=0x00)
    assert not rig.start()
    assert "unexpected PRODUCT_ID 0x00" in rig.dmesg()


def test_absent_chip_refuses_to_start() -> None:
    rig = Rig()
    rig.chip.faults.absent = True
    assert not rig.start()
    assert "WHO_AM_I read 0xFF" in rig.dmesg()


# -- faults at run time ------------------------------------------------------------------------

def test_absent_then_back() -> None:
    rig = Rig().started()
    rig.chip.faults.absent = True
    rig.run_s(0.1)
    d = rig.driver
    assert d.perf_bad_transfer.events >= 1 and d.error_count >= 1
    assert d.state != FIFO_READ and "read 0xFF" in rig.dmesg()  # noticed, chip reset
    rig.chip.faults.absent = False
    rig.run_s(1.5)
    assert d.state == FIFO_READ and rig.gyro[-1].error_count == d.error_count
    assert mean(rig.accel[-100:], "z") == pytest.approx(-G0_M_S2, abs=0.1)


def test_wrong_id_at_run_time_resets_and_reports() -> None:
    rig = Rig().started()
    rig.chip.faults.wrong_id = 0x00
    rig.run_s(1.5)
    d = rig.driver
    assert d.perf_bad_register.events >= 2
    assert "configuration lost: register 0x75 read 0x00" in rig.dmesg()
    assert "reset failed" in rig.dmesg()
    rig.chip.faults.clear()
    rig.run_s(1.0)
    assert d.state == FIFO_READ and "reset succeeded" in rig.dmesg()


def test_register_flip_is_repaired() -> None:
    rig = Rig().started()
    rig.chip.regs.values[0x1B] = 0x00  # a glitch flips the gyro range (test-only back door)
    rig.run_s(0.5)
    d = rig.driver
    assert d.perf_bad_register.events == 1
    assert "configuration lost: register 0x1B" in rig.dmesg()
    assert d.state == FIFO_READ and rig.chip.regs.values[0x1B] == 0x18


def test_frozen_data_is_reported() -> None:
    rig = Rig().started()
    rig.chip.faults.frozen = True
    rig.run_s(0.3)
    d = rig.driver
    assert d.perf_stuck.events == 1 and "data stuck" in rig.dmesg()
    assert rig.gyro[-1].error_count >= 1
    rig.chip.faults.frozen = False
    rig.run_s(0.05)
    assert "data is changing again" in rig.dmesg()


def test_random_data_is_rejected() -> None:
    rig = Rig().started()
    rig.chip.faults.random_data = True
    rig.run_s(0.1)
    d = rig.driver
    assert d.perf_bad_transfer.events >= 50 and "corrupt FIFO data" in rig.dmesg()
    assert len(rig.gyro) < 10  # bad blocks are dropped, not published
    rig.chip.faults.random_data = False
    rig.run_s(0.1)
    assert rig.gyro[-1].error_count == d.error_count
    assert abs(rig.gyro[-1].z) < 0.05


def test_drdy_stuck_falls_back_to_polling() -> None:
    rig = Rig().started()
    rig.chip.faults.drdy_stuck = True
    rig.run_s(0.5)
    d = rig.driver
    assert d.perf_drdy_timeout.events >= 400 and d.perf_missed.events >= 400
    assert "no data-ready" in rig.dmesg()
    assert len(rig.gyro) == pytest.approx(500, rel=0.02)  # still publishing, polled
    rig.chip.faults.drdy_stuck = False
    rig.run_s(0.1)
    assert "data-ready interrupts are back" in rig.dmesg()


def test_saturation_counts_clipping() -> None:
    rig = Rig().started()
    rig.chip.faults.saturate = True
    rig.run_s(0.05)
    g = rig.gyro[-1]
    assert g.clip_counter == [8, 8, 8] and rig.accel[-1].clip_counter == [8, 8, 8]
    assert "clipping" in rig.dmesg()


def test_bias_step_passes_through() -> None:
    rig = Rig().started()
    rig.chip.faults.bias_step = (0.0, 0.0, 0.2)
    rig.run_s(0.1)
    assert mean(rig.gyro[50:], "z") == pytest.approx(0.2, abs=0.01)


def test_fifo_overflow_when_the_queue_stalls() -> None:
    rig = Rig().started()

    class Hog(WorkItem):
        cpu_cost_ns = 20 * NS_PER_MS  # something blocks wq:SPI1 for 20 ms

        def run(self) -> None:
            pass

    hog = Hog(rig.platform, "hog", "wq:SPI1")
    hog.schedule_now()
    rig.run_s(0.1)
    d = rig.driver
    assert d.perf_fifo_overflow.events == 1 and d.perf_fifo_reset.events == 2
    assert d.state == FIFO_READ and len(rig.gyro) > 50
