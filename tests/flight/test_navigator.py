"""navigator and dataman: takeoff, mission progression, return phases, land, mission storage.

The commander is replaced by a hand-published vehicle_status; the vehicle "flies" by the test
setting vehicle_global_position to where it should be (see :class:`tests.flight.test_commander.Rig`).
"""

from __future__ import annotations

import math

import pytest

from firmware.modules.dataman.store import MissionStore
from firmware.modules.navigator.geo import bearing_rad, distance_m, offset_deg
from firmware.platform.params import MemoryPartition
from tests.flight.test_commander import HOME, Rig

TAKEOFF, LOITER, MISSION, RTL, LAND = 17, 4, 3, 5, 18
SP_POSITION, SP_LOITER, SP_TAKEOFF, SP_LAND, SP_IDLE = 0, 2, 3, 4, 5


def nav_rig(**params: float) -> Rig:
    base = {"NAV_ACC_RAD": 2.0, "MIS_TAKEOFF_ALT": 2.5}
    base.update(params)
    rig = Rig(modules=("dataman", "navigator"), params=base)
    rig.set("home_position", lat=HOME[0], lon=HOME[1], alt=HOME[2], valid_hpos=True,
            valid_alt=True, yaw=0.3)
    return rig


def mode(rig: Rig, nav_state: int, armed: bool = True) -> None:
    rig.set("vehicle_status", nav_state=nav_state, arming_state=2 if armed else 1)
    rig.run(0.2)


def at(rig: Rig, north: float, east: float, up: float, landed: bool = False) -> None:
    lat, lon = offset_deg(HOME[0], HOME[1], north, east)
    rig.set("vehicle_global_position", lat=lat, lon=lon, alt=HOME[2] + up)
    rig.set("vehicle_land_detected", landed=landed)
    rig.run(0.2)


def current(rig: Rig):
    return rig.last("position_setpoint_triplet").current


def test_geo_helpers_agree() -> None:
    lat, lon = offset_deg(HOME[0], HOME[1], 30.0, 40.0)
    assert distance_m(HOME[0], HOME[1], lat, lon) == pytest.approx(50.0, abs=0.05)
    assert bearing_rad(HOME[0], HOME[1], lat, lon) == pytest.approx(math.atan2(40, 30),
                                                                    abs=1e-3)


def test_takeoff_setpoint_then_finished() -> None:
    rig = nav_rig()
    mode(rig, TAKEOFF)
    sp = current(rig)
    assert sp.valid and sp.type == SP_TAKEOFF
    assert sp.alt == pytest.approx(HOME[2] + 2.5) and sp.lat == pytest.approx(HOME[0])
    at(rig, 0, 0, 1.0)
    assert not rig.last("mission_result").finished
    at(rig, 0, 0, 2.2)
    assert rig.last("mission_result").finished
    assert current(rig).type == SP_LOITER


def test_land_here_then_idle() -> None:
    rig = nav_rig()
    at(rig, 5, 5, 8.0)
    mode(rig, LAND)
    sp = current(rig)
    assert sp.type == SP_LAND and distance_m(sp.lat, sp.lon, *offset_deg(HOME[0], HOME[1], 5,
                                                                         5)) < 0.01
    at(rig, 5, 5, 0.0, landed=True)
    assert current(rig).type == SP_IDLE


def test_loiter_holds_where_the_vehicle_is() -> None:
    rig = nav_rig()
    at(rig, 12, -3, 7.0)
    mode(rig, LOITER)
    sp = current(rig)
    assert sp.type == SP_LOITER and sp.alt == pytest.approx(HOME[2] + 7.0)


def _store(rig: Rig) -> MissionStore:
    return rig.system.modules.get("dataman").store


def test_mission_progresses_with_the_acceptance_radius() -> None:
    rig = nav_rig()
    store = _store(rig)
    n1 = offset_deg(HOME[0], HOME[1], 20, 0)
    ne = offset_deg(HOME[0], HOME[1], 20, 20)
    store.store_mission([
        store.new_item(nav_cmd=22, lat=HOME[0], lon=HOME[1], altitude=10.0,
                       altitude_is_relative=True),
        store.new_item(nav_cmd=16, lat=n1[0], lon=n1[1], altitude=10.0,
                       altitude_is_relative=True),
        store.new_item(nav_cmd=16, lat=ne[0], lon=ne[1], altitude=10.0,
                       altitude_is_relative=True, time_inside=1.0, yaw=1.0),
        store.new_item(nav_cmd=21, lat=HOME[0], lon=HOME[1], altitude=0.0,
                       altitude_is_relative=True),
    ])
    rig.run(0.1)
    res = rig.last("mission_result")
    assert res.valid and res.seq_total == 4 and res.seq_current == 0
    mode(rig, MISSION)
    sp = current(rig)
    assert sp.type == SP_TAKEOFF and sp.alt == pytest.approx(HOME[2] + 10)
    at(rig, 0, 0, 9.5)
    sp = current(rig)
    assert rig.last("mission_result").seq_reached == 0
    assert sp.type == SP_POSITION and sp.lat == pytest.approx(n1[0])
    assert sp.yaw == pytest.approx(0.0, abs=1e-3)                  # towards the waypoint
    assert rig.last("position_setpoint_triplet").next.valid
    at(rig, 17, 0, 10.0)                                          # 3 m short: not reached
    assert rig.last("mission_result").seq_current == 1
    at(rig, 18.5, 0, 10.0)                                        # 1.5 m: reached
    res = rig.last("mission_result")
    assert res.seq_reached == 1 and res.seq_current == 2
    sp = current(rig)
    assert sp.yaw == pytest.approx(1.0)                            # the item's own yaw
    prev = rig.last("position_setpoint_triplet").previous
    assert prev.valid and prev.lat == pytest.approx(n1[0])
    at(rig, 20, 19, 10.2)
    assert rig.last("mission_result").seq_reached == 2
    rig.run(0.5)
    assert rig.last("mission_result").seq_current == 2            # holding time_inside
    rig.run(0.6)
    assert rig.last("mission_result").seq_current == 3
    sp = current(rig)
    assert sp.type == SP_POSITION and sp.alt == pytest.approx(HOME[2] + 10.2, abs=0.01)
    at(rig, 0.5, 0.5, 10.2)                                       # over the land point
    assert current(rig).type == SP_LAND
    at(rig, 0.5, 0.5, 0.0, landed=True)
    res = rig.last("mission_result")
    assert res.finished and res.seq_reached == 3
    assert current(rig).type == SP_IDLE


