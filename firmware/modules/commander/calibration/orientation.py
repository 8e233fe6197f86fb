"""Which side the vehicle rests on (PX4's ``detect_orientation``), from the accelerometer.

An exponential moving average (time constant 0.5 s) of the specific force in body axes and a
decaying max-hold of each axis's squared deviation from it (the dispersion) decide rest: below
(0.25 m/s^2)^2 on every axis is still, above four times that is motion (hysteresis between).
Still for 1.3 s, the averaged vector names the side: one axis within 5 m/s^2 of +-g, the
others within 5 m/s^2 of 0; anything else is an invalid orientation.
"""

from __future__ import annotations

from typing import Final
from common.units import G0_M_S2

__all__ = ["G0", "SIDE_GRAVITY", "OrientationDetector"]

EMA_S: Final = 0.5
STILL_THR2: Final = 0.25 * 0.25
STILL_TIME_US: Final = 1_300_000
ERR_THR: Final = 5.0
#: specific force at rest on each side (PX4's order: back, front, left, right, up, down)
SIDE_GRAVITY: Final = ((G0_M_S2, 0.0, 0.0), (-G0_M_S2, 0.0, 0.0), (0.0, G0_M_S2, 0.0),
                       (0.0, -G0_M_S2, 0.0), (0.0, 0.0, G0_M_S2), (0.0, 0.0, -G0_M_S2))
#: what :meth:`OrientationDetector.feed` reports besides a side (0..5)
NOTHING: Final = -1
REST: Final = -2
MOTION: Final = -3
INVALID: Final = -4


class OrientationDetector:
    """``lenient`` (PX4's for the magnetometer, turned by hand): three times the still
    threshold, still for 0.5 s."""

    def __init__(self, lenient: bool = False) -> None:
        self.thr2 = STILL_THR2 * (9.0 if lenient else 1.0)
        self.still_us = 500_000 if lenient else STILL_TIME_US
        self.reset()

    def reset(self) -> None:
        self.ema = [0.0, 0.0, 0.0]
        self.disp = [0.0, 0.0, 0.0]
        self.t_prev = -1
        self.t_still = -1
        self.primed = False

    def feed(self, t_us: int, f: tuple[float, float, float]) -> int:
        """One sample (body axes, m/s^2, at ``t_us``): NOTHING, REST (rest just began),
        MOTION (rest interrupted), INVALID or the side once still long enough."""
        if not self.primed:
            self.ema = [f[0], f[1], f[2]]
            self.t_prev = t_us
            self.primed = True
            return NOTHING
        dt = (t_us - self.t_prev) * 1e-6
        self.t_prev = t_us
        w = min(1.0, max(0.0, dt / EMA_S))
        for i in range(3):
            d = f[i] - self.ema[i]
            self.ema[i] += d * w
            d2 = min(d * d, self.thr2 * 8.0)
            self.disp[i] *= 1.0 - w
            if d2 > self.disp[i]:
                self.disp[i] = d2
        if all(v < self.thr2 for v in self.disp):
            if self.t_still < 0:
                self.t_still = t_us
                return REST
            if t_us - self.t_still > self.still_us:
                side = self.side()
                self.t_still = -1
                return INVALID if side < 0 else side
        elif any(v > self.thr2 * 4.0 for v in self.disp) and self.t_still >= 0:
            self.t_still = -1
            return MOTION
        return NOTHING

    def side(self) -> int:
        e = self.ema
        for side, g in enumerate(SIDE_GRAVITY):
            if all(abs(e[i] - g[i]) < ERR_THR for i in range(3)):
                return side
        return -1
