"""MS4525DO model against its datasheet: transfer functions, read commands, status bits,
conversion timing, faults."""

from __future__ import annotations

import errno

import pytest

from board.i2c import I2cBus
from board.kernel import Kernel
from peripherals import ms4525do as m
from peripherals.errors import rng_for
from peripherals.ms4525do import (CONVERSION_NS, PSI_PA, STATUS_FAULT, STATUS_NORMAL,
                                  STATUS_STALE, Ms4525do)
from peripherals.physics import Environment

ADDR = 0x28
MS = 1_000_000


@pytest.fixture
def env() -> Environment:
    return Environment(diff_pressure_pa=200.0, temperature_c=21.0)


@pytest.fixture
def chip(kernel: Kernel, env: Environment, monkeypatch: pytest.MonkeyPatch) -> Ms4525do:
    monkeypatch.setattr(m, "PRESSURE_NOISE_PA", 0.0)      # exact counts for these tests
    monkeypatch.setattr(m, "TEMPERATURE_NOISE_C", 0.0)
    return Ms4525do(kernel, env, rng_for(5, "ms4525do"))


@pytest.fixture
def bus(kernel: Kernel, chip: Ms4525do) -> I2cBus:
    b = I2cBus(kernel, "i2c1", clock_hz=400_000)
    b.attach(ADDR, chip)
    return b


def fetch(bus: I2cBus, n: int = 4) -> tuple[int, int, int, bytes]:
    """(status, bridge count, temperature count, raw bytes) of a Read_DF<n>."""
    d = bus.readfrom(ADDR, n)
    t = (d[2] << 8 | d[3]) >> 5 if n >= 4 else -1
    return d[0] >> 6, (d[0] << 8 | d[1]) & 0x3FFF, t, d


def measure(kernel: Kernel, bus: I2cBus) -> None:
    bus.write_quick(ADDR)                     # Write_MR: address only
    kernel.run(kernel.now_ns + 1 * MS)


def test_transfer_functions_both_ways_at_the_datasheet_points():
    full = 16383
    assert m.counts_from_pressure_pa(-PSI_PA) == round(0.1 * full)     # Pmin: 10 %
    assert m.counts_from_pressure_pa(PSI_PA) == round(0.9 * full)      # Pmax: 90 %
    assert m.counts_from_pressure_pa(0.0) == round(0.5 * full)         # mid-scale
    assert m.counts_from_pressure_pa(-3 * PSI_PA) == 0                 # clipped below
    assert m.counts_from_pressure_pa(3 * PSI_PA) == full               # and above
    for c in (1638, 5000, 8192, 12000, 14745):
        assert m.counts_from_pressure_pa(m.pressure_pa_from_counts(c)) == c
    # one count is 2 psi / (0.8 * 16383) = 1.052 Pa
    step = m.pressure_pa_from_counts(8193) - m.pressure_pa_from_counts(8192)
    assert step == pytest.approx(2 * PSI_PA / (0.8 * full))
    assert m.temperature_c_from_counts(0) == -50.0
    assert m.temperature_c_from_counts(2047) == 150.0
    assert m.counts_from_temperature_c(25.0) == round(75 * 2047 / 200)
    assert m.counts_from_temperature_c(-80.0) == 0 and m.counts_from_temperature_c(200) == 2047


def test_a_measurement_reads_the_pitot_pressure_with_the_pixhawk_sign(kernel, bus, env):
    measure(kernel, bus)
    status, p, t, raw = fetch(bus)
    assert status == STATUS_NORMAL
    # the pitot's +200 Pa is -200 Pa at the datasheet's port 1 - port 2 (module doc)
    assert m.pressure_pa_from_counts(p) == pytest.approx(-200.0, abs=0.6)
    assert m.temperature_c_from_counts(t) == pytest.approx(21.0, abs=0.05)
    assert raw[3] & 0x1F == 0x1F                                       # undetermined bits
    env.diff_pressure_pa = -50.0
    measure(kernel, bus)
    assert m.pressure_pa_from_counts(fetch(bus)[1]) == pytest.approx(50.0, abs=0.6)


def test_read_df2_df3_df4_return_the_same_packet_prefix(kernel, bus):
    measure(kernel, bus)
    raw2 = bus.readfrom(ADDR, 2)
    raw3 = bus.readfrom(ADDR, 3)
    raw4 = bus.readfrom(ADDR, 4)
    assert raw2[0] >> 6 == STATUS_NORMAL
    assert raw3[0] >> 6 == raw4[0] >> 6 == STATUS_STALE      # fetched by the first read
    assert raw2[0] & 0x3F == raw3[0] & 0x3F == raw4[0] & 0x3F and raw2[1] == raw3[1] == raw4[1]
    assert raw3[2] == raw4[2]                                  # byte 3: T's 8 high bits
    assert bus.readfrom(ADDR, 6)[4:] == b"\xff\xff"           # beyond the packet


