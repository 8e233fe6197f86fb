"""Fixed wing in the commander and the navigator (issue 23): the vehicle type from MAV_TYPE, a
plane's control flags and failsafe, and the navigator's plane semantics (takeoff by altitude on
the runway heading, altitude acceptance NAV_FW_ALT_RAD / NAV_FW_ALTL_RAD, the L1 acceptance
radius, loiter radius, land at the touchdown point, Return's circles) on synthetic positions.

The vehicle "flies" by the test setting its position (see :mod:`tests.flight.test_navigator`);
the commander is replaced by a hand-published vehicle_status with ``vehicle_type`` FIXED_WING.
"""

from __future__ import annotations

import pytest

from firmware.modules.commander.vehicle_type import classify
from firmware.modules.navigator.geo import distance_m, offset_deg
from tests.flight.test_commander import ACCEPTED, HOME, POSCTL, RTL, Rig, _fly_in
from tests.flight.test_navigator import (
    MISSION,
    SP_IDLE,
    SP_LAND,
    SP_LOITER,
    SP_POSITION,
    SP_TAKEOFF,
    TAKEOFF,
    _store,
    at,
    current,
    mode,
    nav_rig,
)

FIXED_WING, ROTARY_WING = 2, 1
MANUAL = 0


# -- commander: vehicle type ------------------------------------------------------------------

@pytest.mark.parametrize("mav_type, vtype, vtol", [
    (1, FIXED_WING, False), (2, ROTARY_WING, False), (13, ROTARY_WING, False),
    (22, ROTARY_WING, True), (10, 0, False)])
def test_classify_mav_type(mav_type: int, vtype: int, vtol: bool) -> None:
    assert classify(mav_type) == (vtype, vtol)


def test_vehicle_status_type_follows_mav_type_and_its_changes() -> None:
    rig = Rig(params={"MAV_TYPE": 1})
    rig.run(0.3)
    st = rig.status
    assert st.system_type == 1 and st.vehicle_type == FIXED_WING and not st.is_vtol
    assert rig.system.modules.command("commander", ["status"]) == 0
    assert any("vehicle type: fixed wing, MAV_TYPE 1" in line for line in rig.out)
    rig.params.set("MAV_TYPE", 22)                   # a standard VTOL: takes off as a copter
    rig.run(0.1)
    st = rig.status
    assert st.system_type == 22 and st.vehicle_type == ROTARY_WING and st.is_vtol


def test_a_planes_manual_mode_has_no_stabilization() -> None:
    plane, copter = Rig(params={"MAV_TYPE": 1}), Rig()
    for r in (plane, copter):
        r.run(0.3)
        assert r.set_mode(1) == ACCEPTED             # PX4 custom main mode 1: Manual
        r.run(0.1)
        assert r.status.nav_state == MANUAL
    fw, mc = plane.last("vehicle_control_mode"), copter.last("vehicle_control_mode")
    assert fw.flag_control_manual_enabled and not fw.flag_control_attitude_enabled
    assert not fw.flag_control_rates_enabled
    assert mc.flag_control_attitude_enabled and mc.flag_control_rates_enabled
    for r in (plane, copter):
        assert r.set_mode(3) == ACCEPTED             # Position
        r.run(0.1)
    fw, mc = plane.last("vehicle_control_mode"), copter.last("vehicle_control_mode")
    assert fw.flag_control_position_enabled and fw.flag_control_attitude_enabled
    assert not fw.flag_multicopter_position_control_enabled
    assert mc.flag_multicopter_position_control_enabled


def test_a_plane_returns_on_rc_loss() -> None:
    rig = Rig(params={"MAV_TYPE": 1, "NAV_RCL_ACT": 2, "COM_FAIL_ACT_T": 0.0})
    rig.run(0.3)
    _fly_in(rig, (3, 0))
    assert rig.status.nav_state == POSCTL
    rig.stop("manual_control_setpoint")
    rig.run(1.0)
    st = rig.status
    assert st.nav_state == RTL and st.failsafe and st.vehicle_type == FIXED_WING


# -- navigator: a plane's mission ---------------------------------------------------------------

def fw_rig(**params: float) -> Rig:
    base = {"NAV_ACC_RAD": 15.0, "NAV_LOITER_RAD": 50.0, "NAV_FW_ALT_RAD": 10.0,
            "NAV_FW_ALTL_RAD": 5.0}
    base.update(params)
    rig = nav_rig(**base)
    rig.set("vehicle_status", vehicle_type=FIXED_WING)
    rig.set("vehicle_local_position", heading=0.5)   # the runway heading
    return rig


