"""STM32 timer: PWM waveform arithmetic, preload at the update event, UG, interrupts, capture."""

from __future__ import annotations

import pytest

from board.gpio import Gpio
from board.kernel import Kernel
from board.timer import Timer

MS = 1_000_000
US = 1_000

CCMR_PWM1_PRELOAD = 0x68  # OC1M = 110, OC1PE = 1 (channel 1 / 3 position)


@pytest.fixture
def kernel() -> Kernel:
    return Kernel("io")


def io_pwm(kernel: Kernel, ccr: int = 1500, arr: int = 19999) -> Timer:
    """The IO's TIM2 as PX4 arms it: 24 MHz, PSC 23 -> 1 us ticks, 50 Hz, CH1 PWM mode 1."""
    tim = Timer(kernel, "TIM2", 24_000_000)
    tim.write_reg("PSC", 23)
    tim.write_reg("ARR", arr)
    tim.write_reg("CCMR1", CCMR_PWM1_PRELOAD | CCMR_PWM1_PRELOAD << 8)
    tim.write_reg("CCR1", ccr)
    tim.write_reg("CCER", 0x0001)
    tim.write_reg("EGR", 1)  # UG: load the preloads, reset the counter
    tim.write_reg("CR1", 0x81)  # ARPE | CEN
    return tim


def test_pwm_period_and_pulse(kernel):
    tim = io_pwm(kernel)
    ch = tim.channel(1)
    assert (ch.pulse_ns, ch.period_ns) == (1_500 * US, 20 * MS)
    assert ch.level_at(0) == 1
    assert ch.level_at(1_500 * US - 1) == 1
    assert ch.level_at(1_500 * US) == 0
    assert ch.level_at(20 * MS - 1) == 0
    assert ch.level_at(20 * MS) == 1
    kernel.run(7 * MS + 400)
    assert tim.read_reg("CNT") == 7_000
    assert len(kernel) == 0  # nothing scheduled per period


def test_ccr_zero_and_above_arr(kernel):
    tim = io_pwm(kernel, ccr=0)
    assert tim.channel(1).pulse_ns == 0
    assert all(tim.channel(1).level_at(t) == 0 for t in (0, 1 * US, 19_999 * US))
    tim.write_reg("CCR1", 20_000)
    tim.write_reg("EGR", 1)
    assert tim.channel(1).pulse_ns == 20 * MS  # 100 %
    tim.write_reg("CCER", 0x0003)  # CC1P: active low
    assert tim.channel(1).pulse_ns == 0


def test_preloaded_ccr_takes_effect_exactly_at_next_uev(kernel):
    tim = io_pwm(kernel)
    seen = []
    tim.channel(1).on_pwm(lambda t, high, period: seen.append((t, high, period)))
    kernel.run(5 * MS)
    tim.write_reg("CCR1", 1_000)
    assert tim.channel(1).pulse_ns == 1_500 * US
    assert tim.channel(1).level_at(20 * MS + 1_200 * US) == 0  # prediction uses the new CCR
    kernel.run(20 * MS - 1)
    assert seen == []
    kernel.run(20 * MS)
    assert seen == [(20 * MS, 1_000 * US, 20 * MS)]
    assert tim.channel(1).pulse_ns == 1_000 * US
    kernel.run(100 * MS)
    assert len(seen) == 1 and len(kernel) == 0


def test_preloaded_psc_and_arr_change_period_at_next_uev(kernel):
    tim = io_pwm(kernel)
    seen = []
    tim.channel(1).on_pwm(lambda *a: seen.append(a))
    kernel.run(3 * MS)
    tim.write_reg("ARR", 2_499)  # 400 Hz, ARPE set: waits for the UEV
    tim.write_reg("PSC", 11)  # 2 MHz ticks
    kernel.run(20 * MS)
    assert seen == [(20 * MS, 750 * US, 1_250 * US)]
    kernel.run(20 * MS + 1_000 * US)
    assert tim.read_reg("CNT") == 2_000
    kernel.run(21_250 * US)
    assert tim.read_reg("CNT") == 0


