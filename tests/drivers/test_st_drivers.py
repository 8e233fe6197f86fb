"""L3GD20 and LSM303D drivers against the models: real SpiBus, Gpio and Platform, one kernel."""

from __future__ import annotations

import math
import statistics

import pytest

from board.gpio import Gpio
from board.kernel import Kernel
from board.spi import SpiBus
from firmware.drivers.device import BUS_TYPE_SPI, DeviceId
from firmware.drivers.imu.l3gd20 import L3gd20Driver
from firmware.drivers.imu.lsm303d import Lsm303dDriver
from firmware.platform import Platform
from firmware.platform.workqueue import WorkItem
from peripherals.errors import rng_for
from peripherals.l3gd20 import L3gd20
from peripherals.lsm303d import Lsm303d
from peripherals.physics import Environment
from common.units import G0_M_S2

MS = 1_000_000


class Board:
    """The FMUv2 SPI1 sensor corner: L3GD20 on PC13 (DRDY PB0), LSM303D on PC15 (PB4, PB1)."""

    def __init__(self, gyro: bool = True, accel: bool = True, drdy: bool = True,
                 seed: int = 1) -> None:
        self.kernel = k = Kernel("fmu")
        self.platform = Platform(k)
        self.gpio = Gpio(k)
        self.env = Environment()
        self.bus = SpiBus(k, "SPI1", pclk_hz=84_000_000)
        self.gyro = self.accel = None
        self.gyro_drv: L3gd20Driver | None = None
        self.accel_drv: Lsm303dDriver | None = None
        self.msgs: dict[str, list] = {"sensor_gyro": [], "sensor_accel": [], "sensor_mag": []}
        if gyro:
            self.gyro = L3gd20(k, self.env, rng_for(seed, "l3gd20"),
                               drdy_pin=self.gpio.pin("PB0"))
            self.bus.attach("PC13", self.gyro)
            self.gyro_drv = L3gd20Driver(self.platform, self.bus.device("PC13"),
                                         drdy_pin=self.gpio.pin("PB0") if drdy else None)
        if accel:
            self.accel = Lsm303d(k, self.env, rng_for(seed, "lsm303d"),
                                 int1_pin=self.gpio.pin("PB4"), int2_pin=self.gpio.pin("PB1"))
            self.bus.attach("PC15", self.accel)
            self.accel_drv = Lsm303dDriver(self.platform, self.bus.device("PC15"))

    def start(self) -> None:
        for drv in (self.gyro_drv, self.accel_drv):
            if drv is not None:
                assert drv.start(), self.platform.dmesg_text()
        for topic, out in self.msgs.items():
            node = self.platform.orb.node(topic, 0)
            node.callbacks.append(lambda n=node, o=out: o.append(n.last))

    def run_ms(self, ms: float) -> None:
        self.kernel.run(self.kernel.now_ns + int(ms * MS))

    def since(self, topic: str, t_us: int) -> list:
        return [m for m in self.msgs[topic] if m.timestamp >= t_us]

    def dmesg(self) -> str:
        return self.platform.dmesg_text()


def _mean(msgs: list, axis: str) -> float:
    return statistics.fmean(getattr(m, axis) for m in msgs)


def test_still_level_board_rates_and_values() -> None:
    b = Board()
    b.start()
    b.run_ms(200)                                  # boot, reset, configure
    t0 = b.platform.time_us()
    b.run_ms(1000)
    gyro = b.since("sensor_gyro", t0)
    accel = b.since("sensor_accel", t0)
    mag = b.since("sensor_mag", t0)
    assert 758 <= len(gyro) <= 762                 # 760 Hz ODR, one read per DRDY
    assert 399 <= len(accel) <= 401                # 1600 Hz in FIFO batches of 4
    assert 49 <= len(mag) <= 51                    # 50 Hz
    assert all(m.samples == 4 for m in accel)
    for axis in "xyz":
        assert abs(_mean(gyro, axis)) < 0.02       # rad/s: zero rate within bias/noise
        assert 0.003 < statistics.pstdev(getattr(m, axis) for m in gyro) < 0.03
    assert abs(_mean(accel, "x")) < 0.4 and abs(_mean(accel, "y")) < 0.4
    assert abs(_mean(accel, "z") + G0_M_S2) < 0.4
    for axis, want in zip("xyz", b.env.mag_gauss):
        assert abs(_mean(mag, axis) - want) < 0.03
    assert gyro[-1].temperature == 35.0 and accel[-1].temperature == 35.0
    assert DeviceId.decode(gyro[0].device_id) == DeviceId(BUS_TYPE_SPI, 1, 1, 0x22)
    assert DeviceId.decode(accel[0].device_id) == DeviceId(BUS_TYPE_SPI, 1, 2, 0x11)
    assert DeviceId.decode(mag[0].device_id) == DeviceId(BUS_TYPE_SPI, 1, 2, 0x02)
    stamps = [m.timestamp_sample for m in gyro]
    assert stamps == sorted(stamps) and all(m.error_count == 0 for m in gyro + accel + mag)
    assert b.gyro_drv.perf_missed.events == 0 and b.accel_drv.perf_missed.events == 0
    assert "ERROR" not in b.dmesg() and "WARN" not in b.dmesg()


