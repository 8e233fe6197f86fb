"""Flight modes as data: PX4's navigation states, custom modes, requirements and control flags.

Everything the commander decides about a mode is a table lookup here, so adding a mode means
adding rows, not branches. Numbers are PX4's (vehicle_status NAVIGATION_STATE_*, MAVLink PX4
custom main/sub modes, COM_FLTMODEn values, MAV_CMD ids).
"""

from __future__ import annotations

from typing import Final

__all__ = [
    "FLTMODE_TO_NAV", "MODE_NAMES", "NAV_NAMES", "NO_ARMING", "REQUIREMENTS",
    "SELECTABLE_NAV_STATES", "VALID_NAV_STATES",
    "control_flags", "custom_to_nav", "nav_to_custom", "offboard_flags",
]

# vehicle_status.NAVIGATION_STATE_*
MANUAL: Final = 0
ALTCTL: Final = 1
POSCTL: Final = 2
AUTO_MISSION: Final = 3
AUTO_LOITER: Final = 4
AUTO_RTL: Final = 5
ACRO: Final = 10
DESCEND: Final = 12
TERMINATION: Final = 13
OFFBOARD: Final = 14
STAB: Final = 15
AUTO_TAKEOFF: Final = 17
AUTO_LAND: Final = 18
AUTO_PRECLAND: Final = 20

NAV_NAMES: Final[dict[int, str]] = {
    MANUAL: "Manual", ALTCTL: "Altitude", POSCTL: "Position", AUTO_MISSION: "Mission",
    AUTO_LOITER: "Hold", AUTO_RTL: "Return", ACRO: "Acro", DESCEND: "Descend",
    TERMINATION: "Termination", OFFBOARD: "Offboard", STAB: "Stabilized",
    AUTO_TAKEOFF: "Takeoff", AUTO_LAND: "Land", AUTO_PRECLAND: "Precision Landing",
}

# PX4 custom modes (MAVLink HEARTBEAT custom_mode / DO_SET_MODE param2, param3)
MAIN_MANUAL: Final = 1
MAIN_ALTCTL: Final = 2
MAIN_POSCTL: Final = 3
MAIN_AUTO: Final = 4
MAIN_ACRO: Final = 5
MAIN_OFFBOARD: Final = 6
MAIN_STAB: Final = 7
SUB_READY: Final = 1
SUB_TAKEOFF: Final = 2
SUB_LOITER: Final = 3
SUB_MISSION: Final = 4
SUB_RTL: Final = 5
SUB_LAND: Final = 6
SUB_PRECLAND: Final = 9

_CUSTOM: Final[dict[tuple[int, int], int]] = {
    (MAIN_MANUAL, 0): MANUAL, (MAIN_ALTCTL, 0): ALTCTL, (MAIN_POSCTL, 0): POSCTL,
    (MAIN_ACRO, 0): ACRO, (MAIN_OFFBOARD, 0): OFFBOARD, (MAIN_STAB, 0): STAB,
    (MAIN_AUTO, SUB_TAKEOFF): AUTO_TAKEOFF, (MAIN_AUTO, SUB_LOITER): AUTO_LOITER,
    (MAIN_AUTO, SUB_MISSION): AUTO_MISSION, (MAIN_AUTO, SUB_RTL): AUTO_RTL,
    (MAIN_AUTO, SUB_LAND): AUTO_LAND, (MAIN_AUTO, SUB_PRECLAND): AUTO_PRECLAND,
}
_NAV_TO_CUSTOM: Final = {nav: key for key, nav in _CUSTOM.items()}
_NAV_TO_CUSTOM[DESCEND] = (MAIN_AUTO, SUB_LAND)
_NAV_TO_CUSTOM[TERMINATION] = (MAIN_MANUAL, 0)

