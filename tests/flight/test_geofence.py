"""The commander's geofence: GF_MAX_HOR_DIST / GF_MAX_VER_DIST from home and the uploaded
polygons and circles (dataman's fence list) with the GF_ACTION reaction, on the hand-fed
commander rig of test_commander."""

from __future__ import annotations

import pytest

from firmware.modules.commander.geofence import inside_polygon
from firmware.modules.dataman.points import (
    FENCE_CIRCLE_EXCLUSION,
    FENCE_CIRCLE_INCLUSION,
    FENCE_POLYGON_EXCLUSION,
    FENCE_POLYGON_INCLUSION,
    Point,
    self_intersecting,
)
from firmware.modules.navigator.geo import offset_deg
from tests.flight.test_commander import ARMED, HOME, LAND, LOITER, POSCTL, RTL, Rig

TERMINATION = 13


def _flying(params: dict[str, float]) -> Rig:
    rig = Rig(params={"COM_FAIL_ACT_T": 0.0, **params})
    rig.run(0.3)
    assert rig.set_mode(3) == 0                    # Position
    assert rig.arm() == 0
    rig.take_off(5.0)
    rig.run(0.3)
    assert rig.status.nav_state == POSCTL
    return rig


def _move(rig: Rig, north_m: float, up_m: float = 5.0) -> None:
    lat, lon = offset_deg(HOME[0], HOME[1], north_m, 0.0)
    rig.set("vehicle_global_position", lat=lat, lon=lon, alt=HOME[2] + up_m)


@pytest.mark.parametrize("action, nav", [(2, LOITER), (3, RTL), (5, LAND), (4, TERMINATION)])
def test_a_horizontal_breach_takes_gf_action(action: int, nav: int) -> None:
    rig = _flying({"GF_MAX_HOR_DIST": 20.0, "GF_ACTION": action})
    _move(rig, 19.0)
    rig.run(0.3)
    assert rig.status.nav_state == POSCTL and not rig.status.failsafe
    _move(rig, 21.0)
    rig.run(0.1)
    assert rig.status.nav_state == nav and rig.status.failsafe
    assert "Maximum distance from home reached (20.0 m)" in rig.dmesg()
    assert "Failsafe: geofence breached" in rig.dmesg()
    assert rig.status.arming_state == ARMED


def test_hold_ends_back_inside_and_warning_only_reports() -> None:
    rig = _flying({"GF_MAX_VER_DIST": 30.0, "GF_ACTION": 2})
    _move(rig, 0.0, up_m=31.0)
    rig.run(0.1)
    assert rig.status.nav_state == LOITER
    assert "Maximum altitude above home reached (30.0 m)" in rig.dmesg()
    _move(rig, 0.0, up_m=25.0)
    rig.run(0.1)
    assert rig.status.nav_state == POSCTL
    warn = _flying({"GF_MAX_HOR_DIST": 20.0, "GF_ACTION": 1})
    _move(warn, 50.0)
    warn.run(0.3)
    assert warn.status.nav_state == POSCTL and not warn.status.failsafe
    assert "Maximum distance from home reached" in warn.dmesg()


def test_no_fence_without_limits_or_on_the_ground() -> None:
    rig = _flying({"GF_ACTION": 2})                 # both limits 0: disabled
    _move(rig, 5000.0, up_m=3000.0)
    rig.run(0.2)
    assert rig.status.nav_state == POSCTL
    ground = Rig(params={"GF_MAX_HOR_DIST": 20.0, "GF_ACTION": 3, "COM_FAIL_ACT_T": 0.0})
    ground.run(0.3)
    assert ground.arm() == 0
    _move(ground, 50.0, up_m=0.0)                   # landed: no reaction
    ground.run(0.3)
    assert not ground.status.failsafe


# -- the uploaded fence (dataman's fence list, issue 21) ----------------------------------------

def _vertices(half_m: float, north_m: float = 0.0) -> list[tuple[int, int]]:
    """A square of ``half_m`` around a point ``north_m`` north of HOME, as degE7 vertices."""
    out = []
    for dn, de in ((-1, -1), (-1, 1), (1, 1), (1, -1)):
        lat, lon = offset_deg(HOME[0], HOME[1], north_m + dn * half_m, de * half_m)
        out.append((round(lat * 1e7), round(lon * 1e7)))
    return out


