"""Magnetometer calibration with rotations (PX4's ``mag_calibration``): hard-iron offsets.

For every side in ``CAL_MAG_SIDES`` (bit i: PX4's side i, back front left right up down; 63
all six) the operator puts the vehicle on that side (PX4's lenient side detection: three times
the still threshold, 0.5 s), is told "[cal] Rotate vehicle around the detected orientation",
and turns it about the vertical. Collection starts once the gyro has integrated 0.5 rad on
some axis (no rotation within :data:`ROTATION_WAIT_US`: "This calibration requires rotation")
and ends after one full turn (counted from the side's detection),
:attr:`MagCalibration.POINTS_PER_SIDE` points or
:data:`SIDE_TIMEOUT_US`. Points closer to one already taken than PX4's minimum distance are
rejected, so a vehicle held still does not pile up one point. Over every side's points each
magnetometer's raw field (``sensor_mag``) lies on a sphere around its hard-iron offset: a
linear least-squares sphere fit (``|p|^2 = 2 c.p + k``) gives the centre ``c``, written to
``CAL_MAGn_[XYZ]OFF`` with scales 1 and no off-diagonal terms (the soft-iron ellipsoid fit is
not done).
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
    OrientationDetector,
)
from firmware.modules.commander.calibration.sides import ANNOUNCE, DETECT, SideBySide
from firmware.modules.sensors.params import N_MAG_CAL

__all__ = ["MagCalibration", "sphere_fit"]

WAIT_ROTATION, COLLECT = 2, 3
ROTATION_START_RAD: Final = 0.5
ROTATION_WAIT_US: Final = 30_000_000
SIDE_TIMEOUT_US: Final = 20_000_000
#: a full turn about some axis since the side was detected (less 5 % for the gyro's errors)
FULL_TURN_RAD: Final = 0.95 * 2.0 * math.pi
#: PX4's minimum distance between points: 5.4 r / sqrt(points) / 3 for a field of radius r
NOMINAL_FIELD_GA: Final = 0.5


def sphere_fit(points: list[tuple[float, float, float]]) -> tuple[float, float, float, float]:
    """(cx, cy, cz, r) of the least-squares sphere through ``points`` (NaN if degenerate)."""
    ata = [[0.0] * 4 for _ in range(4)]
    atb = [0.0] * 4
    for x, y, z in points:
        row = (2.0 * x, 2.0 * y, 2.0 * z, 1.0)
        b = x * x + y * y + z * z
        for i in range(4):
            atb[i] += row[i] * b
            for j in range(4):
                ata[i][j] += row[i] * row[j]
    # Gauss-Jordan with partial pivoting on the 4x4 normal equations
    m = [ata[i] + [atb[i]] for i in range(4)]
    for col in range(4):
        piv = max(range(col, 4), key=lambda r: abs(m[r][col]))
        if abs(m[piv][col]) < 1e-12:
            return math.nan, math.nan, math.nan, math.nan
        m[col], m[piv] = m[piv], m[col]
        p = m[col][col]
        m[col] = [v / p for v in m[col]]
        for r in range(4):
            if r != col and m[r][col] != 0.0:
                f = m[r][col]
                m[r] = [a - f * b for a, b in zip(m[r], m[col])]
    cx, cy, cz, k = (m[i][4] for i in range(4))
    r2 = k + cx * cx + cy * cy + cz * cz
    return cx, cy, cz, math.sqrt(r2) if r2 > 0.0 else math.nan


class MagCalibration(SideBySide):
    KIND = "mag"
    #: PX4: 240 points over all sides
    POINTS_PER_SIDE = 40

    def __init__(self, orb: Any, params: Any, say: Say) -> None:
        super().__init__(orb, params, say)
        self.mags = SensorSet(orb, "sensor_mag")
        self.accels = SensorSet(orb, "sensor_accel", 1)
        self.gyros = SensorSet(orb, "sensor_gyro", 1)
        self.detector = OrientationDetector(lenient=True)
        mask = int(self.get("CAL_MAG_SIDES")) & 63 or 63
        self.done = [not mask & (1 << i) for i in range(6)]
        self.n_sides = sum(1 for d in self.done if not d)
        self.points: list[list[tuple[float, float, float]]] = [[] for _ in range(len(self.mags))]
        n_total = self.POINTS_PER_SIDE * self.n_sides
        self.min_dist = 5.4 * NOMINAL_FIELD_GA / math.sqrt(n_total) / 3.0
        self.side = -1
        self.side_points = 0
        self.gyro_int = [0.0, 0.0, 0.0]
        self.gyro_t = -1
        self.first_step = True

    def _step(self, now_us: int) -> int:
        if not len(self.mags) or not len(self.accels) or not len(self.gyros):
            self.say(CRITICAL, msg.READING_SENSOR)
            return FAILED
        if self.first_step:
            self.first_step = False
            for i in range(6):  # sides left out by CAL_MAG_SIDES: done from the start (PX4)
                if self.done[i]:
                    self.say(INFO, msg.side_done(i))
        if self.state == ANNOUNCE:
            return self._announce(now_us)
        if self.state == DETECT:
            return self._detect(now_us)
        if self.state == WAIT_ROTATION:
            return self._wait_rotation(now_us)
        return self._collect(now_us)

    def _detect(self, now_us: int) -> int:
        if self._detect_timed_out(now_us):
            return FAILED
        rot = self.board_rotation()
        for s in self.accels.drain()[0]:
            x, y, z = float(s.x), float(s.y), float(s.z)
            f = (rot[0][0] * x + rot[0][1] * y + rot[0][2] * z,
                 rot[1][0] * x + rot[1][1] * y + rot[1][2] * z,
                 rot[2][0] * x + rot[2][1] * y + rot[2][2] * z)
            event = self.detector.feed(int(s.timestamp_sample), f)
            if event == NOTHING:
                continue
            if event == REST:
                self.say(INFO, msg.REST_DETECTED)
                continue
            if event == MOTION:
                self.say(INFO, msg.MOTION_DETECTED)
                continue
            if event == INVALID or self.done[event]:
                self.failures += 1
                self.say(INFO, msg.already_done(event) if event >= 0 else
                         "[cal] ERROR: invalid orientation")
                self.state = ANNOUNCE
                return RUNNING
            self.failures = 0
            self.side = event
            self.say(INFO, msg.detected(event))
            self.say(INFO, "[cal] Rotate vehicle around the detected orientation")
            self.gyro_int = [0.0, 0.0, 0.0]
            self.gyro_t = -1
            self.gyros.skip()
            self.since_us = now_us
            self.state = WAIT_ROTATION
            return RUNNING
        return RUNNING

    def _integrate_gyro(self) -> float:
        """Integrate the first gyro; the largest |angle| on any axis so far."""
        for s in self.gyros.drain()[0]:
            t = int(s.timestamp_sample)
            if self.gyro_t >= 0:
                dt = (t - self.gyro_t) * 1e-6
                self.gyro_int[0] += float(s.x) * dt
                self.gyro_int[1] += float(s.y) * dt
                self.gyro_int[2] += float(s.z) * dt
            self.gyro_t = t
        return max(abs(v) for v in self.gyro_int)

    def _wait_rotation(self, now_us: int) -> int:
        if now_us - self.since_us > ROTATION_WAIT_US:
            self.say(CRITICAL, msg.failed("This calibration requires rotation"))
            return FAILED
        if self._integrate_gyro() < ROTATION_START_RAD:
            return RUNNING
        self.mags.skip()
        self.side_points = 0
        self.since_us = now_us
        self.state = COLLECT
        return RUNNING

    def _far_enough(self, i: int, p: tuple[float, float, float]) -> bool:
        d2 = self.min_dist * self.min_dist
        return all((p[0] - q[0]) ** 2 + (p[1] - q[1]) ** 2 + (p[2] - q[2]) ** 2 >= d2
                   for q in self.points[i])

    def _collect(self, now_us: int) -> int:
        turned = self._integrate_gyro()
        latest = [samples[-1] if samples else None for samples in self.mags.drain()]
        new = [(float(s.x), float(s.y), float(s.z)) if s is not None else None for s in latest]
        # all magnetometers in lockstep (PX4): a point goes in only if it is new for every one
        if all(p is not None for p in new) and \
                all(self._far_enough(i, p) for i, p in enumerate(new) if p is not None):
            for i, p in enumerate(new):
                if p is not None:
                    self.points[i].append(p)
            self.side_points += 1
        if self.side_points < self.POINTS_PER_SIDE and turned < FULL_TURN_RAD and \
                now_us - self.since_us < SIDE_TIMEOUT_US:
            return RUNNING
        self.done[self.side] = True
        self.say(INFO, msg.side_done(self.side))
        sides_done = self.n_sides - sum(1 for d in self.done if not d)
        self.say(INFO, msg.progress(sides_done * 100 // max(1, self.n_sides)))
        self.state = ANNOUNCE
        return RUNNING

    def _result(self) -> int:
        slots = assign_slots(self.params, "MAG", N_MAG_CAL, self.mags.device_ids)
        values: dict[str, float] = {}
        for i, (dev, slot) in enumerate(zip(self.mags.device_ids, slots)):
            cx, cy, cz, r = sphere_fit(self.points[i])
            if slot < 0 or len(self.points[i]) < 10 or not all(
                    math.isfinite(v) for v in (cx, cy, cz, r)):
                self.say(CRITICAL, msg.failed(f"mag {i} sphere fit"))
                return FAILED
            p = f"CAL_MAG{slot}_"
            values[p + "ID"] = float(dev)
            values[p + "XOFF"], values[p + "YOFF"], values[p + "ZOFF"] = cx, cy, cz
            for a in "XYZ":
                values[p + a + "SCALE"] = 1.0
                values[p + a + "ODIAG"] = 0.0
        result = self.finish(values)
        return DONE if result == DONE else FAILED