def test_ug_forces_preload_and_resets_counter(kernel):
    tim = io_pwm(kernel)
    seen = []
    tim.channel(1).on_pwm(lambda *a: seen.append(a))
    kernel.run(5 * MS)
    tim.write_reg("CCR1", 1_100)
    tim.write_reg("EGR", 1)
    assert seen == [(5 * MS, 1_100 * US, 20 * MS)]
    assert tim.read_reg("CNT") == 0
    assert tim.channel(1).level_at(5 * MS + 1_099 * US) == 1
    assert tim.channel(1).level_at(5 * MS + 1_100 * US) == 0
    kernel.run(5 * MS + 2_345 * US)
    assert tim.read_reg("CNT") == 2_345


def test_unbuffered_arr_and_ccr_act_immediately(kernel):
    tim = io_pwm(kernel)
    tim.write_reg("CR1", 0x01)  # CEN, no ARPE
    tim.write_reg("CCMR1", 0x60)  # PWM1, no OC1PE
    kernel.run(5 * MS)
    tim.write_reg("ARR", 9_999)
    tim.write_reg("CCR1", 500)
    assert (tim.channel(1).pulse_ns, tim.channel(1).period_ns) == (500 * US, 10 * MS)
    kernel.run(10 * MS)
    assert tim.read_reg("CNT") == 0


def test_update_interrupt_only_while_uie(kernel):
    tim = io_pwm(kernel)
    tim.write_reg("SR", 0)  # UG set UIF
    assert tim.read_reg("SR") == 0
    calls = []

    def isr(timer, t):
        calls.append((t, kernel.in_isr, timer.read_reg("SR") & 1))
        timer.write_reg("SR", ~1 & 0xFFFF)

    tim.attach_irq(isr)
    tim.write_reg("DIER", 1)
    kernel.run(60 * MS)
    assert calls == [(20 * MS, True, 1), (40 * MS, True, 1), (60 * MS, True, 1)]
    tim.write_reg("DIER", 0)
    assert len(kernel) == 0
    kernel.run(85 * MS)
    assert tim.read_reg("SR") & 1 == 1  # UIF still flags the UEVs at 80 ms lazily


def test_stop_freezes_counter_and_output(kernel):
    tim = io_pwm(kernel)
    seen = []
    tim.channel(1).on_pwm(lambda *a: seen.append(a))
    kernel.run(1 * MS)
    tim.write_reg("CR1", 0)  # disarm as PX4 does: the pin stays where it was
    assert seen == [(1 * MS, 20 * MS, 20 * MS)]
    kernel.run(50 * MS)
    assert tim.read_reg("CNT") == 1_000
    assert tim.channel(1).level_at(50 * MS) == 1


def test_compare_interrupt_on_output_channel(kernel):
    tim = io_pwm(kernel)
    hits = []
    tim.attach_irq(lambda timer, t: (hits.append((t, timer.read_reg("SR") & 0x2)),
                                     timer.write_reg("SR", 0)))
    tim.write_reg("DIER", 0x2)
    kernel.run(45 * MS)
    assert hits == [(1_500 * US, 2), (21_500 * US, 2), (41_500 * US, 2)]


