"""RC calibration and mapping parameters (PX4's rc_update names, ranges and defaults).

The stick mapping defaults are the 2014 firmware's (roll 1, pitch 2, throttle 3, yaw 4), the
ones the px4io driver also assumes for the IO's manual override. As in recent PX4, RC_CHAN_CNT
stays 0 until the radio is calibrated and manual control is only published when it is > 0, so
an uncalibrated radio never flies the vehicle: the calibration (or the airframe) sets it.
"""

from __future__ import annotations

from typing import Final

from firmware.platform.params import ParamDef

__all__ = ["MAX_CHANNELS", "PARAMS", "SWITCH_MAPS"]

MAX_CHANNELS: Final = 18
_G: Final = "Radio Calibration"
_GS: Final = "Radio Switches"


def _channel_params(n: int) -> tuple[ParamDef, ...]:
    return (
        ParamDef(f"RC{n}_MIN", "FLOAT", 1000.0, min=800.0, max=1500.0, unit="us", group=_G,
                 short=f"RC channel {n} minimum", decimals=1),
        ParamDef(f"RC{n}_TRIM", "FLOAT", 1500.0, min=800.0, max=2200.0, unit="us", group=_G,
                 short=f"RC channel {n} trim",
                 long="Centre value. A throttle channel calibrated with TRIM = MIN is recentred "
                      "to (MIN + MAX) / 2 so throttle spans -1..1.", decimals=1),
        ParamDef(f"RC{n}_MAX", "FLOAT", 2000.0, min=1500.0, max=2200.0, unit="us", group=_G,
                 short=f"RC channel {n} maximum", decimals=1),
        ParamDef(f"RC{n}_REV", "INT32", 1, min=-1, max=1, group=_G,
                 short=f"RC channel {n} reverse", values={-1: "Reverse", 1: "Normal"}),
        ParamDef(f"RC{n}_DZ", "FLOAT", 10.0 if n <= 8 else 0.0, min=0.0, max=100.0, unit="us",
                 group=_G, short=f"RC channel {n} dead zone", decimals=1),
    )


def _map(name: str, short: str, group: str = _GS, default: int = 0) -> ParamDef:
    return ParamDef(name, "INT32", default, min=0, max=MAX_CHANNELS, group=group, short=short,
                    long="RC channel (1-based) carrying this function; 0 = unassigned.")


def _th(name: str, short: str, default: float = 0.75) -> ParamDef:
    return ParamDef(name, "FLOAT", default, min=-1.0, max=1.0, group=_GS, short=short,
                    long="Switch position in 0..1 above which the switch is ON; a negative "
                         "value inverts the comparison (ON below its magnitude).", decimals=2)


#: switch name in manual_control_switches -> (map parameter, threshold parameter)
SWITCH_MAPS: Final[dict[str, tuple[str, str]]] = {
    "return_switch": ("RC_MAP_RETURN_SW", "RC_RETURN_TH"),
    "loiter_switch": ("RC_MAP_LOITER_SW", "RC_LOITER_TH"),
    "offboard_switch": ("RC_MAP_OFFB_SW", "RC_OFFB_TH"),
    "kill_switch": ("RC_MAP_KILL_SW", "RC_KILLSWITCH_TH"),
    "arm_switch": ("RC_MAP_ARM_SW", "RC_ARMSWITCH_TH"),
    "gear_switch": ("RC_MAP_GEAR_SW", "RC_GEAR_TH"),
}

PARAMS: Final[tuple[ParamDef, ...]] = tuple(
    p for n in range(1, MAX_CHANNELS + 1) for p in _channel_params(n)
) + (
    _map("RC_MAP_ROLL", "Roll control channel", _G, 1),
    _map("RC_MAP_PITCH", "Pitch control channel", _G, 2),
    _map("RC_MAP_YAW", "Yaw control channel", _G, 4),
    _map("RC_MAP_THROTTLE", "Throttle control channel", _G, 3),
    _map("RC_MAP_FLTMODE", "Single channel flight mode selection"),
    _map("RC_MAP_RETURN_SW", "Return switch channel"),
    _map("RC_MAP_LOITER_SW", "Loiter switch channel"),
    _map("RC_MAP_OFFB_SW", "Offboard switch channel"),
    _map("RC_MAP_KILL_SW", "Emergency kill switch channel"),
    _map("RC_MAP_ARM_SW", "Arm switch channel"),
    _map("RC_MAP_GEAR_SW", "Landing gear switch channel"),
    _map("RC_MAP_FLAPS", "Flaps channel"),
    _map("RC_MAP_AUX1", "AUX1 passthrough channel"),
    _map("RC_MAP_AUX2", "AUX2 passthrough channel"),
    _map("RC_MAP_AUX3", "AUX3 passthrough channel"),
    _map("RC_MAP_AUX4", "AUX4 passthrough channel"),
    _map("RC_MAP_AUX5", "AUX5 passthrough channel"),
    _map("RC_MAP_AUX6", "AUX6 passthrough channel"),
    _map("RC_MAP_FAILSAFE", "Failsafe channel mapping",),
    ParamDef("RC_FAILS_THR", "INT32", 0, min=0, max=2200, unit="us", group=_G,
             short="Failsafe channel PWM threshold",
             long="0 disables. Below RCn_MIN (or above RCn_MAX) of the failsafe channel (the "
                  "throttle unless RC_MAP_FAILSAFE is set), a raw value beyond this threshold "
                  "means the receiver is in failsafe."),
    ParamDef("RC_CHAN_CNT", "INT32", 0, min=0, max=MAX_CHANNELS, group=_G,
             short="RC channel count",
             long="Set by the calibration; manual control is only valid when this is > 0."),
    _th("RC_RETURN_TH", "Threshold for the return switch"),
    _th("RC_LOITER_TH", "Threshold for the loiter switch", 0.5),
    _th("RC_OFFB_TH", "Threshold for the offboard switch", 0.5),
    _th("RC_KILLSWITCH_TH", "Threshold for the kill switch"),
    _th("RC_ARMSWITCH_TH", "Threshold for the arm switch"),
    _th("RC_GEAR_TH", "Threshold for the landing gear switch"),
)