def _polygon(cmd: int, half_m: float, north_m: float = 0.0) -> list[Point]:
    return [Point(cmd, lat, lon, 0.0, True, 4) for lat, lon in _vertices(half_m, north_m)]


def _circle(cmd: int, north_m: float, radius_m: float) -> Point:
    lat, lon = offset_deg(HOME[0], HOME[1], north_m, 0.0)
    return Point(cmd, round(lat * 1e7), round(lon * 1e7), 0.0, True, 0, radius_m)


def _fenced(points: list[Point], action: int = 2) -> Rig:
    rig = Rig(modules=("dataman", "commander"),
              params={"COM_FAIL_ACT_T": 0.0, "GF_ACTION": action})
    rig.run(0.3)
    rig.system.modules.get("dataman").fence.replace(points)
    assert rig.set_mode(3) == 0
    assert rig.arm() == 0
    rig.take_off(5.0)
    rig.run(0.3)
    return rig


def test_leaving_the_inclusion_polygon_takes_gf_action() -> None:
    rig = _fenced(_polygon(FENCE_POLYGON_INCLUSION, 20.0), action=3)
    _move(rig, 19.0)
    rig.run(0.3)
    assert rig.status.nav_state == POSCTL and not rig.status.failsafe
    _move(rig, 21.0)
    rig.run(0.1)
    assert rig.status.nav_state == RTL and rig.status.failsafe
    assert "Geofence violation" in rig.dmesg()
    assert "Failsafe: geofence breached, return" in rig.dmesg()


def test_entering_an_exclusion_circle_holds_until_out_again() -> None:
    fence = _polygon(FENCE_POLYGON_INCLUSION, 100.0) + [
        _circle(FENCE_CIRCLE_EXCLUSION, 40.0, 10.0)]
    rig = _fenced(fence, action=2)
    _move(rig, 29.0)
    rig.run(0.2)
    assert rig.status.nav_state == POSCTL
    _move(rig, 31.0)
    rig.run(0.1)
    assert rig.status.nav_state == LOITER and rig.status.failsafe
    _move(rig, 25.0)
    rig.run(0.1)
    assert rig.status.nav_state == POSCTL


def test_an_exclusion_polygon_and_an_inclusion_circle_all_must_pass() -> None:
    """PX4's isInsidePolygonOrCircle: every area's check must pass (inside the inclusion
    circle and outside the exclusion polygon)."""
    fence = [_circle(FENCE_CIRCLE_INCLUSION, 0.0, 60.0)] + \
        _polygon(FENCE_POLYGON_EXCLUSION, 5.0, north_m=30.0)
    rig = _fenced(fence, action=5)
    _move(rig, 30.0)
    rig.run(0.1)
    assert rig.status.nav_state == LAND
    ok = _fenced(fence, action=5)
    _move(ok, -30.0)
    ok.run(0.2)
    assert ok.status.nav_state == POSCTL
    far = _fenced(fence, action=5)
    _move(far, -61.0)
    far.run(0.1)
    assert far.status.nav_state == LAND


def test_an_area_without_home_is_dropped_as_px4_does() -> None:
    rig = _fenced(_polygon(FENCE_POLYGON_INCLUSION, 5.0, north_m=100.0), action=2)
    assert "Geofence invalid, doesn't contain Home position" in rig.dmesg()
    assert rig.status.nav_state == POSCTL and not rig.status.failsafe
    assert rig.system.modules.get("commander").geofence.areas == []


def test_pnpoly_and_self_intersection() -> None:
    square = [(0.0, 0.0), (0.0, 1.0), (1.0, 1.0), (1.0, 0.0)]
    assert inside_polygon(0.5, 0.5, square) and not inside_polygon(1.5, 0.5, square)
    assert not self_intersecting([(0, 0), (0, 10), (10, 10), (10, 0)])
    assert self_intersecting([(0, 0), (10, 10), (10, 0), (0, 10)])           # bow-tie
    assert self_intersecting([(0, 0), (0, 10), (0, 5)])                      # folds back
    assert self_intersecting([(0, 0), (0, 10), (10, 10), (0, 10)])           # repeated vertex
    assert self_intersecting([(0, 0), (5, 5), (10, 10)])                     # no area
    assert not self_intersecting([(0, 0), (0, 10), (5, 5), (10, 10), (10, 0)])  # concave
