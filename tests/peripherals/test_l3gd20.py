"""L3GD20 model conformance: facts from the reference sheet section 2, checked over the SPI bus."""

from __future__ import annotations

import math
import struct

import pytest

from board.gpio import Gpio
from board.kernel import Kernel
from board.spi import SpiBus
from peripherals.errors import AxisErrors, rng_for
from peripherals.l3gd20 import L3gd20
from peripherals.physics import Environment

DPS = math.pi / 180.0

#: Reset values from the sheet's register table (2.4), independent of the model's table.
RESET_VALUES = {
    0x0F: 0xD4, 0x20: 0x07, 0x21: 0x00, 0x22: 0x00, 0x23: 0x00, 0x24: 0x00, 0x25: 0x00,
    0x27: 0x00, 0x2E: 0x00, 0x2F: 0x20, 0x30: 0x00, 0x32: 0x00, 0x33: 0x00, 0x34: 0x00,
    0x35: 0x00, 0x36: 0x00, 0x37: 0x00, 0x38: 0x00, 0x39: 0x00,
    **{a: 0x00 for a in range(0x0F)},
}


class Rig:
    """One kernel, SPI1 with the gyro on PC13, DRDY on PB0; helpers in driver words."""

    def __init__(self, exact: bool = True) -> None:
        self.kernel = Kernel("test")
        self.env = Environment()
        self.gpio = Gpio(self.kernel)
        self.pin = self.gpio.pin("PB0")
        self.bus = SpiBus(self.kernel, "SPI1")
        errors = AxisErrors() if exact else None
        self.chip = L3gd20(self.kernel, self.env, rng_for(7, "l3gd20"), drdy_pin=self.pin,
                           errors=errors)
        self.bus.attach("PC13", self.chip)
        self.dev = self.bus.device("PC13", mode=3, clock_hz=10_000_000)
        self.edges: list[tuple[int, int]] = []
        self.pin.on_change(lambda _p, t, level: self.edges.append((t, level)))

    def rd(self, addr: int) -> int:
        return self.dev.transfer(bytes((0x80 | addr, 0)))[1]

    def wr(self, addr: int, value: int) -> None:
        self.dev.transfer(bytes((addr, value)))

    def burst(self, addr: int, n: int, ms: bool = True) -> bytes:
        return self.dev.transfer(bytes((0x80 | (0x40 if ms else 0) | addr,)) + bytes(n))[1:]

    def now(self) -> int:
        """Start the next transfer exactly at the kernel's time (tests run outside events)."""
        self.kernel.busy_ns = 0
        return self.kernel.now_ns

    def run_ms(self, ms: float) -> None:
        self.kernel.run(self.kernel.now_ns + int(ms * 1_000_000))

    def xyz(self) -> tuple[int, int, int]:
        return struct.unpack("<3h", self.burst(0x28, 6))


@pytest.fixture
def rig() -> Rig:
    return Rig()


def test_reset_values_of_every_register(rig: Rig) -> None:
    for addr, value in RESET_VALUES.items():
        assert rig.rd(addr) == value, f"register 0x{addr:02X}"


def test_who_am_i_and_read_bit(rig: Rig) -> None:
    assert rig.rd(0x0F) == 0xD4
    # Without the read bit the same byte is a write (ignored for a read-only register).
    rig.wr(0x0F, 0x12)
    assert rig.rd(0x0F) == 0xD4
    assert rig.chip.regs.ignored_writes == 1


def test_auto_increment_only_with_ms(rig: Rig) -> None:
    rig.dev.transfer(bytes((0x40 | 0x21, 0x05, 0x08, 0x80)))     # MS write: 0x21, 0x22, 0x23
    assert rig.burst(0x21, 3) == bytes((0x05, 0x08, 0x80))
    assert rig.burst(0x20, 3, ms=False) == bytes((0x07, 0x07, 0x07))
    rig.dev.transfer(bytes((0x25, 0x11, 0x22, 0x33)))             # no MS: all to REFERENCE
    assert rig.rd(0x25) == 0x33 and rig.rd(0x26) != 0x22


def test_read_only_and_reserved_bits(rig: Rig) -> None:
    for addr in (0x26, 0x27, 0x28, 0x2F, 0x31):
        before = rig.rd(addr)
        rig.wr(addr, 0x5A)
        assert rig.rd(addr) == before
    rig.wr(0x21, 0xFF)                 # CTRL_REG2 bits 7:6 must be 0
    assert rig.rd(0x21) == 0x3F
    rig.wr(0x05, 0x20)                 # reserved 0x05 is storage (PX4's "disable I2C")
    assert rig.rd(0x05) == 0x20
    rig.wr(0x39, 0x08)                 # LOW_ODR kept even on the plain L3GD20
    assert rig.rd(0x39) == 0x08


