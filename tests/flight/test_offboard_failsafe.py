"""Offboard-loss reaction and Offboard's control flags (firmware.modules.commander), as PX4
1.14's Failsafe::checkModeFallback and ModeUtil's control_mode decide them."""

import pytest

from firmware.modules.commander import failsafe as fs
from firmware.modules.commander import modes

ALL = {"manual": True, "alt": True, "lpos": True, "gpos": True, "home": True}
NO_RC = ALL | {"manual": False}


@pytest.mark.parametrize(("act", "ok", "nav"), [
    (0, ALL, modes.POSCTL), (1, ALL, modes.ALTCTL), (2, ALL, modes.STAB),
    (3, ALL, modes.AUTO_RTL), (4, ALL, modes.AUTO_LAND), (5, ALL, modes.AUTO_LOITER),
    (6, ALL, modes.TERMINATION), (7, ALL, None), (99, ALL, modes.POSCTL),
    # no manual control: the manual modes cannot run, PX4 returns instead
    (0, NO_RC, modes.AUTO_RTL), (1, NO_RC, modes.AUTO_RTL), (2, NO_RC, modes.AUTO_RTL),
    (5, NO_RC, modes.AUTO_LOITER),
    # RC but no position: Position falls to Altitude
    (0, ALL | {"lpos": False}, modes.ALTCTL),
])
def test_offboard_loss_mode(act, ok, nav):
    assert fs.offboard_loss_nav(act, ok) == nav


def test_offboard_flags_follow_what_is_controlled():
    def flags(**kw):
        given = {k: kw.get(k, False) for k in
                 ("position", "velocity", "acceleration", "attitude", "body_rate")}
        return modes.control_flags(modes.OFFBOARD, modes.offboard_flags(**given))

    pos = flags(position=True, velocity=True)
    assert pos["flag_control_position_enabled"] and pos["flag_control_offboard_enabled"]
    vel = flags(velocity=True)
    assert not vel["flag_control_position_enabled"] and vel["flag_control_velocity_enabled"]
    assert vel["flag_control_climb_rate_enabled"]
    att = flags(attitude=True)
    assert att["flag_control_attitude_enabled"] and not att["flag_control_climb_rate_enabled"]
    assert not att["flag_multicopter_position_control_enabled"]
    rates = flags(body_rate=True)
    assert rates["flag_control_rates_enabled"] and not rates["flag_control_attitude_enabled"]
    assert not flags(acceleration=True)["flag_control_velocity_enabled"]
