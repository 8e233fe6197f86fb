"""battery_status: ADC counts through the FMUv2 power-module dividers, consumption, remaining,
warning levels."""

from __future__ import annotations

import pytest

from board.adc import Adc
from board.kernel import Kernel
from board.specs import FMU_V2
from firmware.modules.battery import BatteryStatusModule
from firmware.modules.battery.battery import FMUV2_A_PER_V, FMUV2_V_DIV
from firmware.modules.system_params import PARAMS as SYS_PARAMS
from firmware.platform import Platform
from firmware.platform.params import Params
from firmware.system import System


class Power:
    """What the world feeds the power module: battery volts and amps (settable)."""

    def __init__(self, volts: float, amps: float) -> None:
        self.volts, self.amps = volts, amps


def make(power: Power, **params: float) -> tuple[Kernel, BatteryStatusModule]:
    kernel = Kernel("fmu")
    platform = Platform(kernel)
    p = Params(platform, list(SYS_PARAMS) + list(BatteryStatusModule.PARAMS))
    for k, v in params.items():
        p.set(k, v)
    adc = Adc(kernel, "ADC1", bits=12, vref_v=3.3)
    adc.set_source(2, lambda t: power.volts / FMUV2_V_DIV)
    adc.set_source(3, lambda t: power.amps / FMUV2_A_PER_V)
    system = System(platform, p, board=FMU_V2)
    mod = BatteryStatusModule(system, adc=adc)
    mod.start()
    return kernel, mod


def run(kernel: Kernel, seconds: float) -> None:
    kernel.run(kernel.now_ns + int(seconds * 1e9))


def status(mod: BatteryStatusModule):
    return mod.platform.orb.node("battery_status").last


def test_counts_to_volts_and_amps_with_the_fmuv2_dividers() -> None:
    kernel, mod = make(Power(12.0, 10.0))
    run(kernel, 0.15)
    m = status(mod)
    lsb_v, lsb_a = 3.3 / 4095 * FMUV2_V_DIV, 3.3 / 4095 * FMUV2_A_PER_V
    assert m.connected and m.cell_count == 3
    assert m.voltage_v == pytest.approx(12.0, abs=lsb_v) and m.current_a == pytest.approx(
        10.0, abs=lsb_a)
    counts = mod.adc.counts_for(12.0 / FMUV2_V_DIV)
    assert m.voltage_v == pytest.approx(counts * 3.3 / 4095 * FMUV2_V_DIV, rel=1e-6)


def test_the_divider_parameter_overrides_the_board() -> None:
    kernel, mod = make(Power(12.0, 0.0), BAT_V_DIV=5.0)
    run(kernel, 0.15)
    assert status(mod).voltage_v == pytest.approx(12.0 / FMUV2_V_DIV * 5.0, abs=0.01)


def test_discharged_mah_integrates_the_current() -> None:
    kernel, mod = make(Power(12.0, 10.0))
    run(kernel, 36.05)
    m = status(mod)   # 10 A for 36 s = 100 mAh (first sample only starts the clock)
    assert m.discharged_mah == pytest.approx(100.0, abs=0.5)
    assert m.current_filtered_a == pytest.approx(10.0, abs=0.02)


def test_remaining_is_voltage_based_with_load_compensation() -> None:
    power = Power(4.05 * 3, 0.0)
    kernel, mod = make(power)
    run(kernel, 0.15)
    assert status(mod).remaining == pytest.approx(1.0, abs=0.01)
    assert mod.soc_from_voltage(3.775 * 3, 0.0) == pytest.approx(0.5)
    # 20 A through 5 mOhm per cell = 0.1 V per cell of sag, compensated
    assert mod.soc_from_voltage((3.775 - 0.1) * 3, 20.0) == pytest.approx(0.5)


def test_warnings_rise_with_falling_voltage_and_never_fall() -> None:
    power = Power(3.8 * 3, 0.0)
    kernel, mod = make(power)
    run(kernel, 1.0)
    assert status(mod).warning == 0
    seen = []
    for cell in (3.57, 3.53, 3.515, 3.6):  # ~14 %, ~6 %, ~3 %, then recovers under no load
        power.volts = cell * 3
        run(kernel, 8.0)
        seen.append(status(mod).warning)
    assert seen == [1, 2, 3, 3]


def test_capacity_blends_coulomb_counting_with_voltage() -> None:
    power = Power(3.775 * 3, 0.0)
    kernel, mod = make(power, BAT_CAPACITY=1000.0)
    run(kernel, 0.5)
    assert status(mod).remaining == pytest.approx(0.5, abs=0.01)
    power.amps = 36.0           # 36 A for 10 s = 100 mAh = 10 % of the capacity
    power.volts = 3.775 * 3 - 36.0 * 0.005 * 3   # the sag the load compensation removes
    run(kernel, 10.0)
    assert status(mod).remaining == pytest.approx(0.4, abs=0.02)


def test_disconnected_battery() -> None:
    kernel, mod = make(Power(0.0, 0.0))
    run(kernel, 0.25)
    m = status(mod)
    assert not m.connected and m.remaining == 0.0 and m.warning == 0