@pytest.mark.parametrize("fs, dps, counts", [(0x00, 100.0, 11429), (0x10, 100.0, 5714),
                                             (0x20, 100.0, 1429), (0x30, -100.0, -1429)])
def test_scale_per_range(rig: Rig, fs: int, dps: float, counts: int) -> None:
    rig.env.gyro_rad_s = (dps * DPS, -dps * DPS, 0.0)
    rig.wr(0x23, fs)
    rig.wr(0x20, 0xCF)
    rig.run_ms(2)
    assert rig.xyz() == (counts, -counts, 0)


def test_sheet_example_bytes(rig: Rig) -> None:
    """100 dps at 2000 dps -> 1429 = 0x0595 -> bytes 95 05 (sheet 2.6)."""
    rig.env.gyro_rad_s = (100 * DPS, 0.0, 0.0)
    rig.wr(0x23, 0x20)
    rig.wr(0x20, 0xCF)
    rig.run_ms(2)
    assert rig.burst(0x28, 2) == b"\x95\x05"


def test_big_endian_swaps_bytes(rig: Rig) -> None:
    rig.env.gyro_rad_s = (100 * DPS, 0.0, 0.0)
    rig.wr(0x23, 0x60)                  # BLE, 2000 dps
    rig.wr(0x20, 0xCF)
    rig.run_ms(2)
    assert rig.burst(0x28, 2) == b"\x05\x95"


@pytest.mark.parametrize("dr, odr_mhz", [(0, 95_000), (1, 190_000), (2, 380_000),
                                         (3, 760_000)])
