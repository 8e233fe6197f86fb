"""LSM303D model conformance: facts from the reference sheet section 3, checked over the bus."""

from __future__ import annotations

import struct

import pytest

from board.gpio import Gpio
from board.kernel import Kernel
from board.spi import SpiBus
from peripherals.errors import AxisErrors, rng_for
from peripherals.lsm303d import Lsm303d
from peripherals.physics import Environment
from common.units import G0_M_S2

#: Reset values from the sheet's register table (3.3) including its [?] items.
RESET_VALUES = {
    **{a: 0x00 for a in range(0x05)}, 0x07: 0x00, 0x0F: 0x49, 0x12: 0xE8, 0x14: 0x00,
    0x15: 0x00, **{a: 0x00 for a in range(0x16, 0x1F)}, 0x1F: 0x00, 0x20: 0x07, 0x21: 0x00,
    0x22: 0x00, 0x23: 0x00, 0x24: 0x18, 0x25: 0x20, 0x26: 0x02, 0x27: 0x00, 0x2E: 0x00,
    0x2F: 0x20, 0x30: 0x00, 0x32: 0x00, 0x33: 0x00, 0x34: 0x00, 0x36: 0x00, 0x37: 0x00,
    0x38: 0x00, 0x3A: 0x00, 0x3B: 0x00, 0x3C: 0x00, 0x3D: 0x00, 0x3E: 0x00, 0x3F: 0x00,
}


class Rig:
    def __init__(self) -> None:
        self.kernel = Kernel("test")
        self.env = Environment()
        self.gpio = Gpio(self.kernel)
        self.int1 = self.gpio.pin("PB4")
        self.int2 = self.gpio.pin("PB1")
        self.bus = SpiBus(self.kernel, "SPI1")
        self.chip = Lsm303d(self.kernel, self.env, rng_for(7, "lsm303d"), int1_pin=self.int1,
                            int2_pin=self.int2, accel_errors=AxisErrors(),
                            mag_errors=AxisErrors())
        self.bus.attach("PC15", self.chip)
        self.dev = self.bus.device("PC15", mode=3, clock_hz=10_000_000)

    def rd(self, addr: int) -> int:
        return self.dev.transfer(bytes((0x80 | addr, 0)))[1]

    def wr(self, addr: int, value: int) -> None:
        self.dev.transfer(bytes((addr, value)))

    def burst(self, addr: int, n: int, ms: bool = True) -> bytes:
        return self.dev.transfer(bytes((0x80 | (0x40 if ms else 0) | addr,)) + bytes(n))[1:]

    def now(self) -> int:
        self.kernel.busy_ns = 0
        return self.kernel.now_ns

    def run_ms(self, ms: float) -> None:
        self.kernel.run(self.kernel.now_ns + int(ms * 1_000_000))

    def accel(self) -> tuple[int, int, int]:
        return struct.unpack("<3h", self.burst(0x28, 6))

    def mag(self) -> tuple[int, int, int]:
        return struct.unpack("<3h", self.burst(0x08, 6))


@pytest.fixture
def rig() -> Rig:
    return Rig()


def test_reset_values_of_every_register(rig: Rig) -> None:
    for addr, value in RESET_VALUES.items():
        assert rig.rd(addr) == value, f"register 0x{addr:02X}"


def test_id_read_bit_and_auto_increment(rig: Rig) -> None:
    assert rig.rd(0x0F) == 0x49
    rig.wr(0x0F, 0)
    assert rig.rd(0x0F) == 0x49
    assert rig.burst(0x24, 3) == bytes((0x18, 0x20, 0x02))
    assert rig.burst(0x24, 3, ms=False) == bytes((0x18, 0x18, 0x18))
    rig.dev.transfer(bytes((0x40 | 0x21, 0x20, 0x04, 0x08)))
    assert rig.burst(0x21, 3) == bytes((0x20, 0x04, 0x08))
    rig.wr(0x25, 0xFF)                                    # CTRL6: only MFS is defined
    assert rig.rd(0x25) == 0x60


@pytest.mark.parametrize("afs, counts", [(0, 16393), (1, 8197), (2, 5464), (3, 4098),
                                         (4, 1366)])
def test_accel_scale_per_range(rig: Rig, afs: int, counts: int) -> None:
    rig.env.accel_m_s2 = (G0_M_S2, 0.0, -G0_M_S2 / 2 if afs == 0 else -G0_M_S2)
    rig.wr(0x21, afs << 3)
    rig.wr(0x20, 0xA7)                                    # 1600 Hz, XYZ
    rig.run_ms(1)
    x, _y, _z = rig.accel()
    assert x == counts


