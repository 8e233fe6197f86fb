"""PWM limit state machine (PX4 ``pwm_limit``): normalized mixer outputs -> pulse widths in µs.

Why it exists: on arming, ESCs must not jump from "no pulse"/disarmed to full control; the
IO holds disarmed values for INIT_TIME after boot, then ramps the lower bound from the disarmed
value to CONTROL_MIN over RAMP_TIME (io-and-rc.md §3.4).

    INIT --armed for >= INIT_TIME--> OFF --armed--> RAMP --RAMP_TIME--> ON
                                      ^--------not armed--------------/ (from RAMP or ON)

Exactly one transition is evaluated per call, then the outputs of the (new) state are
computed, as in the C code. Integer details kept on purpose: the C expression
``out * (max - min) / 2 + (max + min) / 2`` evaluates its first term in float (``*`` binds
first) and its second in integer division; the sum is truncated to uint16, then clamped. Time is passed
in (``now_us``); ``time_armed_us == 0`` doubles as "not set", like the C code.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum
from math import isnan
from typing import Final

from ioproc.protocol import ERA, Era


class LimitState(Enum):
    OFF = 0
    INIT = 1
    RAMP = 2
    ON = 3


@dataclass(frozen=True)
class LimitTiming:
    init_time_us: int
    ramp_time_us: int


#: INIT/RAMP durations per era (E14: 500 ms / 2.5 s; 2016-05+: 50 ms / 0.5 s).
TIMING: Final[dict[Era, LimitTiming]] = {Era.E14: LimitTiming(500_000, 2_500_000)}


def _half(value: int) -> int:
    """C ``int / 2``: truncation toward zero, also for negative differences."""
    return int(value / 2) if value < 0 else value // 2


def _to_uint16(value: float) -> int:
    """float -> uint16_t assignment: truncate; NaN/negative saturate to 0 as ARM's VCVT does."""
    if math.isnan(value) or value <= 0.0:
        return 0
    return 0xFFFF if value >= 65535.0 else int(value)


class PwmLimit:
    """One pwm_limit_t instance (the IO keeps one for its 8 outputs)."""

    def __init__(self, era: Era = ERA) -> None:
        self.timing = TIMING[era]
        self.state = LimitState.INIT
        self.time_armed_us = 0

    def _step(self, armed: bool, now_us: int) -> None:
        timing = self.timing
        if self.state is LimitState.INIT:
            if armed:
                if self.time_armed_us == 0:
                    self.time_armed_us = now_us
                if now_us - self.time_armed_us >= timing.init_time_us:
                    self.state = LimitState.OFF
        elif self.state is LimitState.OFF:
            if armed:
                self.state = LimitState.RAMP
                self.time_armed_us = now_us
        elif self.state is LimitState.RAMP:
            if not armed:
                self.state = LimitState.OFF
            elif now_us - self.time_armed_us >= timing.ramp_time_us:
                self.state = LimitState.ON
        elif not armed:  # ON
            self.state = LimitState.OFF

    def calc(self, armed: bool, now_us: int, disarmed_pwm: Sequence[int],
             min_pwm: Sequence[int], max_pwm: Sequence[int], outputs: Sequence[float],
             reverse_mask: int = 0) -> list[int]:
        """Effective PWM (µs) for ``len(outputs)`` channels.

        ``reverse_mask`` negates output i when bit i is set. The E14 IO has no PWM_REVERSE
        register and always passes 0; the argument exists for later eras and FMU-side use.
        """
        self._step(armed, now_us)
        n = len(outputs)
        if self.state in (LimitState.OFF, LimitState.INIT):
            return [disarmed_pwm[i] for i in range(n)]
        if self.state is LimitState.RAMP:
            progress = (now_us - self.time_armed_us) * 10000 // self.timing.ramp_time_us
            ramp: list[int] = []
            for i in range(n):
                if disarmed_pwm[i] > 0:
                    d = min(disarmed_pwm[i], min_pwm[i])
                    ramp.append((d + (min_pwm[i] - d) * progress // 10000) & 0xFFFF)
                else:
                    ramp.append(min_pwm[i])
            lows: Sequence[int] = ramp
        else:
            lows = min_pwm
        # _to_uint16 and _half inlined (this runs for every output on every 1 ms IO pass);
        # the expression order is the C code's, see the module docstring.
        result = []
        for i in range(n):
            value = outputs[i]
            if reverse_mask & (1 << i):
                value = -value
            lo, hi = lows[i], max_pwm[i]
            mid = hi + lo
            v = value * (hi - lo) / 2.0 + (mid // 2 if mid >= 0 else int(mid / 2))
            if isnan(v) or v <= 0.0:  # NaN or negative: VCVT saturates to 0
                pwm = 0
            elif v >= 65535.0:
                pwm = 0xFFFF
            else:
                pwm = int(v)
            result.append(lo if pwm < lo else (hi if pwm > hi else pwm))  # noqa: FURB136
        return result
