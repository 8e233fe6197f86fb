"""A mission with an item outside the uploaded fence is not flown (PX4's feasibility check
against the geofence, with GF_ACTION above None): the navigator marks it invalid with
"Geofence violation for waypoint N" and holds instead of starting it; with GF_ACTION None, or
every item inside, the same mission is valid. Navigator and dataman on the rig of
tests/flight (hand-published vehicle_status and position)."""

from __future__ import annotations

from firmware.modules.dataman.points import FENCE_POLYGON_EXCLUSION, FENCE_POLYGON_INCLUSION, Point
from firmware.modules.navigator.geo import offset_deg
from tests.flight.test_commander import HOME
from tests.flight.test_navigator import MISSION, current, mode, nav_rig

SP_LOITER = 2


def _square(cmd: int, half_m: float, north_m: float = 0.0) -> list[Point]:
    out = []
    for dn, de in ((-1, -1), (-1, 1), (1, 1), (1, -1)):
        lat, lon = offset_deg(HOME[0], HOME[1], north_m + dn * half_m, de * half_m)
        out.append(Point(cmd, round(lat * 1e7), round(lon * 1e7), 0.0, True, 4))
    return out


def _mission(rig, north_m: float) -> None:
    store = rig.system.modules.get("dataman").store
    wp = offset_deg(HOME[0], HOME[1], north_m, 0.0)
    store.store_mission([
        store.new_item(nav_cmd=22, lat=HOME[0], lon=HOME[1], altitude=10.0,
                       altitude_is_relative=True),
        store.new_item(nav_cmd=16, lat=HOME[0], lon=HOME[1], altitude=10.0,
                       altitude_is_relative=True),
        store.new_item(nav_cmd=16, lat=wp[0], lon=wp[1], altitude=10.0,
                       altitude_is_relative=True),
    ])
    rig.run(0.1)


def test_item_outside_the_inclusion_fence_makes_the_mission_invalid() -> None:
    rig = nav_rig(GF_ACTION=2)
    rig.system.modules.get("dataman").fence.replace(_square(FENCE_POLYGON_INCLUSION, 30.0))
    _mission(rig, 60.0)                       # waypoint 3 is 30 m beyond the fence
    assert not rig.last("mission_result").valid
    errors = [text for _t, sev, module, text in rig.platform.dmesg
              if module == "navigator" and sev <= 3]
    assert "Geofence violation for waypoint 3" in errors, errors
    mode(rig, MISSION)
    assert current(rig).type == SP_LOITER    # holds: the mission does not start
    _mission(rig, 20.0)                       # inside: valid
    assert rig.last("mission_result").valid


def test_exclusion_area_and_gf_action_none() -> None:
    rig = nav_rig(GF_ACTION=2)
    rig.system.modules.get("dataman").fence.replace(
        _square(FENCE_POLYGON_EXCLUSION, 5.0, north_m=40.0))
    _mission(rig, 40.0)                       # the waypoint inside a no-fly square
    assert not rig.last("mission_result").valid
    rig.params.set("GF_ACTION", 0)            # no reaction to a breach: no check either
    rig.run(0.2)
    _mission(rig, 40.0)
    assert rig.last("mission_result").valid


def test_fence_uploaded_after_the_mission_is_checked_when_it_starts() -> None:
    rig = nav_rig(GF_ACTION=3)
    _mission(rig, 60.0)
    assert rig.last("mission_result").valid
    rig.system.modules.get("dataman").fence.replace(_square(FENCE_POLYGON_INCLUSION, 30.0))
    mode(rig, MISSION)
    assert not rig.last("mission_result").valid
    assert current(rig).type == SP_LOITER