def _pcs(rig: Rig, acceptance_radius_m: float) -> None:
    """fw_pos_control_l1's report: its L1 switch distance."""
    rig.set("position_controller_status", acceptance_radius=acceptance_radius_m)
    rig.run(0.1)


def _item(store, cmd: int, north: float, east: float, alt: float, **kw):
    lat, lon = offset_deg(HOME[0], HOME[1], north, east)
    return store.new_item(nav_cmd=cmd, lat=lat, lon=lon, altitude=alt,
                          altitude_is_relative=True, **kw)


def test_plane_mission_takeoff_waypoints_loiter_land() -> None:
    rig = fw_rig()
    store = _store(rig)
    store.store_mission([
        _item(store, 22, 0, 0, 50.0),                     # takeoff (no position of its own)
        _item(store, 16, 300, 0, 50.0),
        _item(store, 16, 300, 300, 50.0),
        _item(store, 19, 0, 300, 50.0, time_inside=2.0),  # loiter time, default radius
        _item(store, 21, 0, 0, 0.0),                      # land at home
    ])
    rig.run(0.1)
    at(rig, 0, 0, 0.0, landed=True)
    mode(rig, MISSION)
    sp = current(rig)
    assert sp.type == SP_TAKEOFF and sp.alt == pytest.approx(HOME[2] + 50.0)
    assert sp.yaw == pytest.approx(0.5) and sp.loiter_radius == 50.0   # on the runway heading
    at(rig, 150, 80, 35.0)                     # climbing out, far from the takeoff point
    assert rig.last("mission_result").seq_reached == -1
    at(rig, 200, 100, 41.0)                    # within NAV_FW_ALT_RAD below: climbout done
    assert rig.last("mission_result").seq_reached == 0
    sp = current(rig)
    assert sp.type == SP_POSITION and distance_m(
        sp.lat, sp.lon, *offset_deg(HOME[0], HOME[1], 300, 0)) < 0.1
    at(rig, 280, 0, 43.0)                      # 20 m short, 7 m low: not yet (NAV_ACC_RAD 15)
    assert rig.last("mission_result").seq_reached == 0
    _pcs(rig, 25.0)                            # the L1 distance is larger: turn now
    at(rig, 280, 0, 43.0)
    assert rig.last("mission_result").seq_reached == 1
    assert current(rig).type == SP_POSITION    # the second waypoint
    at(rig, 300, 290, 49.0)
    sp = current(rig)
    assert sp.type == SP_LOITER and sp.loiter_radius == 50.0
    nxt = rig.last("position_setpoint_triplet").next
    assert nxt.valid and nxt.type == SP_LAND
    at(rig, 0, 355, 42.0)                      # on the circle, 8 m low: NAV_FW_ALTL_RAD 5
    assert rig.last("mission_result").seq_reached == 2
    at(rig, 0, 355, 46.0)                      # within 1.2 x radius and 5 m: reached
    assert rig.last("mission_result").seq_reached == 3
    assert current(rig).type == SP_LOITER      # holding for time_inside
    rig.run(2.2)
    t = rig.last("position_setpoint_triplet")
    assert t.current.type == SP_LAND and t.current.alt == pytest.approx(HOME[2])
    assert distance_m(t.current.lat, t.current.lon, HOME[0], HOME[1]) < 0.1
    assert t.previous.valid and t.previous.type == SP_LOITER  # the approach starts there
    at(rig, 10, 0, 0.0, landed=True)
    res = rig.last("mission_result")
    assert res.finished and res.seq_reached == 4 and current(rig).type == SP_IDLE


def test_plane_mission_on_the_ground_takes_off_to_its_first_waypoint() -> None:
    rig = fw_rig(MIS_TAKEOFF_ALT=30.0)
    store = _store(rig)
    store.store_mission([_item(store, 16, 300, 0, 40.0)])
    rig.run(0.1)
    at(rig, 0, 0, 0.0, landed=True)
    mode(rig, MISSION)
    sp = current(rig)
    assert sp.type == SP_TAKEOFF and sp.alt == pytest.approx(HOME[2] + 40.0)
    assert sp.lat == pytest.approx(HOME[0]) and sp.yaw == pytest.approx(0.5)
    at(rig, 100, 0, 31.0)
    assert current(rig).type == SP_POSITION


def test_plane_takeoff_mode_climbs_out_then_circles() -> None:
    rig = fw_rig(MIS_TAKEOFF_ALT=40.0)
    at(rig, 0, 0, 0.0, landed=True)
    mode(rig, TAKEOFF)
    sp = current(rig)
    assert sp.type == SP_TAKEOFF and sp.yaw == pytest.approx(0.5)
    at(rig, 200, 0, 29.0)
    assert not rig.last("mission_result").finished
    at(rig, 250, 0, 31.0)                      # 9 m below: done for a plane
    assert rig.last("mission_result").finished
    sp = current(rig)
    assert sp.type == SP_LOITER and sp.loiter_radius == 50.0


