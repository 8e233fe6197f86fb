"""Mode changes from a ground station: SET_MODE (#11) and MAV_CMD_DO_SET_MODE take the same
path (PX4's receiver turns SET_MODE into DO_SET_MODE), with the same refusals and the same
COMMAND_ACK (command 176), for every main mode; the HEARTBEAT reports the new custom mode."""

from __future__ import annotations

from typing import Any

import pytest
from pymavlink.dialects.v20 import common as mav

from tests.mavlink.conftest import open_commander_session

CUSTOM = mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
#: PX4 custom (main, sub) modes settable on the ground without a mission
MODES = {"manual": (1, 0), "altctl": (2, 0), "posctl": (3, 0), "acro": (5, 0),
         "stabilized": (7, 0), "takeoff": (4, 2), "hold": (4, 3), "return": (4, 5),
         "land": (4, 6)}


def _text(m: Any) -> str:
    return m.text if isinstance(m.text, str) else m.text.decode("latin-1")


def custom_mode(main: int, sub: int) -> int:
    """PX4's px4_custom_mode: main mode in bits 16-23, sub mode in bits 24-31."""
    return (main << 16) | (sub << 24)


@pytest.fixture(scope="module")
def vehicle(tmp_path_factory):
    s = open_commander_session(tmp_path_factory.mktemp("modes"))
    yield s
    s.close()


def set_mode_msg(gcs: Any, base: int, main: int, sub: int, target: int = 1) -> Any:
    """Send SET_MODE and return its COMMAND_ACK (DO_SET_MODE's id), or None within 0.5 s."""
    mark = gcs.mark()
    gcs.send(mav.MAVLink_set_mode_message(target, base, custom_mode(main, sub)))
    gcs.step(0.5)
    acks = [a for a in gcs.messages("COMMAND_ACK", mark)
            if a.command == mav.MAV_CMD_DO_SET_MODE]
    assert len(acks) <= 1, acks
    return acks[0] if acks else None


def _heartbeat_mode(gcs: Any) -> tuple[int, int]:
    gcs.step(1.1)  # HEARTBEAT at 1 Hz
    hb = gcs.last["HEARTBEAT"]
    return (hb.custom_mode >> 16) & 0xFF, (hb.custom_mode >> 24) & 0xFF


@pytest.mark.parametrize("name", list(MODES))
def test_every_main_mode_by_set_mode_and_by_command(vehicle, name):
    gcs = vehicle.gcs
    main, sub = MODES[name]
    gcs.set_mode(1)  # from Manual each time
    ack = set_mode_msg(gcs, CUSTOM, main, sub)
    assert ack is not None and ack.result == mav.MAV_RESULT_ACCEPTED
    assert ack.target_system == 255
    assert _heartbeat_mode(gcs) == (main, sub)
    assert gcs.set_mode(1).result == mav.MAV_RESULT_ACCEPTED
    assert gcs.set_mode(main, sub).result == mav.MAV_RESULT_ACCEPTED
    assert _heartbeat_mode(gcs) == (main, sub)


def test_set_mode_refused_as_the_command_is(vehicle):
    """Mission without a mission: both paths refuse with TEMPORARILY_REJECTED and the
    commander's reason; the mode stays."""
    gcs = vehicle.gcs
    gcs.set_mode(1)
    mark = gcs.mark()
    ack = set_mode_msg(gcs, CUSTOM, 4, 4)
    assert ack.result == mav.MAV_RESULT_TEMPORARILY_REJECTED
    assert gcs.set_mode(4, 4).result == mav.MAV_RESULT_TEMPORARILY_REJECTED
    gcs.step(0.2)
    text = "".join(_text(m) for m in gcs.messages("STATUSTEXT", mark))  # chunked at 50
    assert text.count("Switching to Mission is currently not possible") == 2, text
    assert _heartbeat_mode(gcs) == (1, 0)


def test_set_mode_auto_without_sub_mode_is_mission_and_unknown_modes_are_refused(vehicle):
    """PX4: main mode AUTO with sub mode 0 means Mission (refused here: no mission); an
    unknown main mode is not acted on."""
    gcs = vehicle.gcs
    gcs.set_mode(1)
    assert set_mode_msg(gcs, CUSTOM, 4, 0).result == mav.MAV_RESULT_TEMPORARILY_REJECTED
    assert set_mode_msg(gcs, CUSTOM, 99, 0).result == mav.MAV_RESULT_UNSUPPORTED
    assert _heartbeat_mode(gcs) == (1, 0)


def test_set_mode_by_base_mode_flags_only(vehicle):
    """Without MAV_MODE_FLAG_CUSTOM_MODE_ENABLED the base mode decides (PX4): manual input +
    guided is Position."""
    gcs = vehicle.gcs
    gcs.set_mode(1)
    base = mav.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | mav.MAV_MODE_FLAG_GUIDED_ENABLED
    assert set_mode_msg(gcs, base, 0, 0).result == mav.MAV_RESULT_ACCEPTED
    assert _heartbeat_mode(gcs) == (3, 0)


def test_set_mode_armed_needs_what_the_mode_needs(vehicle):
    """Armed (forced: this board has no sensors), Position needs a position estimate: SET_MODE
    is refused exactly as DO_SET_MODE is."""
    gcs = vehicle.gcs
    gcs.set_mode(1)
    assert gcs.arm(force=True).result == mav.MAV_RESULT_ACCEPTED
    try:
        assert set_mode_msg(gcs, CUSTOM, 3, 0).result == mav.MAV_RESULT_TEMPORARILY_REJECTED
        assert gcs.set_mode(3).result == mav.MAV_RESULT_TEMPORARILY_REJECTED
    finally:
        assert gcs.disarm(force=True).result == mav.MAV_RESULT_ACCEPTED


def test_set_mode_for_another_system_ignored(vehicle):
    gcs = vehicle.gcs
    gcs.set_mode(1)
    before = vehicle.counters()["rx_not_for_us"]
    assert set_mode_msg(gcs, CUSTOM, 3, 0, target=42) is None
    assert vehicle.counters()["rx_not_for_us"] == before + 1
    assert _heartbeat_mode(gcs) == (1, 0)


# -- a second flight (issue 21) --------------------------------------------------------------

@pytest.mark.slow
def test_land_disarm_arm_again_and_fly_again(hil_vehicle):
    """The whole vehicle (boards, world, RC, GCS over pymavlink): take off, Land (auto), the
    commander disarms after landing and switches back to Hold (PX4), so arming is accepted
    again and a second takeoff climbs. It used to stay in Land and refuse: "arming not
    possible in Land mode"."""
    v = hil_vehicle
    gcs = v.gcs
    v.wait_for("home_set", within=40.0, step=0.2)
    # as hil/flight.py's pilot: 0.1 s ahead (the switch has already played up to the
    # lookahead; HilVehicle.press_safety presses at t_ns, which it refuses as past)
    v.dev["safety"].press(v.orch.t_ns + 100_000_000, hold_s=1.5)
    v.wait_for("topic.px4io_status.status_safety_off", within=5.0)
    for flight in (1, 2):
        assert gcs.arm(timeout_s=2.0).result == mav.MAV_RESULT_ACCEPTED, flight
        assert gcs.takeoff(3.0).result == mav.MAV_RESULT_ACCEPTED
        v.wait_for("alt_agl_m > 2.5", within=15.0, step=0.1)
        assert gcs.land().result == mav.MAV_RESULT_ACCEPTED
        v.wait_for("not armed", within=20.0, step=0.1)
        assert v.read("on_ground")
        assert v.read("nav_state").lower() == "hold"
