"""The motor test on the IO's outputs: one motor at a set throttle, the others disarmed.

The commander publishes ``test_motor`` (PX4's topic) for MAV_CMD_DO_MOTOR_TEST and
MAV_CMD_ACTUATOR_TEST, disarmed only. PX4 runs the test in its output driver's mixing
(``MixingOutput``); with E14's IO, which mixes on the IO, the real way to put chosen pulse
widths on the pins without arming is the IO's DIRECT_PWM page (what ``pwm test`` writes): a
write sets RAW_PWM, and the IO drives its outputs from the written values while RAW_PWM and
FMU_OK hold and the safety switch is off (the IO enforces it). The driver writes the page every
poll (20 ms, so FMU_OK stays fresh) while the test runs and holds back the CONTROLS writes
that would clear RAW_PWM; at the timeout, a stop or an arming it writes zero controls once,
which clears RAW_PWM: the IO mixes again and, disarmed, outputs its disarmed PWM.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Final

from ioproc.protocol import CONTROL_CHANNELS, PageNo

if TYPE_CHECKING:
    from firmware.drivers.px4io.driver import Px4ioDriver
    from firmware.drivers.px4io.link import Txn

__all__ = ["MotorTest"]

#: the longest test (MAVLink's ACTUATOR_TEST: timeout at most 3 s)
MAX_TIMEOUT_US: Final = 3_000_000


class MotorTest:
    """The running test (if any) and the DIRECT_PWM writes that carry it."""

    def __init__(self, driver: Px4ioDriver) -> None:
        self.d = driver
        self.sub = driver.m.subscribe("test_motor")
        self.sub.copy()  # a test published before the driver started is over
        self.motor = -1
        self.pwm_us = 0
        self.end_us = 0
        self.running = False
        #: tests run (``px4io status`` and tests read it)
        self.runs = 0

    def _pwm(self, value: float) -> int:
        lo, hi = int(self.d._param("PWM_MIN", 1000)), int(self.d._param("PWM_MAX", 2000))
        v = value if math.isfinite(value) else 0.0
        return lo + round(max(0.0, min(1.0, v)) * (hi - lo))

    def poll(self, now_us: int, armed: bool) -> None:
        """Take a new ``test_motor``; end the test at its timeout or when the vehicle arms."""
        msg = self.sub.update()
        if msg is not None:
            n = len(self.d.pwm_disarmed)
            if int(msg.action) == 1 and int(msg.motor_number) < n and not armed:
                self.motor = int(msg.motor_number)
                self.pwm_us = self._pwm(float(msg.value))
                self.end_us = now_us + min(int(msg.timeout_ms) * 1000, MAX_TIMEOUT_US)
                if not self.running:
                    self.runs += 1
                self.running = True
            else:
                self.end_us = 0
        if self.running and (armed or now_us >= self.end_us):
            self.end_us = 0

    def active(self) -> bool:
        return self.running

    def write(self, now_us: int) -> Txn:
        """The poll's IO write: the test's DIRECT_PWM, or the zero controls that end it."""
        if not self.running:
            return True
        link = self.d.link
        if self.end_us == 0 or now_us >= self.end_us:
            self.running = False
            ok = yield from link.write(PageNo.CONTROLS, 0, [0] * CONTROL_CHANNELS)
            return ok
        pwm = list(self.d.pwm_disarmed)
        pwm[self.motor] = self.pwm_us
        ok = yield from link.write(PageNo.DIRECT_PWM, 0, pwm)
        return ok
