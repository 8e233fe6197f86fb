"""Fixed-wing attitude control parameters (PX4's FW_* names and defaults, v1.12 era), and the
airspeed and attitude limits both fixed-wing modules read.

The shared ones (``FW_AIRSPD_*``, ``FW_ARSP_MODE``, ``FW_R_LIM``, ``FW_P_LIM_*``,
``FW_MAN_R_MAX``) are declared once here and imported by fw_pos_control_l1, so the two
modules hand the parameter table the same declaration objects (a name declared twice must have
the same metadata).
"""

from __future__ import annotations

from typing import Final

from firmware.platform.params import ParamDef

__all__ = ["ATT_PARAMS", "SHARED_PARAMS"]

_G: Final = "FW Attitude Control"
_GA: Final = "FW TECS"
_GL: Final = "FW L1 Control"


def _p(name: str, default: float, lo: float, hi: float, short: str, unit: str = "",
       group: str = _G, decimals: int = 3) -> ParamDef:
    return ParamDef(name, "FLOAT", default, min=lo, max=hi, unit=unit, group=group, short=short,
                    decimals=decimals)


#: read by both fixed-wing modules
SHARED_PARAMS: Final[tuple[ParamDef, ...]] = (
    _p("FW_AIRSPD_MIN", 10.0, 0.5, 40.0, "Minimum airspeed", "m/s", _GA, 1),
    _p("FW_AIRSPD_TRIM", 15.0, 0.5, 40.0, "Cruise (trim) airspeed", "m/s", _GA, 1),
    _p("FW_AIRSPD_MAX", 20.0, 0.5, 40.0, "Maximum airspeed", "m/s", _GA, 1),
    ParamDef("FW_ARSP_MODE", "INT32", 0, min=0, max=1, group=_G,
             short="Airspeed mode",
             values={0: "Use airspeed in the controllers",
                     1: "Do not use airspeed (FW_AIRSPD_TRIM assumed)"}),
    _p("FW_R_LIM", 50.0, 35.0, 65.0, "Maximum roll angle", "deg", _GL, 1),
    _p("FW_P_LIM_MIN", -45.0, -60.0, 0.0, "Minimum pitch angle", "deg", _GL, 1),
    _p("FW_P_LIM_MAX", 45.0, 0.0, 60.0, "Maximum pitch angle", "deg", _GL, 1),
    _p("FW_MAN_R_MAX", 45.0, 0.0, 90.0, "Maximum manual roll angle", "deg", decimals=1),
)

#: fw_att_control's own
ATT_PARAMS: Final[tuple[ParamDef, ...]] = (
    _p("FW_R_TC", 0.4, 0.4, 1.0, "Attitude roll time constant", "s", decimals=2),
    _p("FW_P_TC", 0.4, 0.2, 1.0, "Attitude pitch time constant", "s", decimals=2),
    _p("FW_RR_P", 0.05, 0.005, 1.0, "Roll rate proportional gain", "%/rad/s"),
    _p("FW_RR_I", 0.1, 0.005, 0.5, "Roll rate integrator gain", "%/rad"),
    _p("FW_RR_IMAX", 0.2, 0.0, 1.0, "Roll rate integrator limit"),
    _p("FW_RR_FF", 0.5, 0.0, 10.0, "Roll rate feed-forward", "%/rad/s"),
    _p("FW_R_RMAX", 70.0, 0.0, 90.0, "Maximum roll rate setpoint", "deg/s", decimals=1),
    _p("FW_PR_P", 0.08, 0.005, 1.0, "Pitch rate proportional gain", "%/rad/s"),
    _p("FW_PR_I", 0.1, 0.005, 0.5, "Pitch rate integrator gain", "%/rad"),
    _p("FW_PR_IMAX", 0.4, 0.0, 1.0, "Pitch rate integrator limit"),
    _p("FW_PR_FF", 0.5, 0.0, 10.0, "Pitch rate feed-forward", "%/rad/s"),
    _p("FW_P_RMAX_POS", 60.0, 0.0, 90.0, "Maximum positive (nose up) pitch rate", "deg/s",
       decimals=1),
    _p("FW_P_RMAX_NEG", 60.0, 0.0, 90.0, "Maximum negative (nose down) pitch rate", "deg/s",
       decimals=1),
    _p("FW_YR_P", 0.05, 0.005, 1.0, "Yaw rate proportional gain", "%/rad/s"),
    _p("FW_YR_I", 0.1, 0.0, 50.0, "Yaw rate integrator gain", "%/rad"),
    _p("FW_YR_IMAX", 0.2, 0.0, 1.0, "Yaw rate integrator limit"),
    _p("FW_YR_FF", 0.3, 0.0, 10.0, "Yaw rate feed-forward", "%/rad/s"),
    _p("FW_Y_RMAX", 50.0, 0.0, 90.0, "Maximum yaw rate setpoint", "deg/s", decimals=1),
    _p("FW_RSP_OFF", 0.0, -90.0, 90.0, "Roll setpoint offset (level flight trim)", "deg",
       decimals=1),
    _p("FW_PSP_OFF", 0.0, -90.0, 90.0, "Pitch setpoint offset (level flight trim)", "deg",
       decimals=1),
    _p("FW_MAN_P_MAX", 45.0, 0.0, 90.0, "Maximum manual pitch angle", "deg", decimals=1),
    _p("FW_ACRO_X_MAX", 90.0, 45.0, 720.0, "Acro body x (roll) rate at full stick", "deg/s",
       decimals=0),
    _p("FW_ACRO_Y_MAX", 90.0, 45.0, 720.0, "Acro body y (pitch) rate at full stick", "deg/s",
       decimals=0),
    _p("FW_ACRO_Z_MAX", 45.0, 10.0, 180.0, "Acro body z (yaw) rate at full stick", "deg/s",
       decimals=0),
    _p("TRIM_ROLL", 0.0, -0.25, 0.25, "Roll trim (added to the aileron control)"),
    _p("TRIM_PITCH", 0.0, -0.25, 0.25, "Pitch trim (added to the elevator control)"),
    _p("TRIM_YAW", 0.0, -0.25, 0.25, "Yaw trim (added to the rudder control)"),
    _p("FW_MAN_R_SC", 1.0, 0.0, 1.0, "Manual roll scale (manual mode)", decimals=2),
    _p("FW_MAN_P_SC", 1.0, 0.0, 1.0, "Manual pitch scale (manual mode)", decimals=2),
    _p("FW_MAN_Y_SC", 1.0, 0.0, 1.0, "Manual yaw scale (manual and stabilized modes)",
       decimals=2),
)
