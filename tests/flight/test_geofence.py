"""The commander's geofence: GF_MAX_HOR_DIST / GF_MAX_VER_DIST from home with the GF_ACTION
reaction, on the hand-fed commander rig of test_commander."""

from __future__ import annotations

import pytest

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
