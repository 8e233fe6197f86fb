"""HMC5883L model: reset values, ID, pointer rules, gains, modes, self-test, overflow, faults."""

from __future__ import annotations

import errno

import pytest

from board.gpio import Gpio
from board.i2c import I2cBus
from board.kernel import Kernel
from peripherals.errors import rng_for
from peripherals.hmc5883 import GAIN_LSB_PER_GA, OVERFLOW, SELF_TEST_GA, Hmc5883
from peripherals.physics import Environment

ADDR = 0x1E
MS = 1_000_000


@pytest.fixture
def env() -> Environment:
    return Environment(mag_gauss=(0.25, -0.1, 0.4))


@pytest.fixture
def chip(kernel: Kernel, env: Environment) -> Hmc5883:
    c = Hmc5883(kernel, env, rng_for(3, "hmc5883"))
    c.errors.p = type(c.errors.p)(noise_density=0.0)   # exact counts for these tests
    return c


@pytest.fixture
def bus(kernel: Kernel, chip: Hmc5883) -> I2cBus:
    b = I2cBus(kernel, "i2c1", clock_hz=400_000)
    b.attach(ADDR, chip)
    return b


def xzy(bus: I2cBus) -> tuple[int, int, int]:
    d = bus.readfrom_mem(ADDR, 0x03, 6)
    return tuple(int.from_bytes(d[i:i + 2], "big", signed=True) for i in (0, 2, 4))


def single(kernel: Kernel, bus: I2cBus) -> tuple[int, int, int]:
    bus.write_byte_data(ADDR, 0x02, 0x01)
    kernel.run(kernel.now_ns + 7 * MS)
    return xzy(bus)


def test_reset_values_and_id(bus):
    assert bus.read_byte_data(ADDR, 0x09) == 0x00
    assert list(bus.readfrom_mem(ADDR, 0x00, 3)) == [0x10, 0x20, 0x01]
    assert bus.readfrom_mem(ADDR, 0x0A, 3) == b"H43"
    assert bus.read_byte_data(ADDR, 0x09) == 0x02   # reading MR locks the data registers


def test_invalid_address_reads_zero_and_ignores_writes(bus):
    bus.write_byte_data(ADDR, 0x20, 0x55)
    assert bus.read_byte_data(ADDR, 0x20) == 0


def test_pointer_wraps_08_to_03_and_0c_to_00(bus):
    data = bus.readfrom_mem(ADDR, 0x03, 12)
    assert data[:6] == data[6:]          # the data block again, never the status register
    assert bus.readfrom_mem(ADDR, 0x0A, 5) == b"H43\x10\x20"   # 0x0C -> 0x00


def test_write_auto_increments(bus):
    bus.writeto_mem(ADDR, 0x00, bytes((0x70, 0xA0)))
    assert list(bus.readfrom_mem(ADDR, 0x00, 2)) == [0x70, 0xA0]


def test_reserved_bits_kept(bus):
    bus.write_byte_data(ADDR, 0x01, 0x3F)
    assert bus.read_byte_data(ADDR, 0x01) == 0x20


def test_x_z_y_order_and_gain(kernel, bus, env):
    single(kernel, bus)                  # latch the default gain pipeline
    x, z, y = single(kernel, bus)
    assert (x, z, y) == (round(0.25 * 1090), round(0.4 * 1090), round(-0.1 * 1090))


@pytest.mark.parametrize("gn", range(8))
def test_gain_table_takes_effect_after_next_measurement(kernel, bus, env, gn):
    env.mag_gauss = (0.5, 0.0, 0.0)
    bus.write_byte_data(ADDR, 0x01, gn << 5)
    first = single(kernel, bus)[0]
    second = single(kernel, bus)[0]
    assert first == round(0.5 * 1090)
    expected = round(0.5 * GAIN_LSB_PER_GA[gn])
    assert second == (expected if expected <= 2047 else OVERFLOW)


