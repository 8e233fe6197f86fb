"""MPU-6000 model against the datasheet facts (shared/reference/sensors.md section 1).

Everything goes through the SPI bus and the INT pin, as a driver would see it. Transfers run
inside a kernel event at the current time (as a driver's work item would), so bus time does not
pile up between calls.
"""

from __future__ import annotations

import json
import struct
from itertools import pairwise
from pathlib import Path

import pytest

from board.gpio import Gpio
from board.kernel import NS_PER_MS, Kernel
from board.spi import SpiBus
from peripherals.errors import AxisErrors, rng_for
from peripherals.mpu6000 import Mpu6000
from peripherals.mpu6000.registers import SELF_TEST_TRIM
from peripherals.physics import Environment
from common.units import G0_M_S2

REFERENCE = Path(__file__).resolve().parents[3] / "shared" / "fixtures" / "mpu6000" / \
    "mpu6000_register_reference.json"
DEG = 0.017453292519943295


class Chip:
    """A chip on SPI1 (CS PC2) with its INT on PD15, and register helpers."""

    def __init__(self, noisy: bool = False, **kw) -> None:
        self.kernel = k = Kernel("test")
        self.env = Environment()
        self.gpio = Gpio(k)
        self.pin = self.gpio.pin("PD15")
        quiet = {} if noisy else {"gyro_errors": AxisErrors(), "accel_errors": AxisErrors()}
        quiet.update(kw)
        kw = {"power_up_ms": 0.0, **quiet}
        self.chip = Mpu6000(k, self.env, rng_for(7, "mpu6000"), drdy_pin=self.pin, **kw)
        self.bus = SpiBus(k, "spi1")
        self.bus.attach("PC2", self.chip)
        self.dev = self.bus.device("PC2", mode=3, clock_hz=1_000_000)
        self.edges: list[tuple[int, int]] = []
        self.pin.on_change(lambda pin, t, level: self.edges.append((t, level)))

    def xfer(self, tx: bytes, clock_hz: int = 1_000_000) -> bytes:
        out: list[bytes] = []

        def run() -> None:
            self.dev.max_speed_hz = clock_hz
            out.append(self.dev.transfer(tx))
        self.kernel.call_later(0, run)
        self.kernel.run(self.kernel.now_ns)
        return out[0]

    def rd(self, addr: int, n: int = 1, clock_hz: int = 1_000_000) -> bytes:
        return self.xfer(bytes((0x80 | addr,)) + bytes(n), clock_hz)[1:]

    def r8(self, addr: int) -> int:
        return self.rd(addr)[0]

    def wr(self, addr: int, *values: int, clock_hz: int = 1_000_000) -> None:
        self.xfer(bytes((addr,) + values), clock_hz)

    def data(self) -> tuple[int, ...]:
        """ACCEL x y z, TEMP, GYRO x y z from one 14-byte burst (fast clock)."""
        return struct.unpack(">7h", self.rd(0x3B, 14, 20_000_000))

    def wake(self, **regs: int) -> None:
        for name, value in regs.items():
            self.wr(self.chip.regs.addr(name), value)
        self.wr(0x6B, 0x01)

    def run_ms(self, ms: float) -> None:
        self.kernel.run_for(int(ms * NS_PER_MS))

    def fifo_count(self) -> int:
        h, lo = self.rd(0x72, 2, 20_000_000)
        return h << 8 | lo


@pytest.fixture
def c() -> Chip:
    return Chip()


# -- identity, reset values, framing ---------------------------------------------------------------

def test_reset_values_of_every_register(c: Chip) -> None:
    if not REFERENCE.exists():
        raise AssertionError(f"{REFERENCE} not present")
    ref = json.loads(REFERENCE.read_text())["reset_values_documented"]["by_address"]
    per_part = {0x0C: 0x58, 0x0D: SELF_TEST_TRIM[0], 0x0E: SELF_TEST_TRIM[1],
                0x0F: SELF_TEST_TRIM[2], 0x10: SELF_TEST_TRIM[3]}  # the documented caveats
    for key, value in ref.items():
        addr = int(key, 16)
        assert c.r8(addr) == per_part.get(addr, value), f"register {key}"
    assert all(v != 0 for v in SELF_TEST_TRIM)