def test_plane_return_climbs_returns_circles_down_and_lands() -> None:
    rig = fw_rig(RTL_RETURN_ALT=60.0, RTL_DESCEND_ALT=40.0, RTL_LAND_DELAY=1.0,
                 RTL_LOITER_RAD=80.0)
    at(rig, 400, 0, 30.0)
    mode(rig, RTL)
    rtl = rig.system.modules.get("navigator").modes[RTL]
    sp = current(rig)
    assert rtl.state_name == "climb" and sp.type == SP_LOITER    # climbing in circles
    assert sp.alt == pytest.approx(HOME[2] + 60.0) and sp.loiter_radius == 50.0
    at(rig, 420, 40, 51.0)
    sp = current(rig)
    assert rtl.state_name == "return" and sp.type == SP_POSITION
    assert sp.lat == pytest.approx(HOME[0]) and sp.alt == pytest.approx(HOME[2] + 60.0)
    at(rig, 20, 0, 60.0)                        # outside NAV_ACC_RAD
    assert rtl.state_name == "return"
    at(rig, 10, 0, 55.0)
    sp = current(rig)
    assert rtl.state_name == "descend" and sp.type == SP_LOITER
    assert sp.alt == pytest.approx(HOME[2] + 40.0) and sp.loiter_radius == 80.0
    at(rig, 80, 0, 46.0)
    sp = current(rig)
    assert rtl.state_name == "loiter" and sp.type == SP_LOITER and sp.loiter_radius == 80.0
    assert sp.alt == pytest.approx(HOME[2] + 40.0)
    rig.run(1.1)
    t = rig.last("position_setpoint_triplet")
    assert rtl.state_name == "land" and t.current.type == SP_LAND
    assert t.current.alt == HOME[2] and t.previous.type == SP_LOITER
    at(rig, 30, 0, 0.0, landed=True)
    assert rtl.state_name == "landed" and current(rig).type == SP_IDLE


def test_plane_return_with_negative_land_delay_circles_home() -> None:
    rig = fw_rig(RTL_RETURN_ALT=50.0, RTL_DESCEND_ALT=50.0, RTL_LAND_DELAY=-1.0)
    at(rig, 300, 0, 50.0)
    mode(rig, RTL)
    rtl = rig.system.modules.get("navigator").modes[RTL]
    assert rtl.state_name == "return"
    at(rig, 5, 0, 50.0)
    rig.run(5.0)
    sp = current(rig)
    assert rtl.state_name == "loiter" and sp.type == SP_LOITER
    assert sp.alt == pytest.approx(HOME[2] + 50.0)


def test_copter_keeps_its_tight_altitude_acceptance() -> None:
    """The same waypoint 5 m low: reached for a plane (NAV_FW_ALT_RAD), not for a copter."""
    results = {}
    for vtype in (ROTARY_WING, FIXED_WING):
        rig = fw_rig()
        rig.set("vehicle_status", vehicle_type=vtype)
        store = _store(rig)
        store.store_mission([_item(store, 16, 100, 0, 30.0), _item(store, 16, 200, 0, 30.0)])
        rig.run(0.1)
        at(rig, 50, 0, 30.0)
        mode(rig, MISSION)
        assert rig.last("mission_result").seq_reached == -1
        at(rig, 98, 0, 25.0)
        results[vtype] = rig.last("mission_result").seq_reached
        assert current(rig).loiter_radius == (50.0 if vtype == FIXED_WING else 0.0)
    assert results == {ROTARY_WING: -1, FIXED_WING: 0}


@pytest.mark.parametrize("vtype, valid", [(FIXED_WING, False), (ROTARY_WING, True)])
def test_a_planes_landing_needs_an_approach_waypoint(vtype: int, valid: bool) -> None:
    rig = fw_rig()
    rig.set("vehicle_status", vehicle_type=vtype)
    rig.run(0.1)
    store = _store(rig)
    store.store_mission([_item(store, 178, 0, 0, 0.0, speed_m_s=15.0),  # DO_CHANGE_SPEED
                         _item(store, 21, 200, 0, 0.0)])
    rig.run(0.1)
    assert rig.last("mission_result").valid == valid
    if not valid:
        assert "needs a waypoint before it" in rig.dmesg()
    store.store_mission([_item(store, 22, 0, 0, 30.0), _item(store, 16, 400, 0, 30.0),
                         _item(store, 21, 200, 0, 0.0)])
    rig.run(0.1)
    assert rig.last("mission_result").valid
