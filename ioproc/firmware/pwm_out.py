"""The IO's PWM servo driver at register level (E14 ``up_pwm_servo_*`` behaviour, §8.2).

Why register level: the pulse the ESC sees must come out of the timer exactly as the STM32
makes it, including E14's off-by-one quirks (ARR = 1e6/rate, so the period is one tick too
long, 20 001 µs at 50 Hz; CCR = pulse - 1 with PWM mode 1 high while CNT < CCR, so the pin is
high one tick less than the SERVOS value: 1500 -> 1499 µs; quirk 12), the preload behaviour (a new CCR shows at the next update
event) and the stop-where-you-are disarm (CR1 = 0 may leave a pin high: a runt pulse PX4
accepts).

One register write per *change*: the firmware writes every CCR on every main-loop pass; writing
the value a register already holds is unobservable on the STM32, so the driver keeps a shadow
and skips identical writes. That keeps an idle armed IO cheap without changing any waveform.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

from board.timer import Timer
from ioproc.firmware.hardware import PWM_CHANNELS, TIMER_CLOCK_HZ

__all__ = ["CHANNEL_DEFAULT_CCR", "DEFAULT_RATE_HZ", "PwmServo"]

CR1_CEN: Final = 0x0001
CR1_ARPE: Final = 0x0080
EGR_UG: Final = 0x0001
OCM_PWM1: Final = 6
BDTR_MOE: Final = 0x8000
#: CCR preset at channel init (io-and-rc.md §3.2: "CCR preset to 1000").
CHANNEL_DEFAULT_CCR: Final = 1000
DEFAULT_RATE_HZ: Final = 50
#: PWM_RATE_LOWER_LIMIT / UPPER_LIMIT of the timer layer (§3.9).
RATE_MIN_HZ: Final = 1
RATE_MAX_HZ: Final = 10_000


def _ccmr(channel: int) -> tuple[str, int]:
    """CCMR register and the channel's OCxM | OCxPE bits (PWM mode 1 with CCR preload)."""
    shift = 0 if channel in (1, 3) else 8
    return ("CCMR1" if channel <= 2 else "CCMR2"), ((OCM_PWM1 << 4) | 0x08) << shift


class PwmServo:
    """Outputs on timer channels (the IO: eight on three timers); ``set`` takes µs, 0 = no
    pulse. The same layer drives the FMU's AUX outputs (PX4's drv_pwm_servo serves both
    processors): each timer counts at 1 MHz from its own clock, and an advanced timer
    (TIM1/TIM8) gets BDTR.MOE, without which its outputs stay off."""

    def __init__(self, timers: Sequence[Timer], channels: Sequence[tuple[int, int]] = PWM_CHANNELS,
                 clock_hz: int | Sequence[int] = TIMER_CLOCK_HZ,
                 advanced: Sequence[bool] = ()) -> None:
        """``clock_hz``: the timers' input clock (one for all, or one per timer), as the
        firmware's board configuration knows it; ``advanced``: which timers are TIM1/TIM8."""
        self.timers = tuple(timers)
        self.channels = tuple(channels)
        n = len(self.timers)
        self.clocks_hz = ((clock_hz,) * n if isinstance(clock_hz, int) else tuple(clock_hz))
        self.advanced = tuple(advanced) or (False,) * n
        if len(self.clocks_hz) != n or len(self.advanced) != n:
            raise ValueError("one clock and one advanced flag per timer")
        self.armed = False
        self.rates_hz = [DEFAULT_RATE_HZ] * len(self.timers)
        self._ccr = [-1] * len(self.channels)  # last CCR written; -1 = unknown

    def init(self) -> None:
        """up_pwm_servo_init: every timer stopped at 1 MHz / 50 Hz, every channel PWM mode 1."""
        for group, tim in enumerate(self.timers):
            for reg in ("CR1", "CR2", "SMCR", "DIER", "CCER", "CCMR1", "CCMR2"):
                tim.write_reg(reg, 0)
            tim.write_reg("PSC", self.clocks_hz[group] // 1_000_000 - 1)
            if self.advanced[group]:
                tim.write_reg("BDTR", BDTR_MOE)
            self.set_rate(group, DEFAULT_RATE_HZ)
        for i, (group, ch) in enumerate(self.channels):
            tim = self.timers[group]
            reg, bits = _ccmr(ch)
            tim.write_reg(reg, tim.read_reg(reg) | bits)
            tim.write_reg(f"CCR{ch}", CHANNEL_DEFAULT_CCR)
            self._ccr[i] = CHANNEL_DEFAULT_CCR
            tim.write_reg("CCER", tim.read_reg("CCER") | (1 << (4 * (ch - 1))))
        self.armed = False

    def set_rate(self, group: int, rate_hz: int) -> bool:
        """up_pwm_servo_set_rate_group_update: ARR = 1e6 / rate, then UG (counter restarts)."""
        if not 0 <= group < len(self.timers) or not RATE_MIN_HZ <= rate_hz <= RATE_MAX_HZ:
            return False
        tim = self.timers[group]
        tim.write_reg("ARR", 1_000_000 // rate_hz)
        tim.write_reg("EGR", EGR_UG)
        self.rates_hz[group] = rate_hz
        return True

    def arm(self, armed: bool) -> None:
        """up_pwm_servo_arm: start (UG, then CEN|ARPE) or stop (CR1 = 0) every timer."""
        for tim in self.timers:
            if armed:
                tim.write_reg("EGR", EGR_UG)
                tim.write_reg("CR1", tim.read_reg("CR1") | CR1_CEN | CR1_ARPE)
            else:
                tim.write_reg("CR1", 0)
        self.armed = armed

    def set(self, output: int, pulse_us: int) -> None:
        """up_pwm_servo_set: CCR = pulse - 1 (E14), 0 stays 0 (pin constantly low)."""
        ccr = pulse_us - 1 if pulse_us > 0 else 0
        if self._ccr[output] == ccr:
            return
        self._ccr[output] = ccr
        group, ch = self.channels[output]
        self.timers[group].write_reg(f"CCR{ch}", ccr & 0xFFFF)

    def get(self, output: int) -> int:
        """up_pwm_servo_get: the programmed pulse (CCR + 1), 0 if none."""
        ccr = self._ccr[output]
        return ccr + 1 if ccr > 0 else 0