def test_who_am_i_on_the_wire(c: Chip) -> None:
    assert c.xfer(b"\xf5\x00") == b"\x00\x68"  # MOSI F5 00 -> MISO xx 68 (address byte: 00)


def test_product_id_is_per_part() -> None:
    assert Chip(product_id=0x54).r8(0x0C) == 0x54


def test_write_read_back_and_auto_increment(c: Chip) -> None:
    c.wr(0x19, 0x07, 0x03, 0x18, 0x10)  # SMPLRT_DIV, CONFIG, GYRO_CONFIG, ACCEL_CONFIG
    assert c.rd(0x19, 4) == bytes((0x07, 0x03, 0x18, 0x10))


def test_read_only_and_undefined_registers(c: Chip) -> None:
    c.wr(0x75, 0x00)
    c.wr(0x0C, 0x12)
    c.wr(0x3B, 0x55)
    assert (c.r8(0x75), c.r8(0x0C), c.r8(0x3B)) == (0x68, 0x58, 0x00)
    c.wr(0x11, 0xAB)
    c.wr(0x7F, 0xAB)
    assert c.r8(0x11) == 0x00 and c.r8(0x7F) == 0x00  # reserved: reads 0, writes ignored
    assert c.chip.regs.ignored_writes == 3


def test_reserved_bits_keep_their_reset_value(c: Chip) -> None:
    c.wr(0x1B, 0xFF)
    assert c.r8(0x1B) == 0xF8  # GYRO_CONFIG bits 2:0 are reserved


def test_fifo_r_w_does_not_increment(c: Chip) -> None:
    c.wr(0x6A, 0x40)
    c.wr(0x74, 1, 2, 3, 4)  # a burst write stays on FIFO_R_W
    assert c.fifo_count() == 4
    assert c.rd(0x74, 3) == b"\x01\x02\x03"
    assert c.fifo_count() == 1
    assert c.rd(0x74, 3) == b"\x04\x04\x04"  # empty: the last byte again
    assert c.r8(0x75) == 0x68  # the next register was not touched


def test_fifo_count_low_byte_is_latched_by_the_high_read(c: Chip) -> None:
    c.wr(0x74, *range(20))
    assert c.r8(0x72) == 0
    c.rd(0x74, 5)
    assert c.r8(0x73) == 20  # latched at the FIFO_COUNTH read
    assert c.fifo_count() == 15


# -- power, sleep and reset ------------------------------------------------------------------------

def test_asleep_after_reset_no_samples(c: Chip) -> None:
    c.wr(0x23, 0x78)
    c.wr(0x6A, 0x40)
    c.wr(0x38, 0x01)
    c.run_ms(50)
    assert c.chip.samples_produced == 0
    assert c.data() == (0,) * 7
    assert c.fifo_count() == 0 and c.r8(0x3A) == 0 and c.edges == []


def test_power_up_takes_100_ms() -> None:
    c = Chip(power_up_ms=100.0)
    assert c.r8(0x75) == 0x00
    c.run_ms(100)
    assert c.r8(0x75) == 0x68


def test_device_reset_restores_and_is_deaf_for_100_ms(c: Chip) -> None:
    c.wake(GYRO_CONFIG=0x18, SMPLRT_DIV=4)
    c.run_ms(5)
    c.wr(0x6B, 0x80)
    c.run_ms(50)
    assert c.r8(0x75) == 0x00  # still resetting
    c.wr(0x19, 9)  # ignored
    c.run_ms(50)
    assert (c.r8(0x75), c.r8(0x6B), c.r8(0x1B), c.r8(0x19)) == (0x68, 0x40, 0x00, 0x00)
    assert c.data() == (0,) * 7


def test_power_rail_off_and_on(c: Chip) -> None:
    c.wake()
    c.chip.set_power(False)
    assert c.r8(0x75) == 0xFF
    c.chip.set_power(True)
    c.run_ms(101)
    assert (c.r8(0x75), c.r8(0x6B)) == (0x68, 0x40)