def test_non_integer_tick_period_is_exact(kernel):
    tim = Timer(kernel, "TIM1", 168_000_000, advanced=True)
    tim.write_reg("ARR", 167)  # 168 ticks of 5.952 ns = exactly 1 us
    ups = []
    tim.attach_irq(lambda timer, t: (ups.append(t), timer.write_reg("SR", 0)))
    tim.write_reg("DIER", 1)
    tim.write_reg("CR1", 1)
    kernel.run(3_000_000 * US // 1000)
    assert ups[:3] == [1_000, 2_000, 3_000] and len(ups) == 3_000
    assert tim.counter_at(kernel.now_ns + 6) == 1  # first tick after 5.95 ns
    assert tim.counter_at(kernel.now_ns + 5) == 0


def test_advanced_timer_needs_moe(kernel):
    tim = Timer(kernel, "TIM1", 168_000_000, advanced=True)
    tim.write_reg("PSC", 167)
    tim.write_reg("ARR", 19_999)
    tim.write_reg("CCMR2", 0x6800)  # CH4 PWM1 preload
    tim.write_reg("CCR4", 1_200)
    tim.write_reg("CCER", 0x1000)
    tim.write_reg("EGR", 1)
    tim.write_reg("CR1", 0x81)
    assert tim.channel(4).pulse_ns == 0
    tim.write_reg("BDTR", 0x8000)
    assert (tim.channel(4).pulse_ns, tim.channel(4).period_ns) == (1_200 * US, 20 * MS)


def ppm_capture(kernel: Kernel) -> tuple[Timer, object]:
    """The IO's PPM input: TIM1 free-running at 1 MHz, CH1 capture from PA8, both edges."""
    gpio = Gpio(kernel)
    pin = gpio.pin("PA8")
    tim = Timer(kernel, "TIM1", 24_000_000)
    tim.write_reg("PSC", 23)
    tim.write_reg("ARR", 0xFFFF)
    tim.write_reg("CCMR1", 0x01)  # CC1S = 01: input, TI1
    tim.write_reg("CCER", 0x000B)  # CC1E | CC1P | CC1NP: both edges
    tim.channel(1).bind_input(pin)
    tim.write_reg("EGR", 1)
    tim.write_reg("CR1", 1)
    return tim, pin


def test_input_capture_at_known_edges_with_wrap(kernel):
    tim, pin = ppm_capture(kernel)
    got = []

    def isr(timer, t):
        got.append((t, timer.read_reg("CCR1"), timer.read_reg("SR") & 0x202))

    tim.attach_irq(isr)
    tim.write_reg("DIER", 0x2)
    edges = [(1_000 * US, 1), (1_400 * US, 0), (2_500 * US, 1), (65_300 * US, 0),
             (66_100 * US + 999, 1)]
    for t, level in edges:
        pin.set(level, t_ns=t)
    kernel.run(100 * MS)
    assert got == [
        (1_000 * US, 1_000, 0),
        (1_400 * US, 1_400, 0),
        (2_500 * US, 2_500, 0),
        (65_300 * US, 65_300, 0),
        (66_100 * US + 999, 66_100 - 65_536, 0),  # wrapped; still 564 ticks at 999 ns in
    ]
    assert (got[-1][1] - got[-2][1]) % 65_536 == 800


def test_capture_polarity_rising_only_and_overcapture(kernel):
    tim, pin = ppm_capture(kernel)
    tim.write_reg("CCER", 0x0001)  # rising only
    pin.set(1, t_ns=100 * US)
    pin.set(0, t_ns=200 * US)
    pin.set(1, t_ns=300 * US)
    kernel.run(250 * US)
    assert tim.read_reg("SR") & 0x202 == 0x002
    kernel.run(1 * MS)
    assert tim.read_reg("SR") & 0x202 == 0x202  # second capture before CCR1 was read
    assert tim.read_reg("CCR1") == 300
    assert tim.read_reg("SR") & 0x002 == 0  # reading CCR1 cleared CC1IF
    tim.write_reg("SR", ~0x200 & 0xFFFF)
    assert tim.read_reg("SR") & 0x200 == 0


def test_capture_disabled_without_cc1e_and_ic_prescaler(kernel):
    tim, pin = ppm_capture(kernel)
    tim.write_reg("CCER", 0x000A)  # polarity set, CC1E clear
    pin.set(1, t_ns=10 * US)
    kernel.run(20 * US)
    assert tim.read_reg("SR") & 0x2 == 0
    tim.write_reg("CCER", 0x0001)
    tim.write_reg("CCMR1", 0x01 | 0x04)  # IC1PSC = 01: every 2nd edge
    for k in range(1, 5):
        pin.set(0, t_ns=k * 100 * US - 50 * US)
        pin.set(1, t_ns=k * 100 * US)
    kernel.run(150 * US)
    assert tim.read_reg("SR") & 0x2 == 0
    kernel.run(250 * US)
    assert tim.read_reg("CCR1") == 200


def test_bad_register_access(kernel):
    tim = Timer(kernel, "TIM3", 24_000_000)
    with pytest.raises(ValueError, match="offset 0x48"):
        tim.write(0x48, 0)
    with pytest.raises(ValueError, match="no register named 'CCR5'"):
        tim.read_reg("CCR5")
    with pytest.raises(ValueError, match="channel must be 1..4"):
        tim.channel(0)
    assert tim.read_reg("ARR") == 0xFFFF and tim.read_reg("EGR") == 0
