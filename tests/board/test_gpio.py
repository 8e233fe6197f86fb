"""GPIO pins and EXTI: edges, interrupt context, edge selection, line sharing."""

from __future__ import annotations

import pytest

from board.gpio import Gpio
from board.kernel import Kernel


@pytest.fixture
def kernel() -> Kernel:
    return Kernel("fmu")


@pytest.fixture
def gpio(kernel: Kernel) -> Gpio:
    return Gpio(kernel)


def test_handler_runs_at_edge_time_in_isr_context(kernel, gpio):
    seen = []
    drdy = gpio.pin("PD15")
    gpio.attach_interrupt(drdy, lambda pin, t: seen.append((pin.name, t, kernel.now_ns,
                                                             kernel.in_isr)))
    drdy.set(1, t_ns=125_000)  # a device model places its data-ready edge in the future
    kernel.run(124_999)
    assert seen == [] and drdy.level == 0
    kernel.run(200_000)
    assert seen == [("PD15", 125_000, 125_000, True)]
    assert drdy.level == 1 and kernel.in_isr is False


def test_same_level_again_is_not_an_edge(kernel, gpio):
    seen = []
    pin = gpio.pin("PB0")
    pin.attach_interrupt(lambda p, t: seen.append(t), rising=True, falling=True)
    changes = []
    pin.on_change(lambda p, t, level: changes.append((t, level)))
    pin.set(0)
    pin.set(1)
    pin.set(1)
    kernel.run(10)
    assert seen == [0] and changes == [(0, 1)]


def test_rising_falling_selection(kernel, gpio):
    rise, fall = [], []
    a, b = gpio.pin("PA1"), gpio.pin("PA2")
    a.attach_interrupt(lambda p, t: rise.append(t), rising=True)
    b.attach_interrupt(lambda p, t: fall.append(t), rising=False, falling=True)
    for t, level in ((100, 1), (200, 0), (300, 1), (400, 0)):
        a.set(level, t_ns=t)
        b.set(level, t_ns=t)
    kernel.run(1_000)
    assert rise == [100, 300]
    assert fall == [200, 400]
    with pytest.raises(ValueError, match="rising and/or falling"):
        a.attach_interrupt(lambda p, t: None, rising=False, falling=False)


def test_exti_line_shared_across_ports_last_attach_wins(kernel, gpio):
    seen = []
    pa0, pb0 = gpio.pin("PA0"), gpio.pin("PB0")
    gpio.attach_interrupt(pa0, lambda p, t: seen.append(p.name))
    gpio.attach_interrupt(pb0, lambda p, t: seen.append(p.name))
    assert gpio.exti_rerouted == 1 and gpio.exti[0].pin is pb0
    pa0.set(1, t_ns=10)
    pb0.set(1, t_ns=20)
    kernel.run(100)
    assert seen == ["PB0"]


def test_edge_during_pending_is_coalesced_like_exti_pr(kernel, gpio):
    seen = []
    pin = gpio.pin("PC3")
    pin.attach_interrupt(lambda p, t: seen.append(t))

    def burst():
        pin.set(1)
        pin.set(0)
        pin.set(1)

    kernel.call_at(50, burst)
    kernel.run(100)
    assert seen == [50] and gpio.exti[3].coalesced == 1


def test_edge_time_includes_bus_busy_time(kernel, gpio):
    seen = []
    pin = gpio.pin("PE4")
    pin.attach_interrupt(lambda p, t: seen.append((t, kernel.now_ns)))

    def driver():
        kernel.busy_ns += 7_000  # e.g. an SPI transfer just ran
        pin.set(1)

    kernel.call_at(1_000, driver)
    kernel.run(10_000)
    assert seen == [(8_000, 8_000)]


def test_pull_levels_and_release(kernel, gpio):
    up = gpio.pin("PA8", pull="up")
    down = gpio.pin("PA9", pull="down")
    assert (up.level, down.level) == (1, 0)
    up.set(0)
    assert up.level == 0 and up.driven
    up.release()
    assert up.level == 1 and not up.driven


def test_detach_and_bad_arguments(kernel, gpio):
    seen = []
    pin = gpio.pin("PD10")
    pin.attach_interrupt(lambda p, t: seen.append(t))
    pin.detach_interrupt()
    pin.set(1)
    kernel.run(10)
    assert seen == []
    with pytest.raises(ValueError, match="not a pin name"):
        gpio.pin("PZ3")
    with pytest.raises(ValueError, match="not a pin name"):
        gpio.pin("PA16")
    with pytest.raises(ValueError, match="level must be 0 or 1"):
        pin.set(2)
    with pytest.raises(ValueError, match="no interrupt attached"):
        gpio.detach("PD11")
    kernel.run(100)
    with pytest.raises(ValueError, match="in the past"):
        pin.set(0, t_ns=50)


def test_pulse_return_is_lazy_unless_observed(kernel, gpio):
    """A pulse whose return edge nobody can see costs no event; the level is still right,
    and attaching an observer mid-pulse turns the return back into a real edge."""
    fall = []
    pin = gpio.pin("PD15")
    pin.attach_interrupt(lambda p, t: fall.append((t, kernel.in_isr)), rising=False, falling=True)
    pin.high()
    kernel.call_at(1_000, lambda: pin.pulse(0, 1, 1_050, sync=True))
    kernel.run(1_000)
    assert fall == [(1_000, True)] and pin.level == 0
    assert len(kernel) == 0                  # no pulse-end event
    kernel.run(1_049)
    assert pin.level == 0
    kernel.run(1_050)
    assert pin.level == 1 and pin.driven
    changes = []
    kernel.call_at(2_000, lambda: pin.pulse(0, 1, 2_050, sync=True))
    kernel.run(2_010)
    pin.on_change(lambda p, t, level: changes.append((t, level)))
    kernel.run(3_000)
    assert changes == [(2_050, 1)] and fall[-1] == (2_000, True)