def test_clock_stop_produces_nothing(c: Chip) -> None:
    c.wr(0x6B, 0x07)
    c.run_ms(10)
    assert c.chip.samples_produced == 0


# -- scaling ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("afs_sel, counts", [(0, 16384), (1, 8192), (2, 4096), (3, 2048)])
def test_accel_scale(c: Chip, afs_sel: int, counts: int) -> None:
    c.env.accel_m_s2 = (0.0, 0.0, G0_M_S2)
    c.wake(ACCEL_CONFIG=afs_sel << 3)
    c.run_ms(2)
    assert c.data()[:3] == (0, 0, counts)


def test_rev_c_doubles_accel_sensitivity() -> None:
    c = Chip(product_id=0x54)
    c.env.accel_m_s2 = (0.0, 0.0, G0_M_S2)
    c.wake(ACCEL_CONFIG=0x18)
    c.run_ms(2)
    assert c.data()[2] == 4096


@pytest.mark.parametrize("fs_sel, counts", [(0, 13100), (1, 6550), (2, 3280), (3, 1640)])
def test_gyro_scale(c: Chip, fs_sel: int, counts: int) -> None:
    c.env.gyro_rad_s = (100 * DEG, -100 * DEG, 0.0)
    c.wake(GYRO_CONFIG=fs_sel << 3)
    c.run_ms(1)
    assert c.data()[4:] == (counts, -counts, 0)


def test_saturation_at_the_rails(c: Chip) -> None:
    c.env.gyro_rad_s = (300 * DEG, -300 * DEG, 0.0)
    c.env.accel_m_s2 = (0.0, 0.0, -3 * G0_M_S2)
    c.wake()  # +-250 deg/s, +-2 g
    c.run_ms(2)
    _, _, az, _, gx, gy, _ = c.data()
    assert (az, gx, gy) == (-32768, 32767, -32768)


def test_temperature(c: Chip) -> None:
    c.env.board_temperature_c = 25.0
    c.wake()
    c.run_ms(1)
    assert c.rd(0x41, 2, 20_000_000) == b"\xf0\xb0"  # -3920: (25 - 36.53) * 340


def test_rotation_enum_is_board_to_sensor() -> None:
    c = Chip(rotation="ROTATION_YAW_90")
    c.env.gyro_rad_s = (100 * DEG, 0.0, 0.0)
    c.wake()
    c.run_ms(1)
    assert c.data()[4:] == (0, -13100, 0)  # board x is sensor -y for a yaw-90 mounting


def test_self_test_shift_follows_the_trims(c: Chip) -> None:
    c.wake()
    c.run_ms(1)
    base = c.data()[4]
    c.wr(0x1B, 0xE0)
    c.run_ms(10)  # let the 256 Hz DLPF settle
    g_trim = SELF_TEST_TRIM[0] & 0x1F
    assert c.data()[4] - base == round(25 * 131 * 1.046 ** (g_trim - 1))


# -- sample rate and data-ready ---------------------------------------------------------------

@pytest.mark.parametrize("dlpf, div, period_us", [
    (0, 0, 125), (7, 0, 125), (1, 0, 1000), (6, 0, 1000), (3, 4, 5000), (0, 7, 1000)])
def test_drdy_period(c: Chip, dlpf: int, div: int, period_us: int) -> None:
    c.wake(CONFIG=dlpf, SMPLRT_DIV=div, INT_PIN_CFG=0x80, INT_ENABLE=0x01)
    c.edges.clear()
    c.run_ms(20 * period_us / 1000)
    falls = [t for t, level in c.edges if level == 0]
    assert len(falls) >= 19
    assert {b - a for a, b in pairwise(falls)} == {period_us * 1000}


def test_drdy_pulse_is_50_us_active_high(c: Chip) -> None:
    c.wake(INT_ENABLE=0x01)
    c.run_ms(1)
    rises = [t for t, lv in c.edges if lv == 1]
    falls = [t for t, lv in c.edges if lv == 0]
    widths = [b - a for a, b in zip(rises, falls, strict=False)]  # the last pulse may be running
    assert len(widths) >= 7 and set(widths) == {50_000}


