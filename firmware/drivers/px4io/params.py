"""Parameters the px4io driver reads, with PX4's names and meanings.

PWM_MIN/PWM_MAX/PWM_DISARMED and the per-output PWM_MAIN_FAILn/PWM_MAIN_DISn are the names PX4
used for the main (IO) outputs from 2015-2017 on; in 2014 the same numbers came from the
startup script (``pwm min/max/disarmed``) and this tree's rcS has no such step, so the driver
takes them from parameters.

Read when declared elsewhere (a parameter has one owner): CBRK_IO_SAFETY (the commander's
circuit breaker; 22027 makes the driver force the IO's safety off at start and after an IO
reboot, as E14 did).

The RC calibration (RCn_MIN/TRIM/MAX/REV/DZ, RC_MAP_*) belongs to the sensors module; the
driver reads it when declared and otherwise uses the E14 defaults (:data:`RC_DEFAULTS`).
"""

from __future__ import annotations

from firmware.platform.params import ParamDef

__all__ = ["CBRK_IO_SAFETY_KEY", "PARAMS", "RC_DEFAULTS", "rc_param_defaults"]

CBRK_IO_SAFETY_KEY = 22027
_GROUP = "PWM Outputs"


def _per_output(prefix: str, short: str, long: str) -> tuple[ParamDef, ...]:
    return tuple(ParamDef(f"{prefix}{i}", "INT32", -1, min=-1, max=2150, unit="us",
                          group=_GROUP, short=f"{short} of main output {i}", long=long)
                 for i in range(1, 9))


PARAMS: tuple[ParamDef, ...] = (
    ParamDef("PWM_MIN", "INT32", 1000, min=800, max=1400, unit="us", group=_GROUP,
             short="PWM minimum value",
             long="Pulse width of an armed output at its lowest control value (IO page 106; "
                  "the IO clamps to 900..1300 us)."),
    ParamDef("PWM_MAX", "INT32", 2000, min=1600, max=2200, unit="us", group=_GROUP,
             short="PWM maximum value",
             long="Pulse width at the highest control value (IO page 107; clamped 1700..2100)."),
    ParamDef("PWM_DISARMED", "INT32", 900, min=0, max=2200, unit="us", group=_GROUP,
             short="PWM output value when disarmed",
             long="Pulse width while disarmed (IO page 108). 0 sends no pulses; a non-zero "
                  "value makes the IO drive the outputs whenever the FMU is alive."),
    ParamDef("PWM_RATE", "INT32", 400, min=50, max=400, unit="Hz", group=_GROUP,
             short="PWM rate of the outputs in PWM_OUT",
             long="Written as the IO's alternate rate; the other outputs run at 50 Hz."),
    ParamDef("PWM_OUT", "INT32", 1234, min=0, max=12345678, group=_GROUP,
             short="Outputs running at PWM_RATE",
             long="Output numbers as digits, as the startup script's PWM_OUT variable "
                  "(1234 = outputs 1 to 4). Each IO timer group ({1,2}, {3,4}, {5..8}) must "
                  "be entirely in or out, else the IO raises PWM_ERROR. 0 = all at 50 Hz."),
    ParamDef("IO_OVERRIDE_EN", "INT32", 0, min=0, max=1, group=_GROUP,
             short="Allow the IO's RC manual override on rotary-wing vehicles",
             long="The 2014 IO firmware hands the outputs to the pilot's sticks (through its "
                  "own mixer) when the FMU stops talking or the override switch is set, and "
                  "the FMU allows that for fixed wing only. 1 allows it on multicopters too "
                  "(the emulator's switch for failsafe and override testing) and sets "
                  "OVERRIDE_IMMEDIATE, so the IO gives the pilot the outputs as soon as it "
                  "loses the FMU.",
             values={0: "fixed wing only (E14)", 1: "all vehicles"}),
    *_per_output("PWM_MAIN_DIS", "Disarmed PWM",
                 "-1 uses PWM_DISARMED; 0 sends no pulses on this output while disarmed."),
    *_per_output("PWM_MAIN_FAIL", "Failsafe PWM",
                 "-1 leaves the IO's mixer-derived failsafe value. Setting any output makes "
                 "the IO use the written values for all outputs (FAILSAFE_CUSTOM); 0 = no "
                 "pulses in failsafe."),
)

#: E14 defaults of the RC calibration parameters the sensors module owns (io-and-rc.md §9.2).
RC_DEFAULTS: dict[str, float | int] = {
    "RC_MAP_ROLL": 1, "RC_MAP_PITCH": 2, "RC_MAP_THROTTLE": 3, "RC_MAP_YAW": 4,
    "RC_MAP_FLAPS": 0, "RC_MAP_MODE_SW": 0,
}


def rc_param_defaults(channel: int) -> dict[str, float]:
    """Defaults of RC<channel>_MIN/TRIM/MAX/REV/DZ (1-based channel)."""
    return {f"RC{channel}_MIN": 1000.0, f"RC{channel}_TRIM": 1500.0,
            f"RC{channel}_MAX": 2000.0, f"RC{channel}_REV": 1.0,
            f"RC{channel}_DZ": 10.0 if channel <= 8 else 0.0}