def test_mission_on_the_ground_climbs_first() -> None:
    rig = nav_rig(MIS_TAKEOFF_ALT=5.0)
    store = _store(rig)
    wp = offset_deg(HOME[0], HOME[1], 30, 0)
    store.store_mission([store.new_item(nav_cmd=16, lat=wp[0], lon=wp[1], altitude=3.0,
                                        altitude_is_relative=True)])
    at(rig, 0, 0, 0.0, landed=True)
    mode(rig, MISSION)
    sp = current(rig)
    assert sp.type == SP_TAKEOFF and sp.alt == pytest.approx(HOME[2] + 5.0)
    at(rig, 0, 0, 4.8)
    sp = current(rig)
    assert sp.type == SP_POSITION and sp.lat == pytest.approx(wp[0])
    at(rig, 30, 0, 3.0)
    res = rig.last("mission_result")
    assert res.finished and current(rig).type == SP_LOITER


def test_rtl_climbs_returns_descends_and_lands() -> None:
    rig = nav_rig(RTL_RETURN_ALT=20.0, RTL_DESCEND_ALT=10.0, RTL_LAND_DELAY=1.0)
    at(rig, 100, 0, 5.0)
    mode(rig, RTL)
    rtl = rig.system.modules.get("navigator").modes[RTL]
    sp = current(rig)
    assert rtl.state_name == "climb" and sp.alt == pytest.approx(HOME[2] + 20.0)
    assert distance_m(sp.lat, sp.lon, *offset_deg(HOME[0], HOME[1], 100, 0)) < 0.01
    at(rig, 100, 0, 19.5)
    sp = current(rig)
    assert rtl.state_name == "return" and sp.lat == pytest.approx(HOME[0])
    assert abs(sp.yaw) == pytest.approx(math.pi, abs=1e-3)        # heading south to home
    at(rig, 50, 0, 20.0)
    assert rtl.state_name == "return"
    at(rig, 1.0, 0, 20.0)
    sp = current(rig)
    assert rtl.state_name == "descend" and sp.alt == pytest.approx(HOME[2] + 10.0)
    at(rig, 0.5, 0, 10.3)
    assert rtl.state_name == "loiter"
    rig.run(1.0)
    sp = current(rig)
    assert rtl.state_name == "land" and sp.type == SP_LAND and sp.alt == HOME[2]
    at(rig, 0.5, 0, 0.0, landed=True)
    assert rtl.state_name == "landed" and current(rig).type == SP_IDLE


def test_rtl_near_home_does_not_climb_to_return_alt() -> None:
    rig = nav_rig(RTL_RETURN_ALT=60.0, RTL_DESCEND_ALT=10.0, RTL_MIN_DIST=10.0)
    at(rig, 3, 0, 15.0)
    mode(rig, RTL)
    rtl = rig.system.modules.get("navigator").modes[RTL]
    assert rtl.rtl_alt == pytest.approx(HOME[2] + 15.0)
    assert rtl.state_name == "return"


def test_manual_modes_invalidate_the_triplet() -> None:
    rig = nav_rig()
    at(rig, 0, 0, 5.0)
    mode(rig, LOITER)
    assert current(rig).valid
    mode(rig, 2)   # position control
    assert not current(rig).valid


def test_dataman_persists_the_mission() -> None:
    part = MemoryPartition(8192)
    store = MissionStore(part)
    items = [store.new_item(nav_cmd=16, lat=47.0 + i * 1e-4, lon=8.5, altitude=10.0 + i)
             for i in range(5)]
    store.store_mission(items, current_seq=2)
    again = MissionStore(part)
    assert again.load() == "mission of 5 items loaded"
    assert again.count == 5 and again.current_seq == 2
    assert [it.altitude for it in again.items()] == [10.0, 11.0, 12.0, 13.0, 14.0]
    assert math.isnan(again.item(0).yaw) and again.item(0).autocontinue
    part.data[20] ^= 0xFF     # corrupt one item byte
    assert "corrupt" in MissionStore(part).load()
