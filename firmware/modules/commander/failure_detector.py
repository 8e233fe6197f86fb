"""Failure detector: PX4's attitude check and the commander's reaction to it.

PX4's ``FailureDetector`` watches the attitude while the vehicle is armed and the attitude is
controlled: a roll beyond FD_FAIL_R or a pitch beyond FD_FAIL_P (degrees, 0 disables one)
held for FD_FAIL_R_TTRI / FD_FAIL_P_TTRI seconds raises the roll / pitch flag of
``vehicle_status.failure_detector_status``. The commander then reacts once per flight:

* within COM_LKDOWN_TKO seconds of takeoff: lockdown (``actuator_armed.lockdown``, the motors
  stop) and "Critical failure detected: lockdown";
* later, unless the CBRK_FLIGHTTERM circuit breaker (121212, PX4's default) disables flight
  termination: flight termination (``force_failsafe``: the IO drives its failsafe PWM, the
  motors stop, a parachute would fire) and "Critical failure detected: terminate flight";
* with the breaker set, only the flags and the status bits: the vehicle flies on (or not).

Not modelled: the altitude, external (FD_EXT_ATS_EN), ESC-arming and imbalanced-propeller
checks.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Final

from firmware.platform.params import ParamDef

if TYPE_CHECKING:
    from firmware.modules.commander.commander import CommanderModule

__all__ = ["CBRK_FLIGHTTERM_KEY", "FAILURE_DETECTOR_PARAMS", "FailureDetector", "FAILURE_PITCH",
           "FAILURE_ROLL"]

_F: Final = "Failure Detector"
#: CBRK_FLIGHTTERM's magic: flight termination disabled
CBRK_FLIGHTTERM_KEY: Final = 121212
#: vehicle_status.failure_detector_status bits (PX4's FAILURE_ROLL, FAILURE_PITCH)
FAILURE_ROLL: Final = 1
FAILURE_PITCH: Final = 2

FAILURE_DETECTOR_PARAMS = (
    ParamDef("FD_FAIL_R", "INT32", 60, min=0, max=180, unit="deg", group=_F,
             short="FailureDetector Max Roll",
             long="Maximum roll angle before the failure detector raises its roll flag. "
                  "0 disables the check."),
    ParamDef("FD_FAIL_P", "INT32", 60, min=0, max=180, unit="deg", group=_F,
             short="FailureDetector Max Pitch",
             long="Maximum pitch angle before the failure detector raises its pitch flag. "
                  "0 disables the check."),
    ParamDef("FD_FAIL_R_TTRI", "FLOAT", 0.3, min=0.02, max=5.0, unit="s", group=_F,
             decimals=2, short="Roll failure trigger time"),
    ParamDef("FD_FAIL_P_TTRI", "FLOAT", 0.3, min=0.02, max=5.0, unit="s", group=_F,
             decimals=2, short="Pitch failure trigger time"),
    ParamDef("CBRK_FLIGHTTERM", "INT32", CBRK_FLIGHTTERM_KEY, min=0, max=121212,
             group="Circuit Breaker", short="Circuit breaker for flight termination",
             long=f"Setting this to {CBRK_FLIGHTTERM_KEY} disables flight termination by the "
                  f"failure detector (PX4's default). WARNING: with it off, a detected "
                  f"failure stops the motors in flight."),
    ParamDef("COM_LKDOWN_TKO", "FLOAT", 3.0, min=-1.0, max=5.0, unit="s", group="Commander",
             decimals=1, short="Timeout for detecting a failure after takeoff",
             long="A failure detected this soon after takeoff locks the motors down."),
)


class FailureDetector:
    """The attitude check of one commander; :meth:`update` runs in its loop while armed."""

    def __init__(self, cmd: CommanderModule) -> None:
        self.cmd = cmd
        self.status = 0
        self._roll_since: int | None = None
        self._pitch_since: int | None = None
        self.lockdown = False
        self.terminated = False

    def reset(self) -> None:
        """At arming: a new flight."""
        self.status = 0
        self._roll_since = self._pitch_since = None
        self.lockdown = self.terminated = False

    def update(self, now: int, attitude_controlled: bool) -> None:
        if self.lockdown or self.terminated:
            return  # reacted: the flags that caused it stay (until the next arming)
        cmd, p = self.cmd, self.cmd.p
        att = cmd.data.attitude.node.last
        if not attitude_controlled or att is None:
            self.status = 0
            self._roll_since = self._pitch_since = None
            return
        w, x, y, z = att.q
        roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
        pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
        status = 0
        max_r, max_p = float(p["FD_FAIL_R"]), float(p["FD_FAIL_P"])
        if max_r > 0 and abs(roll) > math.radians(max_r):
            self._roll_since = now if self._roll_since is None else self._roll_since
            if now - self._roll_since >= p["FD_FAIL_R_TTRI"] * 1e6:
                status |= FAILURE_ROLL
        else:
            self._roll_since = None
        if max_p > 0 and abs(pitch) > math.radians(max_p):
            self._pitch_since = now if self._pitch_since is None else self._pitch_since
            if now - self._pitch_since >= p["FD_FAIL_P_TTRI"] * 1e6:
                status |= FAILURE_PITCH
        else:
            self._pitch_since = None
        self.status = status
        if not status:
            return
        tko = cmd.takeoff_time_us
        if tko and now - tko < p["COM_LKDOWN_TKO"] * 1e6:
            self.lockdown = True
            cmd.emergency("Critical failure detected: lockdown")
        elif int(p["CBRK_FLIGHTTERM"]) != CBRK_FLIGHTTERM_KEY:
            self.terminated = True
            cmd.emergency("Critical failure detected: terminate flight")
