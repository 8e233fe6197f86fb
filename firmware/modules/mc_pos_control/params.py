"""Parameters of mc_pos_control (PX4 names, units and defaults; the F450 airframe tunes some).

MPC_MAN_TILT_MAX, MPC_MAN_Y_MAX, MPC_MANTHR_MIN and MPC_THR_CURVE are declared by
mc_att_control (stabilized mode uses them too) and read here through the parameter table.
"""

from __future__ import annotations

from typing import Final

from firmware.platform.params import ParamDef

__all__ = ["PARAMS"]

_G: Final = "Multicopter Position Control"
_H: Final = "Hover Thrust Estimator"


def _p(name: str, default: float, lo: float, hi: float, short: str, unit: str = "",
       group: str = _G, decimals: int = 2) -> ParamDef:
    return ParamDef(name, "FLOAT", default, min=lo, max=hi, unit=unit, group=group, short=short,
                    decimals=decimals)


PARAMS: Final[tuple[ParamDef, ...]] = (
    _p("MPC_XY_P", 0.95, 0.0, 2.0, "Horizontal position P gain", "1/s"),
    _p("MPC_Z_P", 1.0, 0.0, 1.5, "Vertical position P gain", "1/s"),
    _p("MPC_XY_VEL_P_ACC", 1.8, 1.2, 5.0, "Horizontal velocity P gain", "1/s"),
    _p("MPC_XY_VEL_I_ACC", 0.4, 0.0, 60.0, "Horizontal velocity I gain", "1/s^2"),
    _p("MPC_XY_VEL_D_ACC", 0.2, 0.0, 2.0, "Horizontal velocity D gain"),
    _p("MPC_Z_VEL_P_ACC", 4.0, 2.0, 15.0, "Vertical velocity P gain", "1/s"),
    _p("MPC_Z_VEL_I_ACC", 2.0, 0.2, 3.0, "Vertical velocity I gain", "1/s^2"),
    _p("MPC_Z_VEL_D_ACC", 0.0, 0.0, 2.0, "Vertical velocity D gain"),
    _p("MPC_XY_VEL_MAX", 12.0, 0.0, 20.0, "Maximum horizontal velocity", "m/s", decimals=1),
    _p("MPC_XY_CRUISE", 5.0, 3.0, 20.0, "Default horizontal cruise speed in auto", "m/s",
       decimals=1),
    _p("MPC_VEL_MANUAL", 10.0, 3.0, 20.0, "Maximum horizontal stick velocity", "m/s",
       decimals=1),
    _p("MPC_Z_VEL_MAX_UP", 3.0, 0.5, 8.0, "Maximum climb rate", "m/s", decimals=1),
    _p("MPC_Z_VEL_MAX_DN", 1.5, 0.5, 4.0, "Maximum descent rate", "m/s", decimals=1),
    _p("MPC_ACC_HOR", 3.0, 2.0, 15.0, "Horizontal acceleration in auto", "m/s^2"),
    _p("MPC_ACC_HOR_MAX", 5.0, 2.0, 15.0, "Maximum horizontal stick acceleration", "m/s^2"),
    _p("MPC_ACC_UP_MAX", 4.0, 1.0, 15.0, "Maximum upward acceleration", "m/s^2"),
    _p("MPC_ACC_DOWN_MAX", 3.0, 1.0, 15.0, "Maximum downward acceleration", "m/s^2"),
    _p("MPC_JERK_AUTO", 4.0, 1.0, 80.0, "Jerk limit in auto", "m/s^3", decimals=1),
    _p("MPC_TILTMAX_AIR", 45.0, 20.0, 89.0, "Maximum tilt in air", "deg", decimals=1),
    _p("MPC_THR_MIN", 0.12, 0.05, 1.0, "Minimum collective thrust in auto/position"),
    _p("MPC_THR_MAX", 1.0, 0.0, 1.0, "Maximum collective thrust"),
    _p("MPC_THR_HOVER", 0.5, 0.1, 0.8, "Hover thrust (initial value of the estimator)"),
    _p("MPC_TKO_SPEED", 1.5, 1.0, 5.0, "Takeoff climb rate", "m/s"),
    _p("MPC_TKO_RAMP_T", 3.0, 0.0, 5.0, "Takeoff thrust ramp time", "s"),
    _p("MPC_LAND_SPEED", 0.7, 0.6, 4.0, "Landing descent rate", "m/s"),
    _p("MPC_LAND_ALT1", 10.0, 0.0, 122.0, "Height to start slowing down for landing", "m",
       decimals=1),
    _p("MPC_LAND_ALT2", 5.0, 0.0, 122.0, "Height below which the land speed applies", "m",
       decimals=1),
    _p("MPC_HOLD_DZ", 0.1, 0.0, 1.0, "Stick dead zone of the hold modes"),
    _p("MPC_HOLD_MAX_XY", 0.8, 0.0, 3.0, "Speed below which the position is locked", "m/s"),
    _p("MPC_HOLD_MAX_Z", 0.6, 0.0, 3.0, "Climb rate below which the altitude is locked",
       "m/s"),
    _p("HTE_HT_NOISE", 0.0036, 0.0001, 1.0, "Hover thrust process noise", "normalized_thrust/s",
       _H, 4),
    _p("HTE_ACC_GATE", 3.0, 1.0, 10.0, "Gate of the acceleration innovation", "SD", _H, 1),
    _p("HTE_HT_ERR_INIT", 0.1, 0.0, 1.0, "Initial hover thrust uncertainty (1 SD)",
       "normalized_thrust", _H, 3),
)
