"""ADC: counts from volts, clipping, time-varying sources, conversion time."""

from __future__ import annotations

import pytest

from board.adc import Adc, conversion_time_ns
from board.kernel import Kernel


@pytest.fixture
def kernel() -> Kernel:
    return Kernel("fmu")


def test_counts_for_given_volts(kernel):
    adc = Adc(kernel, "adc1")
    adc.set_source(2, 1.65)
    assert adc.read(2) == 2048  # 1.65 / 3.3 * 4095 = 2047.5, rounded half up
    adc.set_source(2, 3.3)
    assert adc.read(2) == 4095
    adc.set_source(2, 0.0)
    assert adc.read(2) == 0
    adc.set_source(2, 1.0)
    assert adc.read(2) == 1241  # 1240.9
    assert adc.read(3) == 0  # open input


def test_clipping_at_both_rails(kernel):
    adc = Adc(kernel, "adc1")
    adc.set_source(0, 5.0)
    adc.set_source(1, -0.3)
    assert adc.read(0) == 4095
    assert adc.read(1) == 0
    assert adc.clipped == 2


def test_callable_source_sampled_at_context_time_and_conversion_time(kernel):
    adc = Adc(kernel, "adc1", bits=10, vref_v=5.0,
              conversion_ns=conversion_time_ns(15, 12, 21_000_000))
    assert adc.conversion_ns == 1_285
    times = []

    def battery_divider(t_ns: int) -> float:
        times.append(t_ns)
        return 2.5

    adc.set_source(4, battery_divider)
    kernel.run(10_000)
    assert adc.read(4) == 512  # 2.5 / 5 * 1023 = 511.5 -> 512
    assert adc.read(4) == 512
    assert times == [10_000, 11_285]
    assert kernel.busy_ns == 2_570
    assert adc.read_u16(4) == 512 * 0xFFFF // 1023


def test_bad_arguments(kernel):
    adc = Adc(kernel, "adc1", channels=4)
    with pytest.raises(ValueError, match="channel must be 0..3"):
        adc.read(4)
    with pytest.raises(ValueError, match="source must be volts"):
        adc.set_source(0, "3.3")
    adc.set_source(0, lambda t: float("nan"))
    with pytest.raises(ValueError, match="channel 0 gave nan"):
        adc.read(0)
    with pytest.raises(ValueError, match="bits"):
        Adc(kernel, "adc2", bits=0)