def test_drdy_latched_until_int_status_read(c: Chip) -> None:
    c.wake(INT_PIN_CFG=0xA0, INT_ENABLE=0x01)  # active low, latched
    c.run_ms(1)
    assert c.pin.level == 0 and len([e for e in c.edges if e[1] == 0]) == 1
    assert c.r8(0x3A) & 0x01
    assert c.pin.level == 1
    c.run_ms(0.125)
    assert c.pin.level == 0


def test_fifo_overflow_interrupt_without_data_ready(c: Chip) -> None:
    t_wake = c.kernel.now_ns
    c.wake(INT_PIN_CFG=0x20, INT_ENABLE=0x10, FIFO_EN=0x78, USER_CTRL=0x40)  # latched
    c.run_ms(20)
    # The 86th 12-byte record overflows 1024 bytes; one latched assertion, no per-sample edges.
    assert c.edges == [(t_wake + 86 * 125_000, 1)]
    assert c.r8(0x3A) & 0x10 and c.pin.level == 0


def test_open_drain_int_releases_to_the_pull() -> None:
    c = Chip()
    c.gpio.pin("PD15", pull="up")
    c.wake(INT_PIN_CFG=0xE0, INT_ENABLE=0x01)  # active low, open drain, latched
    assert c.pin.level == 1 and not c.pin.driven
    c.run_ms(0.2)
    assert c.pin.level == 0 and c.pin.driven
    c.r8(0x3A)
    assert c.pin.level == 1 and not c.pin.driven


def test_int_status_read_to_clear_and_int_rd_clear(c: Chip) -> None:
    c.wake()
    c.run_ms(1)
    assert c.r8(0x3A) == 0x01 and c.r8(0x3A) == 0x00
    c.wr(0x37, 0x10)  # INT_RD_CLEAR: any read clears
    c.run_ms(1)
    c.r8(0x75)
    assert c.r8(0x3A) == 0x00


def test_legacy_burst_from_int_status(c: Chip) -> None:
    c.env.accel_m_s2 = (0.0, 0.0, G0_M_S2)
    c.wake(ACCEL_CONFIG=0x18)
    c.run_ms(1)
    rx = c.xfer(b"\xba" + bytes(15))  # legacy PX4: INT_STATUS then the 14 data bytes
    assert rx[1] == 0x01 and struct.unpack(">7h", rx[2:])[2] == 2048
    assert c.r8(0x3A) == 0x00  # cleared by that read


def test_no_kernel_events_when_nobody_can_see_samples(c: Chip) -> None:
    c.wake(FIFO_EN=0x78, USER_CTRL=0x40)
    assert len(c.kernel) == 0
    c.run_ms(10)
    assert c.fifo_count() == 80 * 12  # yet the samples are there when read


# -- FIFO --------------------------------------------------------------------------------------

def test_fifo_fill_rate_and_record_layout(c: Chip) -> None:
    c.env.accel_m_s2 = (0.0, 0.0, G0_M_S2)
    c.env.gyro_rad_s = (100 * DEG, 0.0, 0.0)
    c.wake(ACCEL_CONFIG=0x18, FIFO_EN=0x78, USER_CTRL=0x40)
    c.run_ms(1)
    assert c.fifo_count() == 8 * 12  # 8 kHz, 12-byte records
    rec = struct.unpack(">6h", c.rd(0x74, 12, 20_000_000))
    assert rec == (0, 0, 2048, 13100, 0, 0)


def test_fifo_overflow_keeps_the_newest_bytes(c: Chip) -> None:
    c.wake(CONFIG=1, FIFO_EN=0x80, USER_CTRL=0x40)  # 1 kHz, 2-byte TEMP records
    for i in range(600):
        c.env.board_temperature_c = 20.0 + i * 0.01
        c.run_ms(1)
        c.r8(0x38)  # any access: the chip catches up to now, reading the new temperature
    assert c.fifo_count() == 1024
    assert c.r8(0x3A) & 0x10  # FIFO_OFLOW_INT
    temps = struct.unpack(">512h", c.rd(0x74, 1024, 20_000_000))
    expect = [round((20.0 + i * 0.01 - 36.53) * 340) for i in range(88, 600)]
    assert list(temps) == expect


