"""A standard VTOL in the commander, the navigator and the land detector (issue 23): the vehicle
type and transition flag follow vtol_att_control's ``vtol_vehicle_status``, the quad-chute is a
failsafe with Return, the multicopter position controller is off only on the wing, a mission's
DO_VTOL_TRANSITION asks for the transition and holds the mission until it is over, and a VTOL on
the wing is never "landed" however low its rotors' thrust.

Synthetic inputs as in :mod:`tests.flight.test_fixedwing_modes` (hand-published topics); the
flight itself is tests/system/test_vtol.py.
"""

from __future__ import annotations

import pytest

from firmware.modules.commander.vehicle_type import vtol_type
from firmware.modules.navigator.geo import distance_m, offset_deg
from tests.flight.test_commander import HOME, Rig, _fly_in
from tests.flight.test_land_detector_fw import FwBench
from common.units import G0_M_S2
from tests.flight.test_navigator import (
    MISSION,
    SP_LAND,
    SP_POSITION,
    SP_TAKEOFF,
    _store,
    at,
    current,
    mode,
    nav_rig,
)

ROTARY_WING, FIXED_WING = 1, 2
TO_FW, TO_MC, MC, FW = 1, 2, 3, 4
RTL = 5


@pytest.mark.parametrize("state, vtype, transition", [
    (MC, ROTARY_WING, False), (TO_FW, ROTARY_WING, True), (FW, FIXED_WING, False),
    (TO_MC, ROTARY_WING, True), (0, ROTARY_WING, False)])
def test_vtol_type_from_the_vtol_state(state: int, vtype: int, transition: bool) -> None:
    assert vtol_type(state) == (vtype, transition)


def test_commander_follows_the_vtol_state_and_returns_on_a_quad_chute() -> None:
    rig = Rig(params={"MAV_TYPE": 22, "COM_FAIL_ACT_T": 0.0})
    rig.run(0.3)
    _fly_in(rig, (4, 3))                                  # Auto: Hold
    st = rig.status
    assert st.is_vtol and st.vehicle_type == ROTARY_WING and not st.in_transition_mode
    rig.set("vtol_vehicle_status", vehicle_vtol_state=TO_FW)
    rig.run(0.3)
    assert rig.status.in_transition_mode and rig.status.vehicle_type == ROTARY_WING
    assert rig.last("vehicle_control_mode").flag_multicopter_position_control_enabled
    rig.set("vtol_vehicle_status", vehicle_vtol_state=FW)
    rig.run(0.3)
    st = rig.status
    assert st.vehicle_type == FIXED_WING and not st.in_transition_mode
    assert not rig.last("vehicle_control_mode").flag_multicopter_position_control_enabled
    assert st.nav_state != RTL and not st.failsafe
    # the wing is given up: back to multicopter at once, latched failure -> Return
    rig.set("vtol_vehicle_status", vehicle_vtol_state=TO_MC, fixed_wing_system_failure=True)
    rig.run(0.3)
    st = rig.status
    assert st.vehicle_type == ROTARY_WING and st.in_transition_mode
    assert st.nav_state == RTL and st.failsafe
    assert "Failsafe: VTOL quad-chute, return" in rig.dmesg()


def _item(store, cmd: int, north: float, east: float, alt: float, **kw):
    lat, lon = offset_deg(HOME[0], HOME[1], north, east)
    return store.new_item(nav_cmd=cmd, lat=lat, lon=lon, altitude=alt,
                          altitude_is_relative=True, **kw)


def test_mission_transition_items_wait_for_the_vtol() -> None:
    rig = nav_rig(NAV_ACC_RAD=15.0, NAV_LOITER_RAD=80.0)
    rig.set("vehicle_status", vehicle_type=ROTARY_WING, is_vtol=True)
    cmds = rig.sub("vehicle_command")
    store = _store(rig)
    store.store_mission([
        _item(store, 22, 0, 0, 30.0),
        _item(store, 3000, 0, 0, 0.0, time_inside=float(FW)),   # PX4: param1 in params[0]
        _item(store, 16, 300, 0, 30.0),
        _item(store, 3000, 0, 0, 0.0, time_inside=float(MC)),
        _item(store, 21, 0, 0, 0.0),
    ])
    rig.run(0.1)
    at(rig, 0, 0, 0.0, landed=True)
    mode(rig, MISSION)
    assert current(rig).type == SP_TAKEOFF
    at(rig, 0, 0, 29.8)                                 # up: the front transition is asked for
    cmd = cmds.update()
    assert cmd is not None and cmd.command == 3000 and cmd.param1 == FW
    sp = current(rig)      # a plain position at the next waypoint, at the takeoff altitude
    assert sp.type == SP_POSITION and sp.alt == pytest.approx(HOME[2] + 30.0)
    assert distance_m(sp.lat, sp.lon, *offset_deg(HOME[0], HOME[1], 300, 0)) < 0.1
    rig.set("vehicle_status", in_transition_mode=True)
    at(rig, 60, 0, 29.0)
    assert rig.last("mission_result").seq_reached == 0  # still transitioning
    rig.set("vehicle_status", in_transition_mode=False, vehicle_type=FIXED_WING)
    at(rig, 120, 0, 29.0)
    assert rig.last("mission_result").seq_reached == 1
    assert current(rig).loiter_radius == 80.0           # the waypoint, as to a plane
    at(rig, 295, 0, 30.0)
    cmd = cmds.update()                                 # the waypoint, then the back transition
    assert rig.last("mission_result").seq_reached == 2
    assert cmd is not None and cmd.command == 3000 and cmd.param1 == MC
    sp = current(rig)
    assert distance_m(sp.lat, sp.lon, *offset_deg(HOME[0], HOME[1], 295, 0)) < 0.5
    rig.set("vehicle_status", in_transition_mode=True, vehicle_type=ROTARY_WING)
    at(rig, 340, 0, 30.0)
    assert rig.last("mission_result").seq_reached == 2
    rig.set("vehicle_status", in_transition_mode=False)
    at(rig, 350, 0, 30.0)                              # a multicopter again: to home, then down
    assert rig.last("mission_result").seq_reached == 3
    sp = current(rig)
    assert sp.type == SP_POSITION and distance_m(sp.lat, sp.lon, HOME[0], HOME[1]) < 0.1