def test_polled_gyro_without_drdy_pin() -> None:
    b = Board(accel=False, drdy=False)
    b.start()
    b.run_ms(100)
    t0 = b.platform.time_us()
    b.run_ms(1000)
    assert 758 <= len(b.since("sensor_gyro", t0)) <= 762
    assert b.gyro_drv.perf_duplicate.events > 300     # 715 us polls of a 1316 us ODR


def test_rotating_board() -> None:
    b = Board()
    rate = (0.5, -1.0, 2.0)
    b.env.gyro_rad_s = rate
    b.env.accel_m_s2 = (1.0, 2.0, -G0_M_S2)
    b.start()
    b.run_ms(200)
    t0 = b.platform.time_us()
    b.run_ms(300)
    gyro, accel = b.since("sensor_gyro", t0), b.since("sensor_accel", t0)
    for axis, want in zip("xyz", rate):
        assert _mean(gyro, axis) == pytest.approx(want, rel=0.03, abs=0.02)
    for axis, want in zip("xyz", b.env.accel_m_s2):
        assert _mean(accel, axis) == pytest.approx(want, rel=0.03, abs=0.4)


def test_mounting_rotation_round_trip() -> None:
    """Chip mounted at yaw 270 (board->sensor matrix in the model), driver told the same."""
    k = Kernel()
    p, gpio, env = Platform(k), Gpio(k), Environment()
    env.gyro_rad_s = (1.0, 0.0, 0.0)
    bus = SpiBus(k, "SPI1")
    board_to_sensor = ((0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    bus.attach("PC13", L3gd20(k, env, rng_for(3, "g"), drdy_pin=gpio.pin("PB0"),
                              rotation=board_to_sensor))
    drv = L3gd20Driver(p, bus.device("PC13"), drdy_pin=gpio.pin("PB0"),
                       rotation="ROTATION_YAW_270")
    assert drv.start()
    k.run(100 * MS)
    m = p.orb.node("sensor_gyro", 0).last
    assert m.x == pytest.approx(1.0, abs=0.03) and abs(m.y) < 0.03


def test_wrong_id_refused_with_a_clear_message() -> None:
    b = Board()
    b.gyro.faults.wrong_id = 0x33
    b.accel.faults.absent = True
    assert not b.gyro_drv.start()
    assert not b.accel_drv.start()
    text = b.dmesg()
    assert "l3gd20] not starting: WHO_AM_I 0x33, expected 0xD4" in text
    assert "lsm303d] not starting: WHO_AM_I 0xFF, expected 0x49" in text
    assert "no device answering" in text


def _started(gyro: bool = True, accel: bool = True) -> Board:
    b = Board(gyro=gyro, accel=accel)
    b.start()
    b.run_ms(200)
    return b


@pytest.mark.parametrize("which", ["gyro", "accel"])
def test_absent_chip_detected_reset_and_recovers(which: str) -> None:
    b = _started(gyro=which == "gyro", accel=which == "accel")
    chip, drv = (b.gyro, b.gyro_drv) if which == "gyro" else (b.accel, b.accel_drv)
    chip.faults.absent = True
    b.run_ms(300)
    # All-0xFF bursts are bad transfers; whichever comes first (10 in a row, or the periodic
    # WHO_AM_I check) resets the chip, and the reset then finds nobody answering.
    assert drv.perf_bad_transfer.events >= 1 and drv.perf_reset.events >= 1
    assert "reset failed: WHO_AM_I 0xFF, expected" in b.dmesg()
    assert "(no device answering)" in b.dmesg()
    if which == "accel":
        assert "10 bad transfers in a row, resetting" in b.dmesg()
    chip.faults.absent = False
    t0 = b.platform.time_us()
    b.run_ms(400)
    topic = "sensor_gyro" if which == "gyro" else "sensor_accel"
    recent = b.since(topic, t0 + 200_000)
    assert len(recent) > 50 and recent[-1].error_count == drv.error_count


def test_wrong_id_at_runtime_detected() -> None:
    b = _started()
    b.gyro.faults.wrong_id = 0xD3 ^ 0xFF
    b.accel.faults.wrong_id = 0x33
    b.run_ms(1000)
    text = b.dmesg()
    assert "[l3gd20] register 0x0F read 0x2C, expected 0xD4" in text
    assert "[l3gd20] reset failed: WHO_AM_I 0x2C, expected 0xD4" in text
    assert "[lsm303d] register 0x0F read 0x33" in text
    assert "[lsm303d] reset failed: WHO_AM_I 0x33, expected 0x49" in text


def test_frozen_data_detected() -> None:
    b = _started()
    b.gyro.faults.frozen = True
    b.accel.faults.frozen = True
    b.run_ms(300)
    assert b.gyro_drv.perf_stuck.events >= 1 and b.accel_drv.perf_stuck.events >= 1
    assert "[l3gd20] data stuck at" in b.dmesg() and "[lsm303d] accel data stuck" in b.dmesg()


def test_random_data_counted_as_bad() -> None:
    b = _started()
    b.gyro.faults.random_data = True
    b.accel.faults.random_data = True
    b.run_ms(200)
    assert b.gyro_drv.perf_bad_transfer.events > 10       # OUT_TEMP garbage
    assert b.accel_drv.perf_bad_transfer.events > 0       # TEMP_OUT garbage
    assert b.gyro_drv.error_count > 10


def test_missing_drdy_falls_back_to_polling() -> None:
    b = _started(accel=False)
    b.gyro.faults.drdy_stuck = True
    t0 = b.platform.time_us()
    b.run_ms(500)
    assert b.gyro_drv.perf_drdy_timeout.events == 1
    assert "no data-ready interrupt" in b.dmesg()
    assert len(b.since("sensor_gyro", t0)) > 370          # polling keeps the data flowing
    b.gyro.faults.drdy_stuck = False
    b.run_ms(50)
    assert "data-ready interrupts back" in b.dmesg()


def test_saturation_reported_in_clip_counters() -> None:
    b = _started()
    b.gyro.faults.saturate = True
    b.accel.faults.saturate = True
    t0 = b.platform.time_us()
    b.run_ms(20)
    gyro, accel = b.since("sensor_gyro", t0), b.since("sensor_accel", t0)
    assert gyro and all(m.clip_counter == [1, 1, 1] for m in gyro[2:])
    assert accel and accel[-1].clip_counter == [4, 4, 4]
    assert gyro[-1].x == pytest.approx(32767 * 0.07 * math.pi / 180)
    assert "gyro clipping" in b.dmesg() and "accel clipping" in b.dmesg()


def test_bias_step_shows_in_data() -> None:
    b = _started()
    b.gyro.faults.bias_step = (0.5, 0.0, 0.0)
    b.accel.faults.bias_step = (0.0, 3.0, 0.0)
    b.run_ms(10)
    t0 = b.platform.time_us()
    b.run_ms(100)
    assert _mean(b.since("sensor_gyro", t0), "x") == pytest.approx(0.5, abs=0.03)
    assert _mean(b.since("sensor_accel", t0), "y") == pytest.approx(3.0, abs=0.4)


def test_fifo_overrun_when_the_queue_stalls() -> None:
    b = _started(gyro=False)

    class Hog(WorkItem):
        cpu_cost_ns = 30 * MS             # something hogs wq:SPI1 for 30 ms

        def run(self) -> None:
            pass

    Hog(b.platform, "hog", "wq:SPI1").schedule_now()
    b.run_ms(100)
    assert b.accel_drv.perf_fifo_overflow.events == 1
    assert b.accel_drv.perf_missed.events == 1
    assert "accel FIFO overflow" in b.dmesg()
    n = len(b.msgs["sensor_accel"])
    b.run_ms(10)
    assert len(b.msgs["sensor_accel"]) == n + 4       # back to normal


def test_changed_register_is_rewritten() -> None:
    b = _started()
    glitch = b.bus.device("PC13", mode=3, clock_hz=1_000_000)
    glitch.transfer(bytes((0x23, 0x00)))            # CTRL_REG4 lost: 250 dps, no BDU
    other = b.bus.device("PC15", mode=3, clock_hz=1_000_000)
    other.transfer(bytes((0x21, 0x00)))             # CTRL2 lost: +-2 g
    b.run_ms(1000)
    assert b.gyro_drv.perf_bad_register.events == 1
    assert b.accel_drv.perf_bad_register.events == 1
    assert b.gyro.regs["CTRL_REG4"] == 0xB0 and b.accel.regs["CTRL2"] == 0x20
    assert "register 0x23 read 0x00, expected 0xB0" in b.dmesg()


def test_same_seed_same_samples() -> None:
    runs = []
    for _ in range(2):
        b = Board(seed=5)
        b.start()
        b.run_ms(250)
        runs.append([(m.timestamp_sample, m.x, m.y, m.z) for topic in b.msgs
                     for m in b.msgs[topic]])
    assert runs[0] == runs[1] and len(runs[0]) > 100
