"""Level horizon calibration (PX4's ``level_calibration``): the board's small mounting tilt.

With the vehicle standing level, the calibrated specific force (``vehicle_acceleration``, body
axes, the current board rotation and trims applied) is averaged for :attr:`DURATION_US`; its
roll and pitch are what the board is still tilted by. They are folded into the trim rotation
(``SENS_BOARD_X_OFF`` roll, ``SENS_BOARD_Y_OFF`` pitch, degrees), which the sensors module
applies after ``SENS_BOARD_ROT``, so the estimator then reads a level vehicle as level. A tilt
above :data:`MAX_TILT_DEG` is not a mounting error but a vehicle that is not level: refused.
"""

from __future__ import annotations

import math
from typing import Any, Final

from common.rotation import euler_matrix
from firmware.modules.commander.calibration import messages as msg
from firmware.modules.commander.calibration.common import (
    CRITICAL,
    DONE,
    FAILED,
    INFO,
    RUNNING,
    Routine,
    Say,
)
from firmware.platform.uorb import Subscription

__all__ = ["LevelCalibration", "tilt_deg"]

MAX_TILT_DEG: Final = 20.0
#: motion: a sample this far (m/s^2) from the running mean on any axis
MOTION_M_S2: Final = 1.0


def tilt_deg(f: tuple[float, float, float]) -> tuple[float, float]:
    """(roll, pitch) in degrees of a body at rest whose specific force is ``f``."""
    fx, fy, fz = f
    roll = math.atan2(-fy, -fz)
    pitch = math.atan2(fx, math.hypot(fy, fz))
    return math.degrees(roll), math.degrees(pitch)


class LevelCalibration(Routine):
    KIND = "level"
    DURATION_US = 1_000_000

    def __init__(self, orb: Any, params: Any, say: Say) -> None:
        super().__init__(orb, params, say)
        self.sub = Subscription(orb, "vehicle_acceleration")
        self.sub.copy()
        self.sum = [0.0, 0.0, 0.0]
        self.n = 0
        self.next_progress_us = 0

    def _step(self, now_us: int) -> int:
        for s in self.sub.update_all():
            x, y, z = float(s.xyz[0]), float(s.xyz[1]), float(s.xyz[2])
            if self.n >= 10:
                k = 1.0 / self.n
                if max(abs(x - self.sum[0] * k), abs(y - self.sum[1] * k),
                       abs(z - self.sum[2] * k)) > MOTION_M_S2:
                    self.say(CRITICAL, msg.failed("motion"))
                    return FAILED
            self.sum[0] += x
            self.sum[1] += y
            self.sum[2] += z
            self.n += 1
        elapsed = now_us - self.started_us
        if elapsed >= self.next_progress_us and elapsed < self.DURATION_US:
            self.say(INFO, msg.progress(int(elapsed * 100 // self.DURATION_US)))
            self.next_progress_us = elapsed + self.DURATION_US // 5
        if elapsed < self.DURATION_US:
            return RUNNING
        if self.n == 0:
            self.say(CRITICAL, msg.READING_SENSOR)
            return FAILED
        k = 1.0 / self.n
        roll, pitch = tilt_deg((self.sum[0] * k, self.sum[1] * k, self.sum[2] * k))
        if abs(roll) > MAX_TILT_DEG or abs(pitch) > MAX_TILT_DEG:
            self.say(CRITICAL, msg.failed(f"excess tilt ({roll:.1f}, {pitch:.1f} deg)"))
            return FAILED
        trim = euler_matrix(self.get("SENS_BOARD_X_OFF"), self.get("SENS_BOARD_Y_OFF"),
                            self.get("SENS_BOARD_Z_OFF"))
        c = euler_matrix(roll, pitch, 0.0)
        m = [[sum(c[i][k2] * trim[k2][j] for k2 in range(3)) for j in range(3)]
             for i in range(3)]
        new_roll = math.degrees(math.atan2(m[2][1], m[2][2]))
        new_pitch = math.degrees(-math.asin(max(-1.0, min(1.0, m[2][0]))))
        result = self.finish({"SENS_BOARD_X_OFF": new_roll, "SENS_BOARD_Y_OFF": new_pitch})
        return DONE if result == DONE else FAILED
