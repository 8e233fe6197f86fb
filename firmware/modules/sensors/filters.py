"""Small digital filters for the sensor pipeline, in plain floats.

The gyro low-pass runs once per gyro sample (1 kHz), so it is written for the host: three
independent biquads unrolled in one method, no lists, no numpy (a numpy call costs more than the
whole filter). The coefficients are the textbook bilinear-transform second-order Butterworth.
"""

from __future__ import annotations

import math

__all__ = ["LowPass2p3", "butterworth2"]


def butterworth2(sample_hz: float, cutoff_hz: float) -> tuple[float, float, float, float, float]:
    """(b0, b1, b2, a1, a2) of a 2nd-order Butterworth low-pass; a pass-through when the
    cutoff is off (<= 0) or too close to Nyquist to be meaningful."""
    if cutoff_hz <= 0.0 or sample_hz <= 0.0 or cutoff_hz >= 0.45 * sample_hz:
        return 1.0, 0.0, 0.0, 0.0, 0.0
    ohm = math.tan(math.pi * cutoff_hz / sample_hz)
    k = 2.0 * math.cos(math.pi / 4.0) * ohm
    c = 1.0 + k + ohm * ohm
    b0 = ohm * ohm / c
    return b0, 2.0 * b0, b0, 2.0 * (ohm * ohm - 1.0) / c, (1.0 - k + ohm * ohm) / c


class LowPass2p3:
    """A 2nd-order Butterworth low-pass on a 3-vector (direct form II, one state pair per axis).

    ``reset`` primes the delay line with a steady input so that a (re)started filter does not
    ring from zero, which matters after a gyro failover: the rate controller must not see a
    step to 0 rad/s.
    """

    __slots__ = (
        "_x1",
        "_x2",
        "_y1",
        "_y2",
        "_z1",
        "_z2",
        "a1",
        "a2",
        "b0",
        "b1",
        "b2",
        "cutoff_hz",
        "sample_hz",
    )

    def __init__(self, sample_hz: float, cutoff_hz: float) -> None:
        self.set_cutoff(sample_hz, cutoff_hz)
        self._x1 = self._x2 = self._y1 = self._y2 = self._z1 = self._z2 = 0.0

    def set_cutoff(self, sample_hz: float, cutoff_hz: float) -> None:
        self.sample_hz = sample_hz
        self.cutoff_hz = cutoff_hz
        self.b0, self.b1, self.b2, self.a1, self.a2 = butterworth2(sample_hz, cutoff_hz)

    def reset(self, x: float, y: float, z: float) -> None:
        # Steady state of DF-II for a constant input u: w = u / (1 + a1 + a2).
        d = 1.0 + self.a1 + self.a2
        if d == 0.0:
            d = 1.0
        self._x1 = self._x2 = x / d
        self._y1 = self._y2 = y / d
        self._z1 = self._z2 = z / d

    def apply(self, x: float, y: float, z: float) -> tuple[float, float, float]:
        b0, b1, b2, a1, a2 = self.b0, self.b1, self.b2, self.a1, self.a2
        w1, w2 = self._x1, self._x2
        w0 = x - a1 * w1 - a2 * w2
        ox = b0 * w0 + b1 * w1 + b2 * w2
        self._x2, self._x1 = w1, w0
        w1, w2 = self._y1, self._y2
        w0 = y - a1 * w1 - a2 * w2
        oy = b0 * w0 + b1 * w1 + b2 * w2
        self._y2, self._y1 = w1, w0
        w1, w2 = self._z1, self._z2
        w0 = z - a1 * w1 - a2 * w2
        oz = b0 * w0 + b1 * w1 + b2 * w2
        self._z2, self._z1 = w1, w0
        return ox, oy, oz
