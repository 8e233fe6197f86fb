"""The FMU's own PWM outputs: the timers behind AUX1..AUX6 and their ports.

A mixin of :class:`fmu.board.FmuV2Board`. The board's spec lists the FMU-side outputs
(``BoardSpecData.pwm``: on a Pixhawk 1 AUX1-4 on TIM1 CH4..CH1, AUX5-6 on TIM4 CH2..CH3); each
timer a listed output uses is built (TIM1 as an advanced timer, whose outputs need BDTR.MOE)
and each output with a port name is exposed as a ``pwm`` port (``aux1``..``aux6``), which the
wiring may connect to a servo or an ESC of the world. Timers are inert until firmware
programs them (the ``fmu`` driver), so a board whose outputs stay unused schedules nothing.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from board.timer import Timer

__all__ = ["FmuPwmSide"]

#: STM32F4 timers with a break and dead-time register (outputs gated by BDTR.MOE)
ADVANCED_TIMERS = ("TIM1", "TIM8")


class FmuPwmSide:
    """Builds ``self.timers`` and the ``aux`` ports from ``self.spec``."""

    kernel: Any
    name: str
    spec: Any
    timers: dict[str, Timer]
    expose_pwm: Callable[[str, Any], None]  # Board's (an annotation only: no attribute here)

    def _build_pwm_outputs(self) -> None:
        used = {o.timer for o in self.spec.pwm}
        self.timers = {t: Timer(self.kernel, f"{self.name}.{t}", hz,
                                advanced=t in ADVANCED_TIMERS)
                       for t, hz in self.spec.timers_hz.items() if t in used}
        for out in self.spec.pwm:
            if out.port:
                self.expose_pwm(out.port, self.timers[out.timer].channel(out.channel))

    def ctl_aux_pwm(self) -> list[tuple[int, int]]:
        """(high_ns, period_ns) of the FMU's PWM outputs in spec order, as the pins show now."""
        channels = [self.timers[o.timer].channel(o.channel) for o in self.spec.pwm]
        return [(ch.pulse_ns, ch.period_ns) for ch in channels]
