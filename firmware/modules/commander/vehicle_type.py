"""The vehicle's type from the MAV_TYPE parameter, as PX4's commander derives it.

PX4 airframe files set MAV_TYPE (1 fixed wing, 2 quadrotor, 13 hexarotor, 22 standard VTOL,
...); the commander copies it into ``vehicle_status.system_type`` and derives
``vehicle_type`` (rotary wing, fixed wing) and ``is_vtol`` from it (commander_helper's
is_rotary_wing / is_fixed_wing / is_vtol). Everything downstream that behaves differently on
a plane (control mode flags, the navigator's acceptance radii, the IO's manual override)
reads ``vehicle_type``, never the parameter, so one airframe setting drives them all.

A VTOL starts as a rotary wing (it takes off as a multicopter); :func:`vtol_type` follows
``vtol_vehicle_status`` from vtol_att_control: FIXED_WING once the front transition is over,
ROTARY_WING again from the start of the back transition (so the multicopter position
controller takes over while the rotors spin up), ``in_transition_mode`` in either transition.
"""

from __future__ import annotations

from typing import Final

__all__ = ["MAV_TYPE_FIXED_WING", "MAV_TYPE_QUADROTOR", "VEHICLE_TYPE_FIXED_WING",
           "VEHICLE_TYPE_ROTARY_WING", "VEHICLE_TYPE_UNKNOWN", "classify", "vtol_type"]

# MAVLink MAV_TYPE values (common.xml)
MAV_TYPE_FIXED_WING: Final = 1
MAV_TYPE_QUADROTOR: Final = 2
#: multicopters and helicopters: PX4's is_rotary_wing (quad, coaxial, heli, hexa, octo, tri,
#: dodeca, decarotor)
_ROTARY: Final = frozenset({2, 3, 4, 13, 14, 15, 29, 35})
#: the VTOL kinds: tailsitter duo/quad, tiltrotor, standard ("fixedrotor"), tailsitter,
#: tiltwing
_VTOL: Final = frozenset({19, 20, 21, 22, 23, 24})

# vehicle_status.VEHICLE_TYPE_*
VEHICLE_TYPE_UNKNOWN: Final = 0
VEHICLE_TYPE_ROTARY_WING: Final = 1
VEHICLE_TYPE_FIXED_WING: Final = 2


def classify(mav_type: int) -> tuple[int, bool]:
    """``(vehicle_type, is_vtol)`` for a MAV_TYPE value.

    Rotary wing and VTOL (in its multicopter state) give ROTARY_WING, fixed wing gives
    FIXED_WING; anything else (rovers, boats, unknown values) is UNKNOWN, which the
    flight stack treats as a multicopter, as it did before MAV_TYPE was read."""
    t = int(mav_type)
    if t in _VTOL:
        return VEHICLE_TYPE_ROTARY_WING, True
    if t in _ROTARY:
        return VEHICLE_TYPE_ROTARY_WING, False
    if t == MAV_TYPE_FIXED_WING:
        return VEHICLE_TYPE_FIXED_WING, False
    return VEHICLE_TYPE_UNKNOWN, False


# vtol_vehicle_status.VEHICLE_VTOL_STATE_*
_VTOL_TRANSITION_TO_FW: Final = 1
_VTOL_TRANSITION_TO_MC: Final = 2
_VTOL_FW: Final = 4


def vtol_type(vtol_state: int) -> tuple[int, bool]:
    """``(vehicle_type, in_transition_mode)`` of a VTOL in ``vtol_state``: a plane only in
    fixed-wing flight; both transitions are flown by the multicopter position controller."""
    if vtol_state == _VTOL_FW:
        return VEHICLE_TYPE_FIXED_WING, False
    return VEHICLE_TYPE_ROTARY_WING, vtol_state in (_VTOL_TRANSITION_TO_FW,
                                                    _VTOL_TRANSITION_TO_MC)