def test_sheet_example_one_g_at_16g(rig: Rig) -> None:
    rig.env.accel_m_s2 = (G0_M_S2, 0.0, 0.0)
    rig.wr(0x21, 0x20)
    rig.wr(0x20, 0xA7)
    rig.run_ms(1)
    assert rig.burst(0x28, 2) == b"\x56\x05"


@pytest.mark.parametrize("mfs, gauss, counts", [(0, 0.5, 6250), (1, 0.5, 3125),
                                                (2, 0.5, 1562), (3, 0.5, 1044)])
def test_mag_scale_per_range(rig: Rig, mfs: int, gauss: float, counts: int) -> None:
    rig.env.mag_gauss = (gauss, -gauss, 0.0)
    rig.wr(0x25, mfs << 5)
    rig.wr(0x24, 0x74)                                    # high res, 100 Hz
    rig.wr(0x26, 0x00)                                    # continuous
    rig.run_ms(11)
    assert rig.mag() == (counts, -counts, 0)


def test_mag_offset_registers_subtract(rig: Rig) -> None:
    rig.env.mag_gauss = (0.5, 0.0, 0.0)
    rig.dev.transfer(bytes((0x40 | 0x16, 0x2C, 0x01)))     # OFFSET_X = 300
    rig.wr(0x25, 0x60)
    rig.wr(0x24, 0x74)
    rig.wr(0x26, 0x00)
    rig.run_ms(11)
    assert rig.mag()[0] == 1044 - 300


def _edges(rig: Rig, pin_name: str, read_addr: int, cfg: list[tuple[int, int]],
           run_ms: float) -> tuple[int, list[int]]:
    rises: list[int] = []

    def isr(_pin: object, t_ns: int) -> None:
        rises.append(t_ns)
        rig.burst(read_addr, 6)

    rig.gpio.attach_interrupt(pin_name, isr)
    for addr, value in cfg[:-1]:
        rig.wr(addr, value)
    t0 = rig.now()
    rig.wr(*cfg[-1])
    rig.run_ms(run_ms)
    return t0, rises


@pytest.mark.parametrize("aodr, odr_mhz", [(1, 3_125), (5, 50_000), (9, 800_000),
                                           (10, 1_600_000)])
