"""Gyroscope calibration (PX4's ``gyro_calibration``): the offset of every gyro at rest.

The vehicle must be still. Each gyro's raw samples (``sensor_gyro``, board frame) are averaged
until the first gyro has delivered :attr:`GyroCalibration.SAMPLES` of them; the averages are
the offsets ``CAL_GYROn_[XYZ]OFF`` the sensors module subtracts, in the slot that holds (or is
given) the gyro's device id.

Still detection: the samples are also averaged in windows (a tenth of the count of the first
gyro, the same time span for every gyro), and a window whose mean differs from the mean of
the samples before it by more than PX4's limit (0.6 deg/s on any axis: what a vehicle being
moved shows, and the noise of a window's mean, ~0.1 deg/s for the L3GD20's 47 samples, does
not) means motion: "[cal] motion, retrying..", and the collection starts again, at most
:attr:`GyroCalibration.MAX_TRIES` times before the calibration fails.
"""

from __future__ import annotations

import math
from typing import Any, Final

from firmware.modules.commander.calibration import messages as msg
from firmware.modules.commander.calibration.common import (
    CRITICAL,
    DONE,
    FAILED,
    INFO,
    RUNNING,
    Routine,
    Say,
    SensorSet,
    assign_slots,
)
from firmware.modules.sensors.params import N_GYRO_CAL

__all__ = ["GyroCalibration"]

#: PX4's limit between a window's mean and the reference, rad/s (0.6 deg/s)
MAX_DIFF_RAD_S: Final = math.radians(0.6)
#: no sample from the first gyro for this long: the sensor is gone
SENSOR_TIMEOUT_US: Final = 1_000_000


class _Accumulator:
    """Sum and count of one gyro's samples, and of its current window."""

    __slots__ = ("n", "sx", "sy", "sz", "wn", "wx", "wy", "wz")

    def __init__(self) -> None:
        self.n = 0
        self.sx = self.sy = self.sz = 0.0
        self.wn = 0
        self.wx = self.wy = self.wz = 0.0

    def add(self, x: float, y: float, z: float) -> None:
        self.n += 1
        self.sx += x
        self.sy += y
        self.sz += z
        self.wn += 1
        self.wx += x
        self.wy += y
        self.wz += z

    def close_window(self) -> bool:
        """End the window; False if its mean is off the mean of everything before it."""
        wn, before = self.wn, self.n - self.wn
        still = True
        if wn and before:
            kw, kb = 1.0 / wn, 1.0 / before
            still = (abs(self.wx * kw - (self.sx - self.wx) * kb) <= MAX_DIFF_RAD_S
                     and abs(self.wy * kw - (self.sy - self.wy) * kb) <= MAX_DIFF_RAD_S
                     and abs(self.wz * kw - (self.sz - self.wz) * kb) <= MAX_DIFF_RAD_S)
        self.wn = 0
        self.wx = self.wy = self.wz = 0.0
        return still

    def mean(self) -> tuple[float, float, float]:
        k = 1.0 / self.n
        return self.sx * k, self.sy * k, self.sz * k


class GyroCalibration(Routine):
    KIND = "gyro"
    #: samples of the first gyro per try (PX4: 250)
    SAMPLES = 250
    #: tries before motion fails the calibration (PX4: 20)
    MAX_TRIES = 20

    def __init__(self, orb: Any, params: Any, say: Say) -> None:
        super().__init__(orb, params, say)
        self.gyros = SensorSet(orb, "sensor_gyro")
        self.tries = 0
        self.last_sample_us = -1
        self.next_progress = 0
        self.acc: list[_Accumulator] = []
        self._restart()

    def _restart(self) -> None:
        self.acc = [_Accumulator() for _ in range(len(self.gyros))]
        self.next_progress = 0
        self.gyros.skip()

    def _step(self, now_us: int) -> int:
        if not len(self.gyros):
            self.say(CRITICAL, msg.READING_SENSOR)
            return FAILED
        if self.last_sample_us < 0:
            self.last_sample_us = now_us
        for i, samples in enumerate(self.gyros.drain()):
            a = self.acc[i]
            for s in samples:
                a.add(float(s.x), float(s.y), float(s.z))
            if i == 0 and samples:
                self.last_sample_us = now_us
        still = True
        if self.acc[0].wn >= max(1, self.SAMPLES // 10):  # windows in the first gyro's time
            for a in self.acc:
                still = a.close_window() and still
        if not still:
            self.tries += 1
            if self.tries >= self.MAX_TRIES:
                self.say(CRITICAL, msg.failed("motion"))
                return FAILED
            self.say(CRITICAL, msg.MOTION_RETRY)
            self._restart()
            return RUNNING
        if now_us - self.last_sample_us > SENSOR_TIMEOUT_US:
            self.say(CRITICAL, msg.READING_SENSOR)
            return FAILED
        n0 = self.acc[0].n
        if n0 >= self.next_progress and n0 < self.SAMPLES:
            self.say(INFO, msg.progress(n0 * 100 // self.SAMPLES))
            self.next_progress = n0 + max(1, self.SAMPLES // 20)
        if n0 < self.SAMPLES:
            return RUNNING
        return self._result()

    def _result(self) -> int:
        slots = assign_slots(self.params, "GYRO", N_GYRO_CAL, self.gyros.device_ids)
        values: dict[str, float] = {}
        for i, (dev, slot) in enumerate(zip(self.gyros.device_ids, slots)):
            a = self.acc[i]
            if slot < 0 or a.n < self.SAMPLES // 2:
                self.say(CRITICAL, msg.failed(f"no data from gyro {i}"))
                return FAILED
            off = a.mean()
            if not all(math.isfinite(v) for v in off):
                self.say(CRITICAL, msg.failed(f"gyro {i} offsets not finite"))
                return FAILED
            p = f"CAL_GYRO{slot}_"
            values[p + "ID"] = float(dev)
            values[p + "XOFF"], values[p + "YOFF"], values[p + "ZOFF"] = off
        result = self.finish(values)
        return DONE if result == DONE else FAILED
