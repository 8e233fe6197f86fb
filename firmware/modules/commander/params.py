"""Commander parameters: PX4's names, defaults and value meanings (commander_params, failsafe)."""

from __future__ import annotations

from typing import Final

from firmware.platform.params import ParamDef

__all__ = ["CBRK_IO_SAFETY_KEY", "FORCE_ARM_MAGIC", "PARAMS"]

#: CBRK_IO_SAFETY value that disables the safety switch check
CBRK_IO_SAFETY_KEY: Final = 22027
#: vehicle_command param2 that forces arming/disarming past the checks
FORCE_ARM_MAGIC: Final = 21196

_C: Final = "Commander"
_S: Final = "Failsafe"
_ACT: Final = {0: "Disabled", 1: "Hold mode", 2: "Return mode", 3: "Land mode", 5: "Terminate",
        6: "Disarm"}
_FLTMODE: Final = {-1: "Unassigned", 0: "Manual", 1: "Altitude", 2: "Position", 3: "Mission",
            4: "Hold", 5: "Return", 6: "Acro", 7: "Offboard", 8: "Stabilized", 10: "Takeoff",
            11: "Land", 13: "Precision Land"}


def _fltmode(n: int) -> ParamDef:
    return ParamDef(f"COM_FLTMODE{n}", "INT32", -1, min=-1, max=13, group=_C,
                    short=f"Mode slot {n}", values=_FLTMODE,
                    long="Flight mode selected when RC_MAP_FLTMODE is in this slot.")


PARAMS: Final[tuple[ParamDef, ...]] = (
    ParamDef("COM_ARM_WO_GPS", "INT32", 1, min=0, max=1, group=_C,
             short="Allow arming without GPS", values={0: "Require GPS", 1: "Allow"},
             long="With 0 a 3D GPS fix is required to arm in every mode; modes that need a "
                  "position always need one."),
    ParamDef("COM_RC_IN_MODE", "INT32", 3, min=0, max=4, group=_C,
             short="RC control input mode",
             values={0: "RC only", 1: "MAVLink only", 2: "RC and MAVLink with fallback",
                     3: "RC or MAVLink keep first", 4: "Stick input disabled"},
             long="Which manual-control source flies (rc_update's selector): RC, a MAVLink "
                  "joystick (MANUAL_CONTROL), either with fallback, or the first one seen. "
                  "0 and 2 require stick input to arm in any mode; 4 never checks it (no RC "
                  "loss failsafe either)."),
    ParamDef("COM_RC_LOSS_T", "FLOAT", 0.5, min=0.0, max=35.0, unit="s", group=_C, decimals=1,
             short="Manual control loss timeout"),
    ParamDef("COM_DL_LOSS_T", "INT32", 10, min=5, max=300, unit="s", group=_C,
             short="Datalink loss time threshold"),
    ParamDef("COM_RC_ARM_HYST", "INT32", 1000, min=100, max=1500, unit="ms", group=_C,
             short="RC input arm/disarm command duration"),
    ParamDef("MAN_ARM_GESTURE", "INT32", 1, min=0, max=1, group=_C,
             short="Enable arm/disarm stick gesture",
             long="Throttle low and yaw right arms, throttle low and yaw left disarms (only "
                  "when no arm switch is mapped)."),
    ParamDef("COM_DISARM_LAND", "FLOAT", 2.0, min=-1.0, max=20.0, unit="s", group=_C,
             decimals=1, short="Time-out for auto disarm after landing", long="-1 disables."),
    ParamDef("COM_DISARM_PRFLT", "FLOAT", 10.0, min=-1.0, max=20.0, unit="s", group=_C,
             decimals=1, short="Time-out for auto disarm if not taking off",
             long="-1 disables."),
    ParamDef("COM_PREARM_MODE", "INT32", 0, min=0, max=2, group=_C,
             short="Condition to enter prearmed mode",
             values={0: "Disabled", 1: "Safety button", 2: "Always"}),
    ParamDef("COM_ARM_IMU_ACC", "FLOAT", 0.7, min=0.1, max=1.0, unit="m/s^2", group=_C,
             decimals=2, short="Maximum accelerometer inconsistency between IMU units"),
    ParamDef("COM_ARM_IMU_GYR", "FLOAT", 0.25, min=0.02, max=0.3, unit="rad/s", group=_C,
             decimals=3, short="Maximum rate gyro inconsistency between IMU units"),
    ParamDef("COM_POS_FS_EPH", "FLOAT", 5.0, min=-1.0, max=400.0, unit="m", group=_C,
             decimals=1, short="Horizontal position error threshold",
             long="A position estimate less accurate than this is not valid for position "
                  "modes."),
    ParamDef("COM_LOW_BAT_ACT", "INT32", 0, min=0, max=3, group=_C,
             short="Battery failsafe mode",
             values={0: "Warning", 1: "Return mode", 2: "Land mode",
                     3: "Return at critical level, land at emergency level"}),
    ParamDef("COM_FAIL_ACT_T", "FLOAT", 5.0, min=0.0, max=25.0, unit="s", group=_S,
             decimals=1, short="Delay between failsafe condition and failsafe reaction",
             long="The vehicle holds this long before a Return/Land reaction, so the pilot can "
                  "notice; 0 reacts at once."),
    ParamDef("COM_RCL_EXCEPT", "INT32", 0, min=0, max=7, group=_S,
             short="RC loss exceptions",
             long="Bitmask of modes in which RC loss is ignored: 0 Mission, 1 Hold, "
                  "2 Offboard."),
    ParamDef("NAV_RCL_ACT", "INT32", 2, min=0, max=6, group=_S,
             short="Set RC loss failsafe mode", values=_ACT),
    ParamDef("NAV_DLL_ACT", "INT32", 0, min=0, max=6, group=_S,
             short="Set data link loss failsafe mode", values=_ACT),
    ParamDef("COM_OF_LOSS_T", "FLOAT", 1.0, min=0.0, max=60.0, unit="s", group=_C,
             decimals=2, short="Time-out for offboard control loss",
             long="Offboard mode can be entered, and stays, only while setpoints "
                  "(offboard_control_mode) arrived within this time; after it the offboard "
                  "loss failsafe (COM_OBL_RC_ACT) acts. PX4 1.14's default."),
    ParamDef("COM_OBL_RC_ACT", "INT32", 0, min=0, max=7, group=_S,
             short="Set offboard loss failsafe mode",
             values={0: "Position mode", 1: "Altitude mode", 2: "Stabilized", 3: "Return mode",
                     4: "Land mode", 5: "Hold mode", 6: "Terminate", 7: "Disarm"},
             long="What the vehicle does when offboard setpoints stop for COM_OF_LOSS_T. As "
                  "in PX4 1.14 (which dropped COM_OBL_ACT), one parameter serves with and "
                  "without RC: a manual mode that cannot run without manual control falls "
                  "back to Return (then Land, Descend)."),
    ParamDef("COM_MOT_TEST_EN", "INT32", 1, min=0, max=1, group=_C,
             short="Enable Motor Testing", values={0: "Disabled", 1: "Enabled"},
             long="If set, enables the motor test interface via MAVLink (DO_MOTOR_TEST and "
                  "ACTUATOR_TEST), that allows spinning the motors for testing purposes."),
    ParamDef("CBRK_IO_SAFETY", "INT32", 0, min=0, max=22027, group="Circuit Breaker",
             short="Circuit breaker for IO safety",
             long="Set to 22027 to disable the safety switch check."),
) + tuple(_fltmode(n) for n in range(1, 7))
