"""fw_pos_control_l1's parameters: PX4's names and defaults (v1.12 era) for L1 guidance, TECS,
takeoff (runway: RWTO_*, hand/catapult launch: LAUN_*) and landing (FW_LND_*)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Final

from firmware.lib.tecs import TecsParams
from firmware.modules.fw_att_control.params import SHARED_PARAMS
from firmware.platform.params import ParamDef

__all__ = ["PARAMS", "apply_tecs_params"]

_GL: Final = "FW L1 Control"
_GT: Final = "FW TECS"
_GLD: Final = "FW Landing"
_GR: Final = "Runway Takeoff"
_GC: Final = "FW Launch detection"


def _p(name: str, default: float, lo: float, hi: float, short: str, unit: str, group: str,
       decimals: int = 2) -> ParamDef:
    return ParamDef(name, "FLOAT", default, min=lo, max=hi, unit=unit, group=group, short=short,
                    decimals=decimals)


def _i(name: str, default: int, lo: int, hi: int, short: str, group: str,
       values: dict[int, str] | None = None) -> ParamDef:
    return ParamDef(name, "INT32", default, min=lo, max=hi, group=group, short=short,
                    values=values or {})


_OWN: Final[tuple[ParamDef, ...]] = (
    _p("FW_L1_PERIOD", 20.0, 7.0, 50.0, "L1 period", "s", _GL, 1),
    _p("FW_L1_DAMPING", 0.75, 0.6, 0.9, "L1 damping", "", _GL),
    _p("FW_LOITER_R", 50.0, 1.0, 1000.0, "Loiter radius without one from the setpoint", "m",
       _GL, 1),
    _p("FW_THR_CRUISE", 0.6, 0.0, 1.0, "Cruise throttle", "norm", _GL),
    _p("FW_THR_MIN", 0.0, 0.0, 1.0, "Throttle limit min", "norm", _GL),
    _p("FW_THR_MAX", 1.0, 0.0, 1.0, "Throttle limit max", "norm", _GL),
    _p("FW_THR_IDLE", 0.15, 0.0, 0.4, "Idle throttle (on the ground, before launch)", "norm",
       _GL),
    _p("FW_THR_LND_MAX", 1.0, 0.0, 1.0, "Throttle limit below FW_LND_TLALT", "norm", _GL),
    _p("FW_CLMBOUT_DIFF", 10.0, 0.0, 150.0,
       "Takeoff climb-out: full throttle, minimum pitch while the altitude error is larger",
       "m", _GL, 1),
    _p("FW_TKO_PITCH_MIN", 10.0, 0.0, 45.0, "Minimum pitch during takeoff climb-out", "deg",
       _GL, 1),
    _p("FW_T_CLMB_MAX", 5.0, 1.0, 15.0, "Maximum climb rate", "m/s", _GT, 1),
    _p("FW_T_SINK_MIN", 2.0, 1.0, 5.0, "Minimum sink rate (throttle at FW_THR_MIN)", "m/s",
       _GT, 1),
    _p("FW_T_SINK_MAX", 5.0, 2.0, 15.0, "Maximum sink rate", "m/s", _GT, 1),
    _p("FW_T_TIME_CONST", 5.0, 1.0, 10.0, "TECS time constant (pitch loop)", "s", _GT, 1),
    _p("FW_T_THRO_CONST", 8.0, 1.0, 10.0, "TECS throttle time constant", "s", _GT, 1),
    _p("FW_T_ALT_TC", 5.0, 2.0, 10.0, "Altitude error time constant", "s", _GT, 1),
    _p("FW_T_TAS_TC", 2.0, 2.0, 10.0, "True airspeed error time constant", "s", _GT, 1),
    _p("FW_T_HRATE_FF", 0.3, 0.0, 1.0, "Height rate feed-forward", "", _GT),
    _p("FW_T_THR_DAMP", 0.1, 0.0, 2.0, "Throttle damping factor", "", _GT),
    _p("FW_T_PTCH_DAMP", 0.1, 0.0, 2.0, "Pitch damping factor", "", _GT),
    _p("FW_T_INTEG_GAIN", 0.1, 0.0, 2.0, "Integrator gain", "", _GT),
    _p("FW_T_VERT_ACC", 7.0, 1.0, 10.0, "Maximum vertical acceleration", "m/s^2", _GT, 1),
    _p("FW_T_SPDWEIGHT", 1.0, 0.0, 2.0, "Speed <-> altitude priority", "", _GT, 1),
    _p("FW_T_RLL2THR", 15.0, 0.0, 20.0, "Roll -> throttle feed-forward", "", _GT, 1),
    _p("FW_T_SPD_OMEGA", 2.0, 1.0, 10.0, "Airspeed complementary filter frequency", "rad/s",
       _GT, 1),
    _p("FW_LND_ANG", 5.0, 1.0, 15.0, "Landing slope angle", "deg", _GLD, 1),
    _p("FW_LND_FLALT", 3.0, 0.0, 25.0, "Landing flare altitude (above the touchdown point)",
       "m", _GLD, 1),
    _p("FW_LND_TLALT", -1.0, -1.0, 30.0,
       "Landing throttle limit altitude (FW_THR_LND_MAX below it; -1: FW_LND_FLALT)", "m",
       _GLD, 1),
    _p("FW_LND_HHDIST", 15.0, 0.0, 30.0, "Landing: hold the line from this distance on", "m",
       _GLD, 1),
    _p("FW_LND_FL_PMIN", 2.5, 0.0, 15.0, "Flare minimum pitch", "deg", _GLD, 1),
    _p("FW_LND_FL_PMAX", 15.0, 0.0, 45.0, "Flare maximum pitch", "deg", _GLD, 1),
    _p("FW_LND_AIRSPD_SC", 1.3, 1.0, 1.5, "Approach airspeed: FW_AIRSPD_MIN times this", "",
       _GLD),
    _i("RWTO_TKOFF", 0, 0, 1, "Runway takeoff with landing gear", _GR,
       {0: "Hand or catapult launch", 1: "Runway takeoff"}),
    _i("RWTO_HDG", 0, 0, 1, "Runway heading", _GR,
       {0: "Airframe heading at the start", 1: "Heading to the takeoff waypoint"}),
    _p("RWTO_NAV_ALT", 5.0, 0.0, 100.0, "Altitude (above the runway) where L1 takes over",
       "m", _GR, 1),
    _p("RWTO_MAX_THR", 1.0, 0.0, 1.0, "Maximum throttle on the runway", "norm", _GR),
    _p("RWTO_PSP", 0.0, -10.0, 20.0, "Pitch setpoint on the runway", "deg", _GR, 1),
    _p("RWTO_MAX_PITCH", 20.0, 0.0, 60.0, "Maximum pitch during the runway takeoff", "deg",
       _GR, 1),
    _p("RWTO_MAX_ROLL", 25.0, 0.0, 60.0, "Maximum roll below RWTO_NAV_ALT", "deg", _GR, 1),
    _p("RWTO_AIRSPD_SCL", 1.3, 0.0, 2.0, "Rotate at FW_AIRSPD_MIN times this", "", _GR),
    _p("RWTO_RAMP_TIME", 2.0, 0.1, 15.0, "Throttle ramp time on the runway", "s", _GR, 1),
    _i("LAUN_ALL_ON", 0, 0, 1, "Launch detection", _GC, {0: "Off", 1: "On"}),
    _p("LAUN_CAT_A", 30.0, 0.0, 200.0, "Catapult/throw acceleration threshold", "m/s^2", _GC,
       1),
    _p("LAUN_CAT_T", 0.05, 0.0, 5.0, "Catapult/throw time threshold", "s", _GC, 3),
    _p("LAUN_CAT_MDEL", 0.0, 0.0, 10.0, "Motor delay after the launch", "s", _GC, 1),
)

PARAMS: Final[tuple[ParamDef, ...]] = SHARED_PARAMS + _OWN


def apply_tecs_params(v: Mapping[str, Any], tp: TecsParams) -> None:
    """Hand TECS its FW_T_* and FW_AIRSPD_* values (the parameter names stay here)."""
    tp.time_const_s = v["FW_T_TIME_CONST"]
    tp.throttle_time_const_s = v["FW_T_THRO_CONST"]
    tp.alt_error_tc_s = v["FW_T_ALT_TC"]
    tp.tas_error_tc_s = v["FW_T_TAS_TC"]
    tp.hgt_rate_ff = v["FW_T_HRATE_FF"]
    tp.climb_max_m_s = v["FW_T_CLMB_MAX"]
    tp.sink_min_m_s = v["FW_T_SINK_MIN"]
    tp.sink_max_m_s = v["FW_T_SINK_MAX"]
    tp.throttle_damp = v["FW_T_THR_DAMP"]
    tp.pitch_damp = v["FW_T_PTCH_DAMP"]
    tp.integ_gain = v["FW_T_INTEG_GAIN"]
    tp.vert_accel_max_m_s2 = v["FW_T_VERT_ACC"]
    tp.speed_weight = v["FW_T_SPDWEIGHT"]
    tp.roll_to_throttle = v["FW_T_RLL2THR"]
    tp.spd_omega = v["FW_T_SPD_OMEGA"]
    tp.airspeed_min_m_s = v["FW_AIRSPD_MIN"]
    tp.airspeed_trim_m_s = v["FW_AIRSPD_TRIM"]
    tp.airspeed_max_m_s = v["FW_AIRSPD_MAX"]
