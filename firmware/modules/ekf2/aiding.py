"""Measurement bookkeeping shared by the fusion steps: innovation checks, flags, timeouts.

Each aiding source (GPS velocity, GPS position, baro height, magnetic heading) has an
:class:`AidSource` that remembers its last test ratio, whether the last measurement was
rejected, when it was last fused and when it was last rejected for the first time in a row, so
the module can say "rejected for 5 s: reset to the measurement" and fill estimator_status.

The pre-flight checks follow PX4's idea: low-pass the innovations while the vehicle is on the
ground; a large filtered innovation means the sensors disagree with each other (a bad compass,
a GPS multipath) and arming should be refused (commander reads the ``pre_flt_fail_*`` flags).
"""

from __future__ import annotations

from typing import Final

__all__ = [
    "INNOV_HGT",
    "INNOV_POS_NE",
    "INNOV_VEL_D",
    "INNOV_VEL_NE",
    "INNOV_YAW",
    "AidSource",
    "PreflightChecks",
]

#: estimator_status.innovation_check_flags bits (PX4 numbering)
INNOV_VEL_NE: Final = 1
INNOV_VEL_D: Final = 2
INNOV_POS_NE: Final = 4
INNOV_HGT: Final = 8
INNOV_YAW: Final = 128

#: pre-flight innovation limits (filtered) and the filter time constant
PREFLT_HEADING_RAD: Final = 0.5
PREFLT_VEL_NE_M_S: Final = 0.8
PREFLT_VEL_D_M_S: Final = 0.8
PREFLT_HGT_M: Final = 1.5
PREFLT_TAU_S: Final = 2.0


class AidSource:
    """State of one kind of observation."""

    __slots__ = (
        "active",
        "innov",
        "last_fuse_us",
        "name",
        "reject_since_us",
        "rejected",
        "rejections",
        "test_ratio",
    )

    def __init__(self, name: str) -> None:
        self.name = name
        self.test_ratio = 0.0
        self.rejected = False
        self.last_fuse_us = -1
        self.reject_since_us = -1
        self.rejections = 0
        self.innov = 0.0
        self.active = False

    def accepted(self, now_us: int, ratio: float) -> None:
        self.test_ratio = ratio
        self.rejected = False
        self.last_fuse_us = now_us
        self.reject_since_us = -1

    def reject(self, now_us: int, ratio: float) -> bool:
        """Record a rejection; True if it starts a new run of rejections (report it once)."""
        self.test_ratio = ratio
        self.rejections += 1
        first = not self.rejected
        self.rejected = True
        if self.reject_since_us < 0:
            self.reject_since_us = now_us
        return first

    def rejected_for_us(self, now_us: int) -> int:
        return now_us - self.reject_since_us if self.reject_since_us >= 0 else 0

    def since_fused_us(self, now_us: int) -> int:
        return now_us - self.last_fuse_us if self.last_fuse_us >= 0 else 1 << 62


class PreflightChecks:
    """Low-passed innovations with PX4-like limits."""

    __slots__ = ("heading", "hgt", "vel_d", "vel_ne")

    def __init__(self) -> None:
        self.heading = self.vel_ne = self.vel_d = self.hgt = 0.0

    @staticmethod
    def _lpf(old: float, new: float, dt: float) -> float:
        a = min(1.0, dt / PREFLT_TAU_S)
        return old + a * (new - old)

    def heading_innov(self, innov: float, dt: float) -> None:
        self.heading = self._lpf(self.heading, innov, dt)

    def vel_innov(self, n: float, e: float, d: float, dt: float) -> None:
        self.vel_ne = self._lpf(self.vel_ne, (n * n + e * e) ** 0.5, dt)
        self.vel_d = self._lpf(self.vel_d, d, dt)

    def hgt_innov(self, innov: float, dt: float) -> None:
        self.hgt = self._lpf(self.hgt, innov, dt)

    @property
    def fail_heading(self) -> bool:
        return abs(self.heading) > PREFLT_HEADING_RAD

    @property
    def fail_vel_ne(self) -> bool:
        return self.vel_ne > PREFLT_VEL_NE_M_S

    @property
    def fail_vel_d(self) -> bool:
        return abs(self.vel_d) > PREFLT_VEL_D_M_S

    @property
    def fail_hgt(self) -> bool:
        return abs(self.hgt) > PREFLT_HGT_M