#: COM_FLTMODEn value -> navigation state (-1 unassigned)
FLTMODE_TO_NAV: Final[dict[int, int]] = {
    0: MANUAL, 1: ALTCTL, 2: POSCTL, 3: AUTO_MISSION, 4: AUTO_LOITER, 5: AUTO_RTL, 6: ACRO,
    7: OFFBOARD, 8: STAB, 10: AUTO_TAKEOFF, 11: AUTO_LAND, 13: AUTO_PRECLAND,
}

#: ``commander mode <name>`` (PX4's names first, then friendly aliases)
MODE_NAMES: Final[dict[str, int]] = {
    "manual": MANUAL, "altctl": ALTCTL, "posctl": POSCTL, "acro": ACRO, "offboard": OFFBOARD,
    "stabilized": STAB, "auto:mission": AUTO_MISSION, "auto:loiter": AUTO_LOITER,
    "auto:rtl": AUTO_RTL, "auto:takeoff": AUTO_TAKEOFF, "auto:land": AUTO_LAND,
    "auto:precland": AUTO_PRECLAND,
    "stab": STAB, "altitude": ALTCTL, "position": POSCTL, "mission": AUTO_MISSION,
    "loiter": AUTO_LOITER, "hold": AUTO_LOITER, "rtl": AUTO_RTL, "return": AUTO_RTL,
    "takeoff": AUTO_TAKEOFF, "land": AUTO_LAND,
}

# What a mode needs to run. "manual": stick input; "alt": a valid altitude estimate;
# "lpos": local horizontal position; "gpos": global position; "home"; "mission"; "offboard":
# a fresh offboard_control_mode whose controlled quantities have a valid estimate (PX4's
# mode_req_offboard_signal, OffboardChecks); "never": not implemented in this stack
# (precision landing).
REQUIREMENTS: Final[dict[int, frozenset[str]]] = {
    MANUAL: frozenset({"manual"}), STAB: frozenset({"manual"}), ACRO: frozenset({"manual"}),
    ALTCTL: frozenset({"manual", "alt"}), POSCTL: frozenset({"manual", "alt", "lpos"}),
    AUTO_MISSION: frozenset({"alt", "lpos", "gpos", "mission"}),
    AUTO_LOITER: frozenset({"alt", "lpos", "gpos"}),
    AUTO_RTL: frozenset({"alt", "lpos", "gpos", "home"}),
    AUTO_TAKEOFF: frozenset({"alt", "lpos", "gpos"}),
    AUTO_LAND: frozenset({"alt", "gpos"}),
    DESCEND: frozenset(), TERMINATION: frozenset(),
    OFFBOARD: frozenset({"offboard"}), AUTO_PRECLAND: frozenset({"never"}),
}

#: the navigation states this commander implements, ascending (PX4's valid_nav_states_mask,
#: the modes AVAILABLE_MODES lists); PX4's Orbit, Follow Target and VTOL Takeoff are not here
VALID_NAV_STATES: Final = tuple(sorted(REQUIREMENTS))
#: those a user may select (PX4's can_set_nav_states_mask): all but the ones that can never
#: run in this stack (precision landing has no landing-target estimator here)
SELECTABLE_NAV_STATES: Final = frozenset(n for n in VALID_NAV_STATES
                                         if "never" not in REQUIREMENTS[n])

#: modes from which arming is refused (PX4: the vehicle would not know what to do on the ground)
NO_ARMING: Final = frozenset({AUTO_RTL, AUTO_LAND, DESCEND, TERMINATION, AUTO_PRECLAND})