def test_accel_odr_exact_int1_edges(rig: Rig, aodr: int, odr_mhz: int) -> None:
    t0, rises = _edges(rig, "PB4", 0x28, [(0x22, 0x04), (0x20, (aodr << 4) | 0x07)], 700)
    assert len(rises) == 700_000_000 * odr_mhz // 10**12
    assert rises == [t0 + -(-k * 10**12 // odr_mhz) for k in range(1, len(rises) + 1)]


@pytest.mark.parametrize("ctrl1, ctrl5, ctrl7, period_ns", [
    (0xA7, 0x74, 0x00, 10_000_000),      # 100 Hz
    (0x57, 0x74, 0x00, 20_000_000),      # 100 Hz asked with the accel at 50 Hz: 50 Hz
    (0xA7, 0x70, 0x00, 20_000_000),      # 50 Hz
    (0xA7, 0x74, 0x04, 320_000_000),     # MLP: 3.125 Hz
])
def test_mag_odr_exact_int2_edges(rig: Rig, ctrl1: int, ctrl5: int, ctrl7: int,
                                  period_ns: int) -> None:
    t0, rises = _edges(rig, "PB1", 0x08, [(0x23, 0x04), (0x20, ctrl1), (0x24, ctrl5),
                                          (0x26, ctrl7)], 700)
    assert rises == [t0 + k * period_ns for k in range(1, 700_000_000 // period_ns + 1)]


def test_interrupt_polarity_and_no_events_when_unrouted(rig: Rig) -> None:
    rig.wr(0x20, 0xA7)
    rig.wr(0x26, 0x00)
    rig.wr(0x24, 0x74)
    rig.run_ms(50)
    assert len(rig.kernel) == 0 and rig.int1.level == 0
    rig.wr(0x12, 0xE0)                     # IEA = 0: active low
    rig.wr(0x22, 0x04)
    assert rig.int1.level == 0             # data ready now: driven low (active)
    rig.accel()
    assert rig.int1.level == 1


def test_status_a_and_status_m(rig: Rig) -> None:
    rig.wr(0x20, 0xA7)
    rig.wr(0x24, 0x74)
    rig.wr(0x26, 0x00)
    rig.run_ms(0.7)
    assert rig.rd(0x27) == 0x0F and rig.rd(0x07) == 0x00
    rig.accel()
    assert rig.rd(0x27) == 0x00
    rig.run_ms(10)
    assert rig.rd(0x27) == 0xFF and rig.rd(0x07) == 0x0F


def test_bdu(rig: Rig) -> None:
    rig.env.accel_m_s2 = (G0_M_S2, 0.0, 0.0)               # 1366 = 0x0556
    rig.wr(0x21, 0x20)
    rig.wr(0x20, 0xAF)                                # 1600 Hz, BDU
    rig.run_ms(0.7)
    assert rig.rd(0x28) == 0x56
    rig.env.accel_m_s2 = (4 * G0_M_S2, 0.0, 0.0)           # 5464 = 0x1558
    rig.run_ms(2)
    assert rig.rd(0x29) == 0x05                       # same sample as the L byte
    rig.run_ms(1)
    assert rig.accel()[0] == 5464


def test_fifo_px4_burst_and_overrun(rig: Rig) -> None:
    rig.env.accel_m_s2 = (G0_M_S2, 0.0, 0.0)
    rig.wr(0x21, 0x20)
    rig.wr(0x1F, 0x40)                                 # FIFO_EN
    rig.wr(0x2E, 0x20 | 4)                             # FIFO mode, FTH 4
    rig.wr(0x20, 0xA7)
    rig.run_ms(2.5)
    src = rig.rd(0x2F)
    assert src == 0x80 | 4
    data = rig.burst(0x28, 4 * 6)                      # PX4: n x 6 bytes in one burst
    assert [struct.unpack_from("<h", data, 6 * i)[0] for i in range(4)] == [1366] * 4
    assert rig.rd(0x2F) == 0x20
    rig.run_ms(25)                                     # 40 samples: full at 32, stopped
    assert rig.rd(0x2F) == 0x80 | 0x40 | 31
    rig.wr(0x2E, 0x04)                                 # Bypass resets the FIFO
    assert rig.rd(0x2F) == 0x20
    rig.wr(0x2E, 0x24)
    rig.run_ms(1.3)
    assert rig.rd(0x2F) & 0x1F == 2


def test_temperature(rig: Rig) -> None:
    rig.env.board_temperature_c = 35.0
    rig.wr(0x24, 0xF0)                                 # TEMP_EN, 50 Hz
    rig.wr(0x26, 0x00)
    assert rig.burst(0x05, 2) == b"\x00\x00"
    rig.run_ms(21)
    assert rig.burst(0x05, 2) == b"\x50\x00"           # (35 - 25) * 8 = 80
    rig.env.board_temperature_c = 15.0
    rig.run_ms(20)
    assert rig.burst(0x05, 2) == b"\xb0\xff"           # -80, sign-extended


def test_single_conversion_returns_to_power_down(rig: Rig) -> None:
    rig.env.mag_gauss = (0.5, 0.0, 0.0)
    rig.wr(0x25, 0x60)
    rig.wr(0x24, 0x74)
    rig.wr(0x26, 0x01)
    rig.run_ms(5)
    assert rig.rd(0x26) & 0x03 == 0x01 and rig.rd(0x07) == 0
    rig.run_ms(6)
    assert rig.rd(0x07) == 0x0F and rig.rd(0x26) & 0x03 == 0x02
    assert rig.mag()[0] == 1044
    rig.run_ms(30)
    assert rig.rd(0x07) == 0


def test_boot_restores_reset_values(rig: Rig) -> None:
    rig.wr(0x20, 0xAF)
    rig.wr(0x25, 0x60)
    rig.wr(0x1F, 0x80)
    rig.run_ms(6)
    assert rig.rd(0x1F) == 0x00 and rig.rd(0x20) == 0x07 and rig.rd(0x25) == 0x20


def test_faults(rig: Rig) -> None:
    rig.env.accel_m_s2 = (G0_M_S2, 0.0, 0.0)
    rig.wr(0x21, 0x20)
    rig.wr(0x20, 0xA7)
    rig.chip.faults.wrong_id = 0x00
    assert rig.rd(0x0F) == 0x00
    rig.chip.faults.clear()
    rig.chip.faults.absent = True
    assert rig.burst(0x27, 7) == b"\xff" * 7
    rig.chip.faults.clear()
    rig.chip.faults.saturate = True
    rig.run_ms(1)
    assert rig.accel() == (32767, 32767, 32767)
    rig.chip.faults.clear()
    rig.chip.faults.bias_step = (G0_M_S2, 0.0, 0.0)
    rig.run_ms(1)
    assert rig.accel()[0] == 2732
    rig.chip.faults.clear()
    rig.chip.faults.frozen = True
    rig.run_ms(1)
    before = rig.accel()
    rig.env.accel_m_s2 = (0.0, G0_M_S2, 0.0)
    rig.run_ms(3)
    assert rig.accel() == before
    rig.chip.faults.clear()
    rig.chip.faults.random_data = True
    assert len({rig.burst(0x28, 6) for _ in range(5)}) == 5
    rig.chip.faults.clear()
    rig.chip.faults.drdy_stuck = True
    rig.wr(0x22, 0x04)
    rig.run_ms(3)
    assert rig.int1.level == 0