def test_status_is_normal_once_then_stale_until_the_next_conversion(kernel, bus):
    assert fetch(bus)[0] == STATUS_STALE                     # nothing measured yet: stale, 0
    assert fetch(bus)[1] == 0
    measure(kernel, bus)
    assert fetch(bus)[0] == STATUS_NORMAL
    assert fetch(bus)[0] == STATUS_STALE                     # already fetched
    measure(kernel, bus)
    assert fetch(bus)[0] == STATUS_NORMAL


def test_a_fetch_faster_than_the_conversion_reads_stale_data(kernel, bus, chip, env):
    measure(kernel, bus)
    fetch(bus)
    env.diff_pressure_pa = 400.0
    t0 = kernel.now_ns + kernel.busy_ns                       # when the request's START is
    bus.write_quick(ADDR)
    kernel.run(t0 + CONVERSION_NS - 100_000)                 # 0.4 ms: not done yet
    status, p, _, _ = fetch(bus)
    assert status == STATUS_STALE
    assert m.pressure_pa_from_counts(p) == pytest.approx(-200.0, abs=0.6)   # the old result
    kernel.run(t0 + CONVERSION_NS + 50_000)
    status, p, _, _ = fetch(bus)
    assert status == STATUS_NORMAL
    assert m.pressure_pa_from_counts(p) == pytest.approx(-400.0, abs=0.6)


def test_a_request_during_a_conversion_is_ignored_and_px4s_one_byte_write_is_a_request(
        kernel, bus, chip):
    bus.writeto(ADDR, b"\x00")                               # PX4's measure()
    bus.write_quick(ADDR)
    assert chip.requests_ignored == 1
    kernel.run(kernel.now_ns + 1 * MS)
    assert chip.conversions == 1 and fetch(bus)[0] == STATUS_NORMAL


def test_noise_comes_from_the_seeded_stream(kernel, env):
    def counts(seed: int) -> list[int]:
        k = Kernel()
        chip = Ms4525do(k, env, rng_for(seed, "ms4525do"))
        b = I2cBus(k, "i2c1")
        b.attach(ADDR, chip)
        out = []
        for _ in range(30):
            measure(k, b)
            out.append(fetch(b)[1])
        return out

    a, again, other = counts(1), counts(1), counts(2)
    assert a == again and a != other
    assert len(set(a)) > 1                                   # it is noisy
    assert max(abs(m.pressure_pa_from_counts(c) + 200.0) for c in a) < 6.0


def test_faults_absent_diag_stale_frozen_blocked_saturate(kernel, bus, chip, env):
    chip.faults.absent = True
    assert bus.transfer(ADDR, b"", 4)[0] == -errno.EIO
    chip.faults.absent = False
    chip.faults.diag_fault = True
    measure(kernel, bus)
    assert fetch(bus)[0] == STATUS_FAULT
    chip.faults.diag_fault = False
    chip.faults.stale = True
    measure(kernel, bus)
    assert fetch(bus)[0] == STATUS_STALE                     # the conversion never lands
    chip.faults.stale = False
    measure(kernel, bus)
    first = fetch(bus)
    chip.faults.frozen = True
    env.diff_pressure_pa = 300.0
    measure(kernel, bus)
    frozen = fetch(bus)
    assert frozen[0] == STATUS_NORMAL and frozen[1:3] == first[1:3]
    chip.faults.frozen = False
    chip.faults.port_blocked = "stuck"
    measure(kernel, bus)
    env.diff_pressure_pa = 50.0
    measure(kernel, bus)
    assert m.pressure_pa_from_counts(fetch(bus)[1]) == pytest.approx(-300.0, abs=0.6)
    chip.faults.port_blocked = "zero"
    measure(kernel, bus)
    assert m.pressure_pa_from_counts(fetch(bus)[1]) == pytest.approx(0.0, abs=0.6)
    chip.faults.port_blocked = ""
    chip.faults.saturate = True
    measure(kernel, bus)
    assert fetch(bus)[1] == 16383
    chip.faults.saturate = False
    chip.faults.bias_step = (10.0, 2.0, 0.0)
    measure(kernel, bus)
    _, p, t, _ = fetch(bus)
    assert m.pressure_pa_from_counts(p) == pytest.approx(-60.0, abs=0.6)
    assert m.temperature_c_from_counts(t) == pytest.approx(23.0, abs=0.1)