def test_a_transition_item_is_passed_by_a_vehicle_that_is_no_vtol() -> None:
    rig = nav_rig()
    cmds = rig.sub("vehicle_command")
    store = _store(rig)
    store.store_mission([_item(store, 22, 0, 0, 10.0),
                         _item(store, 3000, 0, 0, 0.0, time_inside=float(FW)),
                         _item(store, 16, 20, 0, 10.0)])
    rig.run(0.1)
    at(rig, 0, 0, 0.0, landed=True)
    mode(rig, MISSION)
    at(rig, 0, 0, 10.0)
    assert rig.last("mission_result").seq_reached == 1
    sp = current(rig)
    assert distance_m(sp.lat, sp.lon, *offset_deg(HOME[0], HOME[1], 20, 0)) < 0.1
    while (cmd := cmds.update()) is not None:
        assert cmd.command != 3000


class VtolLandBench(FwBench):
    """The land detector alone, started as ``vtol``, with what its multicopter half reads."""

    TOPICS = FwBench.TOPICS + ("vehicle_status", "actuator_controls_0", "vehicle_control_mode")


def test_a_vtol_on_the_wing_is_never_landed() -> None:
    b = VtolLandBench("vtol")
    assert b.start_rc == 0
    b.set("actuator_armed", armed=True)
    b.set("vehicle_control_mode", flag_control_climb_rate_enabled=True)
    b.set("vehicle_local_position", vx=0.0, vy=0.0, vz=0.0, az=-G0_M_S2)   # rotors off, at rest
    b.set("vehicle_status", is_vtol=True, vehicle_type=FIXED_WING)
    b.run(2.0)
    assert not b.landed                  # low thrust, no motion, but on the wing: flying
    b.set("vehicle_status", vehicle_type=ROTARY_WING, in_transition_mode=True)
    b.run(2.0)
    assert not b.landed
    b.set("vehicle_status", in_transition_mode=False)  # a multicopter at rest: landed
    b.run(2.0)
    assert b.landed


def test_return_on_the_wing_transitions_back_first() -> None:
    rig = nav_rig()
    rig.set("vehicle_status", vehicle_type=FIXED_WING, is_vtol=True)
    cmds = rig.sub("vehicle_command")
    at(rig, 200, 0, 30.0)
    mode(rig, RTL)
    cmd = cmds.update()
    assert cmd is not None and (cmd.command, cmd.param1) == (3000, MC)
    assert "Return: transition to multicopter first" in rig.dmesg()


def test_commander_transition_asks_for_the_other_flight_mode() -> None:
    """PX4's ``commander transition``: multicopter -> fixed wing and back; refused on a
    vehicle that is no VTOL."""
    rig = Rig(params={"MAV_TYPE": 22})
    rig.run(0.3)
    cmds = rig.sub("vehicle_command")
    commander = rig.system.modules.get("commander")
    assert commander.custom_command(["transition"]) == 0
    cmd = cmds.update()
    assert cmd is not None and (cmd.command, cmd.param1) == (3000, FW)
    rig.set("vtol_vehicle_status", vehicle_vtol_state=FW)
    rig.run(0.3)
    assert commander.custom_command(["transition"]) == 0
    while (c := cmds.update()) is not None:
        cmd = c
    assert (cmd.command, cmd.param1) == (3000, MC)
    quad = Rig(params={"MAV_TYPE": 2})
    quad.run(0.3)
    assert quad.system.modules.get("commander").custom_command(["transition"]) == 1


def test_a_land_item_on_the_wing_transitions_back_first() -> None:
    """PX4's VTOL land: no approach and flare as a plane, the back transition and then a
    multicopter's landing at the item."""
    rig = nav_rig(NAV_ACC_RAD=15.0)
    rig.set("vehicle_status", vehicle_type=FIXED_WING, is_vtol=True)
    cmds = rig.sub("vehicle_command")
    store = _store(rig)
    store.store_mission([_item(store, 16, 300, 0, 30.0), _item(store, 21, 0, 0, 0.0)])
    rig.run(0.1)
    at(rig, 200, 0, 30.0)
    mode(rig, MISSION)
    at(rig, 295, 0, 30.0)
    assert rig.last("mission_result").seq_reached == 0
    cmd = cmds.update()
    assert cmd is not None and (cmd.command, cmd.param1) == (3000, MC)
    assert current(rig).type == SP_POSITION                  # not a plane's LAND setpoint
    rig.set("vehicle_status", vehicle_type=ROTARY_WING, in_transition_mode=True)
    at(rig, 330, 0, 30.0)
    assert current(rig).type == SP_POSITION
    rig.set("vehicle_status", in_transition_mode=False)
    at(rig, 340, 0, 30.0)                 # a multicopter: to the land point at its altitude
    sp = current(rig)
    assert sp.type == SP_POSITION and distance_m(sp.lat, sp.lon, HOME[0], HOME[1]) < 0.1
    assert sp.alt == pytest.approx(HOME[2] + 30.0, abs=0.5)
    at(rig, 2, 0, 30.0)
    assert current(rig).type == SP_LAND
