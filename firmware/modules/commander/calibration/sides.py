"""What the accelerometer and magnetometer calibrations share: PX4's
``calibrate_from_orientation`` loop of announcing the pending sides and waiting for the vehicle
to rest on one of them."""

from __future__ import annotations

from typing import Any, Final

from firmware.modules.commander.calibration import messages as msg
from firmware.modules.commander.calibration.common import (
    CRITICAL,
    FAILED,
    INFO,
    RUNNING,
    Routine,
    Say,
    SensorSet,
)
from firmware.modules.commander.calibration.orientation import OrientationDetector

__all__ = ["ANNOUNCE", "DETECT", "SideBySide"]

#: the two states every side-by-side calibration starts with; routines number theirs after
ANNOUNCE: Final = 0
DETECT: Final = 1


class SideBySide(Routine):
    """Announce the pending sides, wait for the vehicle to rest on one, give up after too long
    or too many wrong sides. Subclasses set ``done`` (six sides), ``accels`` (the orientation
    source) and ``detector``, and make :meth:`_result` once every side is done."""

    #: no side found for this long: PX4 gives up ("timeout: no motion")
    DETECT_TIMEOUT_US: Final = 90_000_000
    #: orientation failures in a row (invalid side, a side done before) before giving up
    MAX_FAILURES: Final = 4
    accels: SensorSet
    detector: OrientationDetector

    def __init__(self, orb: Any, params: Any, say: Say) -> None:
        super().__init__(orb, params, say)
        self.state = ANNOUNCE
        self.failures = 0
        self.since_us = 0
        self.done: list[bool] = [False] * 6

    def _result(self) -> int:  # pragma: no cover - abstract
        raise NotImplementedError

    def _announce(self, now_us: int) -> int:
        if all(self.done):
            return self._result()
        if self.failures > self.MAX_FAILURES:
            self.say(CRITICAL, msg.failed("timeout: no motion"))
            return FAILED
        self.say(INFO, msg.pending(self.done))
        self.say(INFO, msg.HOLD_STILL)
        self.detector.reset()
        self.accels.skip()
        self.since_us = now_us
        self.state = DETECT
        return RUNNING

    def _detect_timed_out(self, now_us: int) -> bool:
        """No side for DETECT_TIMEOUT_US: said, and the routine is to fail."""
        if now_us - self.since_us > self.DETECT_TIMEOUT_US:
            self.say(CRITICAL, msg.failed("timeout: no motion"))
            return True
        return False