def test_odr_gives_exact_drdy_edges(rig: Rig, dr: int, odr_mhz: int) -> None:
    rises: list[int] = []

    def isr(_pin: object, t_ns: int) -> None:
        rises.append(t_ns)
        rig.burst(0x28, 6)                        # read the sample: DRDY falls

    rig.gpio.attach_interrupt(rig.pin, isr)
    rig.wr(0x22, 0x08)                            # I2_DRDY
    t0 = rig.now()
    rig.wr(0x20, (dr << 6) | 0x0F)
    rig.run_ms(50)
    expected = [t0 + -(-k * 10**12 // odr_mhz) for k in range(1, len(rises) + 1)]
    assert rises == expected
    assert len(rises) == 50_000_000 * odr_mhz // 10**12
    assert all(level == (i % 2 == 0) for i, (_t, level) in enumerate(rig.edges))


def test_no_events_unless_drdy_enabled_and_needed(rig: Rig) -> None:
    rig.wr(0x20, 0xEF)
    rig.run_ms(100)
    assert len(rig.kernel) == 0                   # sampling is lazy: nothing scheduled
    rig.wr(0x22, 0x08)
    rig.run_ms(100)                               # DRDY high, nobody reads: no more events
    assert rig.pin.level == 1 and len(rig.kernel) == 0
    assert rig.edges == [(rig.edges[0][0], 1)]


def test_status_data_ready_and_overrun(rig: Rig) -> None:
    rig.wr(0x20, 0xCF)
    assert rig.rd(0x27) == 0x00
    rig.run_ms(1.4)                               # one sample at 760 Hz
    assert rig.rd(0x27) == 0x0F
    rig.xyz()
    assert rig.rd(0x27) == 0x00
    rig.run_ms(3)                                 # two more samples, unread
    assert rig.rd(0x27) == 0xFF
    rig.burst(0x28, 2)                            # X only
    assert rig.rd(0x27) == 0xEE


def test_bdu_keeps_low_and_high_from_one_sample() -> None:
    for bdu, expected_high in ((0x80, 0x05), (0x00, 0x0B)):
        rig = Rig()
        rig.env.gyro_rad_s = (100 * DPS, 0.0, 0.0)          # 1429 = 0x0595
        rig.wr(0x23, 0x20 | bdu)
        rig.wr(0x20, 0xCF)
        rig.run_ms(1.4)
        assert rig.rd(0x28) == 0x95
        rig.env.gyro_rad_s = (200 * DPS, 0.0, 0.0)          # 2857 = 0x0B29
        rig.run_ms(3)
        assert rig.rd(0x29) == expected_high


def _fill(rig: Rig, n: int) -> None:
    """Let ``n`` samples come, each with its own rate (k dps), touching the chip after each."""
    for _ in range(n):
        k = rig.chip.ch.k + 1
        rig.env.gyro_rad_s = (k * DPS, 0.0, 0.0)
        rig.kernel.run(rig.chip.ch.sample_time(k))
        rig.rd(0x0F)


def test_fifo_mode_fill_watermark_overrun(rig: Rig) -> None:
    rig.wr(0x23, 0x00)                      # 250 dps: k dps = 114.29 k counts
    rig.wr(0x24, 0x40)                      # FIFO_EN
    rig.wr(0x2E, 0x20 | 10)                 # FIFO mode, WTM 10
    rig.wr(0x20, 0xCF)
    _fill(rig, 5)
    assert rig.rd(0x2F) == 0x05
    _fill(rig, 5)
    assert rig.rd(0x2F) == 0x80 | 10
    _fill(rig, 30)                          # 40 > 32: collection stopped at 32
    assert rig.rd(0x2F) == 0x80 | 0x40 | 31
    data = rig.burst(0x28, 32 * 6)          # one burst, wrapping 0x2D -> 0x28
    xs = [struct.unpack_from("<h", data, 6 * i)[0] for i in range(32)]
    assert xs == [round(k / 0.00875) for k in range(1, 33)]
    assert rig.rd(0x2F) == 0x40 | 0x20      # empty, still stopped until Bypass
    rig.wr(0x2E, 0x00)
    assert rig.rd(0x2F) == 0x20
    rig.wr(0x2E, 0x20)
    _fill(rig, 3)
    assert rig.rd(0x2F) & 0x1F == 3


def test_stream_mode_keeps_newest(rig: Rig) -> None:
    rig.wr(0x23, 0x00)
    rig.wr(0x24, 0x40)
    rig.wr(0x2E, 0x40)                      # Stream
    rig.wr(0x20, 0xCF)
    _fill(rig, 40)
    assert rig.rd(0x2F) == 0x80 | 0x40 | 31   # WTM 0: set whenever not empty
    first = struct.unpack("<h", rig.burst(0x28, 6)[:2])[0]
    assert first == round(9 / 0.00875)      # samples 9..40 kept
    assert rig.rd(0x2F) == 0x80 | 31        # one read: OVRN clears in Stream mode


def test_burst_wraps_only_with_fifo(rig: Rig) -> None:
    rig.wr(0x2E, 0x07)
    assert rig.burst(0x2C, 3)[2] == 0x07    # Bypass: 0x2C, 0x2D, 0x2E (FIFO_CTRL)
    rig.wr(0x24, 0x40)
    rig.wr(0x2E, 0x47)
    assert rig.burst(0x2C, 3)[2] != 0x47    # FIFO on: 0x2C, 0x2D, then 0x28


def test_temperature(rig: Rig) -> None:
    rig.env.board_temperature_c = 35.0
    assert rig.rd(0x26) == 5                # OUT_TEMP = 40 - T
    rig.env.board_temperature_c = 50.0
    assert rig.rd(0x26) == 0xF6             # -10


def test_power_down_and_boot(rig: Rig) -> None:
    rig.wr(0x20, 0xC7)                      # PD = 0
    rig.run_ms(10)
    assert rig.rd(0x27) == 0 and rig.chip.ch.samples == 0
    rig.wr(0x23, 0xB0)
    rig.wr(0x24, 0x80)                      # BOOT
    assert rig.rd(0x24) & 0x80
    rig.run_ms(6)
    assert rig.rd(0x24) == 0x00 and rig.rd(0x23) == 0x00 and rig.rd(0x20) == 0x07


def test_clock_above_10_mhz_reads_high(rig: Rig) -> None:
    fast = rig.bus.device("PC13", mode=3, clock_hz=20_000_000)
    assert fast.transfer(b"\x8f\x00") == b"\xff\xff"


def test_faults(rig: Rig) -> None:
    rig.wr(0x20, 0xCF)
    rig.wr(0x23, 0x20)
    rig.chip.faults.wrong_id = 0x33
    assert rig.rd(0x0F) == 0x33
    rig.chip.faults.clear()
    rig.chip.faults.absent = True
    assert rig.burst(0x0F, 4) == b"\xff" * 4
    rig.wr(0x20, 0x00)                       # ignored while absent
    rig.chip.faults.clear()
    assert rig.rd(0x20) == 0xCF
    rig.chip.faults.saturate = True
    rig.run_ms(2)
    assert rig.xyz() == (32767, 32767, 32767)
    rig.chip.faults.clear()
    rig.chip.faults.bias_step = (10 * DPS, 0.0, 0.0)
    rig.run_ms(2)
    assert rig.xyz() == (143, 0, 0)
    rig.chip.faults.clear()
    rig.env.gyro_rad_s = (1.0, 0.0, 0.0)
    rig.run_ms(2)
    rig.chip.faults.frozen = True
    before = rig.xyz()
    rig.env.gyro_rad_s = (2.0, 0.0, 0.0)
    rig.run_ms(5)
    assert rig.rd(0x27) & 0x08 and rig.xyz() == before
    rig.chip.faults.clear()
    rig.chip.faults.random_data = True
    reads = {rig.burst(0x28, 6) for _ in range(5)}
    assert len(reads) == 5
    rig.chip.faults.clear()
    rig.chip.faults.drdy_stuck = True
    rig.wr(0x22, 0x08)
    rig.run_ms(10)
    assert rig.pin.level == 0
