"""MS5611 model: datasheet vectors, CRC-4, commands on the wire, conversion timing, inversion."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from board.kernel import Kernel
from board.spi import SpiBus
from peripherals.errors import rng_for
from peripherals.ms5611 import (
    CONVERSION_TIME_MS,
    DEFAULT_PROM,
    Ms5611,
    compensate,
    crc4,
    prom_with_crc,
    raw_from_physical,
)
from peripherals.physics import Environment

VECTORS = Path(__file__).resolve().parents[3] / "shared" / "fixtures" / "ms5611" / \
    "ms5611_vectors.json"


@pytest.fixture(scope="module")
def vectors() -> dict:
    if not VECTORS.exists():
        raise AssertionError(f"fixture file {VECTORS} not present")
    return json.loads(VECTORS.read_text())


@pytest.fixture
def env() -> Environment:
    return Environment(pressure_pa=100_000.0, board_temperature_c=25.0)


@pytest.fixture
def chip(kernel: Kernel, env: Environment) -> Ms5611:
    return Ms5611(kernel, env, rng_for(7, "ms5611"))


@pytest.fixture
def dev(kernel: Kernel, chip: Ms5611):
    bus = SpiBus(kernel, "spi1")
    bus.attach("PD7", chip)
    return bus.device("PD7", mode=3, clock_hz=10_500_000)


def adc(dev) -> int:
    return int.from_bytes(dev.transfer(b"\x00\x00\x00\x00")[1:], "big")


def prom(dev) -> list[int]:
    out = []
    for i in range(8):
        rx = dev.transfer(bytes((0xA0 + 2 * i, 0, 0)))
        out.append(rx[1] << 8 | rx[2])
    return out


# -- arithmetic against the fixtures ----------------------------------------------------------

def test_default_prom_is_the_fixture_prom(vectors):
    assert list(DEFAULT_PROM) == vectors["ms5611"]["prom_words"]


def test_compensation_matches_every_fixture_vector(vectors):
    c = vectors["ms5611"]["prom_words"]
    for v in vectors["ms5611"]["vectors"]:
        temp, p, off, sens = compensate(c, v["D1"], v["D2"])
        assert (temp, p) == (v["expected_TEMP_centi_degC"], v["expected_P_centi_mbar_equals_Pa"]), \
            v["name"]
        assert (off, sens) == (v["intermediates_recomputed"]["OFF"],
                               v["intermediates_recomputed"]["SENS"]), v["name"]


def test_datasheet_example_by_hand():
    assert compensate(DEFAULT_PROM, 9085466, 8569150)[:2] == (2007, 100009)


def test_crc4_fixture_vectors(vectors):
    for v in vectors["crc4"]:
        words = v["prom_words"]
        assert crc4(words) == v["computed_crc4"], v["name"]
        assert (crc4(words) == words[7] & 0xF) == v["crc_matches_word7_low_nibble"], v["name"]


def test_prom_with_crc_makes_a_valid_prom():
    words = prom_with_crc([0, 1, 2, 3, 4, 5, 6, 0x4B30])
    assert crc4(words) == words[7] & 0xF


@pytest.mark.parametrize("pressure, temp_c", [(101_325.0, 25.0), (100_000.0, 20.0),
                                              (96_000.0, 10.0), (90_000.0, -20.0),
                                              (70_000.0, -35.5), (110_000.0, 60.25)])
def test_inversion_recovers_pressure_and_temperature(pressure, temp_c):
    d1, d2 = raw_from_physical(DEFAULT_PROM, pressure, temp_c)
    temp, p, _, _ = compensate(DEFAULT_PROM, d1, d2)
    assert abs(temp - temp_c * 100) <= 1
    assert p == round(pressure)


# -- the wire ---------------------------------------------------------------------------------

def test_prom_read_over_spi(dev):
    assert prom(dev) == list(DEFAULT_PROM)


def test_reset_makes_the_chip_busy_for_2_8_ms(kernel, dev):
    dev.transfer(b"\x1e")
    assert prom(dev) == [0] * 8          # PROM not reloaded yet
    dev.transfer(b"\x48")                # ignored while resetting
    kernel.run(3_000_000)
    assert adc(dev) == 0                 # that conversion never started
    assert prom(dev) == list(DEFAULT_PROM)


@pytest.mark.parametrize("osr_bits, osr", list(enumerate((256, 512, 1024, 2048, 4096))))
def test_conversion_time_per_osr(kernel, chip, dev, osr_bits, osr):
    lo, _, hi = CONVERSION_TIME_MS[osr]
    assert lo * 1e6 <= chip.conversion_time_ns(osr) <= hi * 1e6
    dev.transfer(bytes((0x40 | osr_bits << 1,)))
    kernel.run(int(lo * 1e6 * 0.95))
    assert adc(dev) == 0                 # too early: 0, and the result will be wrong
    kernel.run(kernel.now_ns + int(hi * 1e6) + 1000)
    assert chip.corrupted_conversions == 1
    dev.transfer(bytes((0x50 | osr_bits << 1,)))
    kernel.run(kernel.now_ns + int(hi * 1e6) + 1000)
    value = adc(dev)
    assert 0 < value < 1 << 24
    assert adc(dev) == 0                 # one result, one read


def test_convert_during_conversion_is_ignored_and_spoils_it(kernel, chip, dev):
    dev.transfer(b"\x48")
    kernel.run(1_000_000)
    dev.transfer(b"\x58")
    kernel.run(20_000_000)
    assert chip.corrupted_conversions == 1
    assert chip.ignored_commands == 1


def test_d1_d2_from_environment_decode_to_truth(kernel, env, dev):
    env.pressure_pa = 95_432.0
    env.board_temperature_c = 12.5
    dev.transfer(b"\x58")
    kernel.run(kernel.now_ns + 10_000_000)
    d2 = adc(dev)
    dev.transfer(b"\x48")
    kernel.run(kernel.now_ns + 10_000_000)
    d1 = adc(dev)
    temp, p, _, _ = compensate(DEFAULT_PROM, d1, d2)
    assert abs(temp - 1250) <= 2
    assert abs(p - 95_432) <= 6          # 0.012 mbar noise at OSR 4096, plus T noise


def test_unknown_command_ignored(chip, dev):
    assert dev.transfer(b"\x13\x00\x00") == b"\x00\x00\x00"
    assert chip.ignored_commands == 1


def test_faults_absent_wrong_id_saturate_frozen(kernel, chip, dev):
    chip.faults.absent = True
    assert dev.transfer(b"\xa2\x00\x00") == b"\xff\xff\xff"
    chip.faults.clear()
    chip.faults.wrong_id = 0x1234
    words = prom(dev)
    assert words[7] == 0x1234 and crc4(words) != words[7] & 0xF
    chip.faults.clear()
    chip.faults.saturate = True
    dev.transfer(b"\x48")
    kernel.run(kernel.now_ns + 10_000_000)
    assert adc(dev) == 0xFFFFFF
    chip.faults.clear()
    chip.faults.frozen = True
    values = set()
    for _ in range(3):
        dev.transfer(b"\x48")
        kernel.run(kernel.now_ns + 10_000_000)
        values.add(adc(dev))
    assert len(values) == 1


def test_bad_prom_argument_raises(kernel, env):
    with pytest.raises(ValueError, match="eight 16-bit words"):
        Ms5611(kernel, env, rng_for(1, "x"), prom=[1, 2, 3])