def test_single_measurement_returns_to_idle_and_sets_rdy(kernel, bus):
    bus.write_byte_data(ADDR, 0x02, 0x01)
    kernel.run(kernel.now_ns + 5 * MS)
    assert bus.read_byte_data(ADDR, 0x09) & 1 == 0   # not done at 5 ms
    kernel.run(kernel.now_ns + 2 * MS)
    assert bus.read_byte_data(ADDR, 0x09) & 1 == 1
    assert bus.read_byte_data(ADDR, 0x02) & 0x03 in (0x02, 0x03)   # idle
    xzy(bus)
    assert bus.read_byte_data(ADDR, 0x09) & 1 == 0   # all six read: data consumed


def test_continuous_mode_rate(kernel, chip, bus):
    bus.write_byte_data(ADDR, 0x00, 0x18)            # 75 Hz
    bus.write_byte_data(ADDR, 0x02, 0x00)
    n0 = chip.measurements
    kernel.run(kernel.now_ns + 1001 * MS)
    # first result after 2/f, then every 1/f: 74 in the first second (+ the write time)
    assert chip.measurements - n0 == 74
    assert bus.read_byte_data(ADDR, 0x02) == 0x00    # stays continuous


def test_lock_drops_new_data_until_all_six_read(kernel, chip, bus):
    single(kernel, bus)
    bus.readfrom_mem(ADDR, 0x03, 2)                  # partial read: locked
    assert bus.read_byte_data(ADDR, 0x09) & 0x02
    bus.write_byte_data(ADDR, 0x02, 0x01)            # a mode write releases the lock
    assert not bus.read_byte_data(ADDR, 0x09) & 0x02
    bus.readfrom_mem(ADDR, 0x03, 2)
    kernel.run(kernel.now_ns + 7 * MS)
    assert chip.dropped_locked == 1


def test_self_test_fields(kernel, bus, env):
    env.mag_gauss = (0.1, 0.2, 0.3)
    bus.write_byte_data(ADDR, 0x01, 0x60)            # 660 LSB/Ga
    bus.write_byte_data(ADDR, 0x00, 0x11)            # positive bias
    single(kernel, bus)
    pos = single(kernel, bus)
    bus.write_byte_data(ADDR, 0x00, 0x12)            # negative bias
    neg = single(kernel, bus)
    g = 660
    assert pos == (round((0.1 + SELF_TEST_GA[0]) * g), round((0.3 + SELF_TEST_GA[2]) * g),
                   round((0.2 + SELF_TEST_GA[1]) * g))
    assert neg == (round((0.1 - SELF_TEST_GA[0]) * g), round((0.3 - SELF_TEST_GA[2]) * g),
                   round((0.2 - SELF_TEST_GA[1]) * g))


def test_overflow_reads_minus_4096(kernel, bus, env):
    env.mag_gauss = (3.0, 0.1, -3.0)
    x, z, y = single(kernel, bus)
    assert x == OVERFLOW and z == OVERFLOW and y == round(0.1 * 1090)


def test_drdy_pulses_low_for_250_us(kernel, env):
    gpio = Gpio(kernel)
    pin = gpio.pin("PB1")
    chip = Hmc5883(kernel, env, rng_for(1, "h"), drdy_pin=pin)
    levels = []
    pin.on_change(lambda p, t, level: levels.append((t, level)))
    kernel.run(10 * MS)                               # the power-on single measurement
    assert levels == [(5_750_000, 0), (6_000_000, 1)]
    chip.faults.drdy_stuck = True
    chip.regs.write(0x02, 0x01)                       # another single measurement
    kernel.run(20 * MS)
    assert len(levels) == 2 and chip.measurements == 2


def test_absent_naks_and_wrong_id(bus, chip):
    chip.faults.absent = True
    with pytest.raises(OSError) as exc:
        bus.read_byte_data(ADDR, 0x0A)
    assert exc.value.errno == errno.EIO
    assert bus.transfer(ADDR, b"\x0a", 3)[0] == -errno.EIO
    chip.faults.clear()
    chip.faults.wrong_id = 0x414243
    assert bus.readfrom_mem(ADDR, 0x0A, 3) == b"ABC"


def test_frozen_and_saturate(kernel, bus, chip, env):
    first = single(kernel, bus)
    chip.faults.frozen = True
    env.mag_gauss = (0.0, 0.0, 0.0)
    assert single(kernel, bus) == first
    chip.faults.clear()
    chip.faults.saturate = True
    assert single(kernel, bus) == (OVERFLOW,) * 3
