"""Accelerometer calibration on six sides (PX4's ``accelerometer_calibration``).

The operator turns the vehicle so each of its six sides faces down in turn, in any order,
holding it still on each. Every accelerometer is averaged on every side (raw ``sensor_accel``,
board frame); from the six averages each axis gets an offset and a scale: per axis, the raw
reading is fitted as ``offset + true / scale`` over the six sides, where ``true`` is gravity's
specific force on that side expressed in the board frame (through the inverse of the board
rotation, so a board mounted rotated or trimmed calibrates the same). With SENS_BOARD_ROT 0
that is PX4's formula: the offset is the mean of the +g and -g readings of the axis and the
scale g over half their difference. The result goes to ``CAL_ACCn_[XYZ]OFF`` /
``CAL_ACCn_[XYZ]SCALE``.

The dialogue is QGroundControl's (see :mod:`.messages`): "pending: ...", "hold vehicle still
on a pending side", "<side> orientation detected", "<side> side done, rotate to a different
side", "<side> side already completed". Side detection: :mod:`.orientation`.
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
    Say,
    SensorSet,
    assign_slots,
)
from firmware.modules.commander.calibration.orientation import (
    INVALID,
    MOTION,
    NOTHING,
    REST,
    SIDE_GRAVITY,
    OrientationDetector,
)
from firmware.modules.commander.calibration.sides import ANNOUNCE, DETECT, SideBySide
from firmware.modules.sensors.params import N_ACCEL_CAL
from common.quaternion import Vec3

__all__ = ["AccelCalibration", "fit_axis"]

COLLECT: Final = 2


def fit_axis(true: list[float], raw: list[float]) -> tuple[float, float]:
    """(offset, scale) with ``raw = offset + true / scale`` in the least-squares sense."""
    n = len(true)
    mt = sum(true) / n
    mr = sum(raw) / n
    var = sum((t - mt) ** 2 for t in true)
    cov = sum((t - mt) * (r - mr) for t, r in zip(true, raw))
    if var <= 0.0 or cov == 0.0:
        return math.nan, math.nan
    gain = cov / var
    return mr - gain * mt, 1.0 / gain


class AccelCalibration(SideBySide):
    KIND = "accel"
    #: samples of the first accelerometer per side
    SAMPLES = 300

    def __init__(self, orb: Any, params: Any, say: Say) -> None:
        super().__init__(orb, params, say)
        self.accels = SensorSet(orb, "sensor_accel")
        self.detector = OrientationDetector()
        self.side = -1
        n = len(self.accels)
        self.sums: list[list[float]] = [[0.0, 0.0, 0.0, 0.0] for _ in range(n)]
        self.refs: list[list[Vec3 | None]] = [[None] * 6 for _ in range(n)]

    def _body(self, x: float, y: float, z: float) -> Vec3:
        (a, b, c), (d, e, f), (g, h, i) = self.board_rotation()
        return a * x + b * y + c * z, d * x + e * y + f * z, g * x + h * y + i * z

    def _step(self, now_us: int) -> int:
        if not len(self.accels):
            self.say(CRITICAL, msg.READING_SENSOR)
            return FAILED
        if self.state == ANNOUNCE:
            return self._announce(now_us)
        if self.state == DETECT:
            return self._detect(now_us)
        return self._collect()

    def _detect(self, now_us: int) -> int:
        if self._detect_timed_out(now_us):
            return FAILED
        for s in self.accels.drain()[0]:
            event = self.detector.feed(int(s.timestamp_sample),
                                       self._body(float(s.x), float(s.y), float(s.z)))
            if event == NOTHING:
                continue
            if event == REST:
                self.say(INFO, msg.REST_DETECTED)
            elif event == MOTION:
                self.say(INFO, msg.MOTION_DETECTED)
            elif event == INVALID:
                self.failures += 1
                self.say(CRITICAL, "[cal] ERROR: invalid orientation")
                self.state = ANNOUNCE
                return RUNNING
            elif self.done[event]:
                self.failures += 1
                self.say(INFO, msg.already_done(event))
                self.state = ANNOUNCE
                return RUNNING
            else:
                self.failures = 0
                self.side = event
                self.say(INFO, msg.detected(event))
                for acc in self.sums:
                    acc[0] = acc[1] = acc[2] = acc[3] = 0.0
                self.accels.skip()
                self.state = COLLECT
                return RUNNING
        return RUNNING

    def _collect(self) -> int:
        for i, samples in enumerate(self.accels.drain()):
            acc = self.sums[i]
            for s in samples:
                acc[0] += float(s.x)
                acc[1] += float(s.y)
                acc[2] += float(s.z)
                acc[3] += 1.0
        if self.sums[0][3] < self.SAMPLES:
            return RUNNING
        side = self.side
        for i, acc in enumerate(self.sums):
            if acc[3] > 0:
                k = 1.0 / acc[3]
                self.refs[i][side] = (acc[0] * k, acc[1] * k, acc[2] * k)
        self.done[side] = True
        self.say(INFO, msg.side_done(side))
        self.say(INFO, msg.progress(sum(self.done) * 100 // 6))
        self.state = ANNOUNCE
        return RUNNING

    def _result(self) -> int:
        rot = self.board_rotation()
        # gravity on each side in the board (raw) frame: R^T g_body
        true_raw = [tuple(sum(rot[r][c] * g[r] for r in range(3)) for c in range(3))
                    for g in SIDE_GRAVITY]
        slots = assign_slots(self.params, "ACC", N_ACCEL_CAL, self.accels.device_ids)
        values: dict[str, float] = {}
        for i, (dev, slot) in enumerate(zip(self.accels.device_ids, slots)):
            refs = self.refs[i]
            if slot < 0 or any(r is None for r in refs):
                self.say(CRITICAL, msg.failed(f"no data from accel {i}"))
                return FAILED
            p = f"CAL_ACC{slot}_"
            values[p + "ID"] = float(dev)
            for axis, name in enumerate("XYZ"):
                offset, scale = fit_axis([t[axis] for t in true_raw],
                                         [r[axis] for r in refs if r is not None])
                if not (math.isfinite(offset) and 0.1 <= scale <= 3.0):
                    self.say(CRITICAL, msg.failed(f"accel {i} {name} axis out of range"))
                    return FAILED
                values[p + name + "OFF"] = offset
                values[p + name + "SCALE"] = scale
        result = self.finish(values)
        return DONE if result == DONE else FAILED