_RATES: Final = 1
_ATT: Final = 2
_ALT: Final = 4
_CLIMB: Final = 8
_POS: Final = 16
_VEL: Final = 32
_ACC: Final = 64
_MANUAL_F: Final = 128
_AUTO_F: Final = 256
_TERM_F: Final = 512
_FLAGS: Final[dict[int, int]] = {
    MANUAL: _MANUAL_F | _RATES | _ATT,      # a multicopter's manual mode is stabilized
    STAB: _MANUAL_F | _RATES | _ATT,
    ACRO: _MANUAL_F | _RATES,
    ALTCTL: _MANUAL_F | _RATES | _ATT | _ALT | _CLIMB,
    POSCTL: _MANUAL_F | _RATES | _ATT | _ALT | _CLIMB | _POS | _VEL | _ACC,
    DESCEND: _AUTO_F | _RATES | _ATT | _CLIMB,
    TERMINATION: _TERM_F,
    OFFBOARD: _RATES | _ATT | _ALT | _CLIMB | _POS | _VEL | _ACC,
}
for _nav in (AUTO_MISSION, AUTO_LOITER, AUTO_RTL, AUTO_TAKEOFF, AUTO_LAND, AUTO_PRECLAND):
    _FLAGS[_nav] = _AUTO_F | _RATES | _ATT | _ALT | _CLIMB | _POS | _VEL | _ACC


def offboard_flags(position: bool, velocity: bool, acceleration: bool, attitude: bool,
                   body_rate: bool) -> int:
    """The controllers Offboard mode runs for what offboard_control_mode says is controlled:
    the highest level given decides, and every loop below it runs (PX4's ModeUtil
    control_mode.cpp). Nothing given: position (the vehicle holds where it is)."""
    if position:
        return _RATES | _ATT | _ALT | _CLIMB | _POS | _VEL | _ACC
    if velocity:
        return _RATES | _ATT | _ALT | _CLIMB | _VEL | _ACC
    if acceleration:
        return _RATES | _ATT | _ACC
    if attitude:
        return _RATES | _ATT
    if body_rate:
        return _RATES
    return _FLAGS[OFFBOARD]


def control_flags(nav_state: int, offboard: int | None = None,
                  fixed_wing: bool = False) -> dict[str, bool]:
    """vehicle_control_mode flags for a navigation state; ``offboard``: the
    :func:`offboard_flags` to use in Offboard mode.

    ``fixed_wing``: PX4's control_mode for a plane: Manual is really manual (no rate or
    attitude loop: a plane flies without stabilization, so the sticks go to the surfaces,
    PX4's stabilization_required() is true only for rotary wings), and the multicopter
    position controller never runs (flag_multicopter_position_control_enabled false)."""
    f = _FLAGS.get(nav_state, _MANUAL_F | _RATES | _ATT)
    if nav_state == OFFBOARD and offboard is not None:
        f = offboard
    if fixed_wing and nav_state == MANUAL:
        f = _MANUAL_F
    out = {
        "flag_control_manual_enabled": bool(f & _MANUAL_F),
        "flag_control_auto_enabled": bool(f & _AUTO_F),
        "flag_control_offboard_enabled": nav_state == OFFBOARD,
        "flag_control_rates_enabled": bool(f & _RATES),
        "flag_control_attitude_enabled": bool(f & _ATT),
        "flag_control_acceleration_enabled": bool(f & _ACC),
        "flag_control_velocity_enabled": bool(f & _VEL),
        "flag_control_position_enabled": bool(f & _POS),
        "flag_control_altitude_enabled": bool(f & _ALT),
        "flag_control_climb_rate_enabled": bool(f & _CLIMB),
        "flag_control_termination_enabled": bool(f & _TERM_F),
    }
    out["flag_multicopter_position_control_enabled"] = not fixed_wing and bool(
        f & (_ALT | _CLIMB | _POS | _VEL | _ACC))
    return out


def custom_to_nav(main_mode: int, sub_mode: int) -> int | None:
    """The navigation state of a PX4 custom mode, or None if there is none."""
    if main_mode == MAIN_AUTO:
        if sub_mode == 0:  # PX4: AUTO without a sub mode is Mission
            return AUTO_MISSION
        return _CUSTOM.get((main_mode, sub_mode))
    return _CUSTOM.get((main_mode, 0))


def nav_to_custom(nav_state: int) -> tuple[int, int]:
    """PX4 custom (main, sub) mode of a navigation state (what MAVLink's heartbeat reports)."""
    return _NAV_TO_CUSTOM.get(nav_state, (MAIN_MANUAL, 0))