def test_fifo_reset_and_sig_cond_reset(c: Chip) -> None:
    c.env.accel_m_s2 = (0.0, 0.0, G0_M_S2)
    c.wake(FIFO_EN=0x08, USER_CTRL=0x40)
    c.run_ms(1)
    c.wr(0x6A, 0x44)
    assert c.fifo_count() == 0 and c.r8(0x6A) == 0x40  # strobe self-clears
    c.wr(0x6A, 0x41)
    assert c.data() == (0,) * 7 and c.r8(0x6A) == 0x40


def test_accel_repeats_eight_times_at_8khz() -> None:
    c = Chip(noisy=True)
    c.wake(FIFO_EN=0x78, USER_CTRL=0x40)
    c.run_ms(4)
    recs = [struct.unpack(">6h", c.rd(0x74, 12, 20_000_000)) for _ in range(32)]
    accel = [r[:3] for r in recs]
    changes = [i for i in range(1, 32) if accel[i] != accel[i - 1]]
    assert changes == [7, 15, 23, 31]  # sample k=8, 16, ... starts a new 1 ms reading
    assert len({r[3:] for r in recs}) > 16  # gyro is new every sample


# -- SPI clock limits --------------------------------------------------------------------------

def test_register_access_above_1_1_mhz_is_refused(c: Chip) -> None:
    assert c.rd(0x75, 1, 2_000_000) == b"\xff"
    c.wr(0x19, 0x05, clock_hz=2_000_000)
    assert c.r8(0x19) == 0x00
    assert c.chip.too_fast_count == 2
    c.wake()
    c.run_ms(1)
    assert c.rd(0x3A, 1, 20_000_000) == b"\x01"  # data and status are fine at 20 MHz
    assert c.rd(0x3B, 2, 25_000_000) == b"\xff\xff"  # but not above 22 MHz


# -- faults ------------------------------------------------------------------------------------

def test_fault_wrong_id_and_absent(c: Chip) -> None:
    c.chip.faults.wrong_id = 0x70
    assert c.r8(0x75) == 0x70
    c.chip.faults.clear()
    c.chip.faults.absent = True
    assert c.rd(0x75, 4) == b"\xff" * 4


def test_fault_drdy_stuck(c: Chip) -> None:
    c.wake(INT_ENABLE=0x01)
    c.chip.faults.drdy_stuck = True
    c.run_ms(2)
    assert c.edges == [] and c.r8(0x3A) & 0x01  # data still ready, the line never moves


def test_fault_frozen_random_saturate_bias() -> None:
    c = Chip(noisy=True)
    c.wake()
    c.run_ms(1)
    c.chip.faults.frozen = True
    frozen = c.data()
    c.run_ms(1)
    assert c.data() == frozen
    c.chip.faults.frozen = False
    c.chip.faults.random_data = True
    c.run_ms(1)
    a = c.data()
    c.run_ms(1)
    b = c.data()
    assert a != b and max(map(abs, a + b)) > 1000
    c.chip.faults.clear()
    c.chip.faults.saturate = True
    c.run_ms(1)
    d = c.data()
    assert d[:3] + d[4:] == (32767,) * 6
    c.chip.faults.clear()
    c.chip.faults.bias_step = (0.0, 0.0, 10 * DEG)
    c.run_ms(10)  # the step goes through the DLPF
    assert abs(c.data()[6] - 1310) < 20  # +10 deg/s at 131 LSB/(deg/s), plus noise


def test_same_seed_same_bytes() -> None:
    def capture() -> bytes:
        c = Chip(noisy=True)
        c.wake(FIFO_EN=0x78, USER_CTRL=0x40)
        c.run_ms(5)
        return c.rd(0x74, 480, 20_000_000)
    assert capture() == capture()
