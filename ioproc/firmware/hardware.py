"""What the IO firmware can touch: the STM32F100's peripherals as the IOv2 board wires them.

The firmware reaches hardware only through these objects (timer registers, UART buffers and
interrupts, pin levels, ADC conversions), never through the board's ports or another
firmware's state. Keeping it a plain record lets a test build a firmware on hand-made
peripherals and lets :class:`ioproc.board.IoV2Board` rebuild the firmware on a reset without
rebuilding the chip.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from board.adc import Adc
from board.gpio import Gpio, Pin
from board.kernel import Kernel
from board.timer import Timer
from board.uart import Uart

__all__ = ["PWM_CHANNELS", "TIMER_CLOCK_HZ", "IoHardware"]

#: All IOv2 timers run from the 24 MHz PCLK (APB prescaler 1, io-and-rc.md §3.1, §8.1).
TIMER_CLOCK_HZ: Final = 24_000_000

#: Output i (0-based) -> (rate group = index into IoHardware.pwm_timers, timer channel),
#: io-and-rc.md §8.1: group 0 TIM2 (outputs 1-2), group 1 TIM3 (5-8), group 2 TIM4 (3-4).
PWM_CHANNELS: Final[tuple[tuple[int, int], ...]] = (
    (0, 1), (0, 2), (2, 3), (2, 4), (1, 1), (1, 2), (1, 3), (1, 4))


@dataclass
class IoHardware:
    """The IO chip's peripherals, named as the firmware uses them."""

    kernel: Kernel
    gpio: Gpio
    usart1: Uart  # Spektrum/DSM RX (PA10), console TX (PA9)
    usart2: Uart  # FMU link, 1.5 Mbit/s
    usart3: Uart  # S.BUS RX (PB11, inverted line) / S.BUS TX (PB10)
    tim1: Timer  # HRT at 1 MHz, CH1 captures PPM on PA8
    pwm_timers: tuple[Timer, Timer, Timer]  # TIM2, TIM3, TIM4 = rate groups 0, 1, 2
    adc: Adc

    def pin(self, name: str) -> Pin:
        return self.gpio.pin(name)
