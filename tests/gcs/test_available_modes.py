"""AVAILABLE_MODES / CURRENT_MODE / AVAILABLE_MODES_MONITOR as PX4 1.15 sends them, and
SYS_STATUS's load from cpuload, against a booted FMU with the commander over its UDP link
(pymavlink with the development dialect)."""

import pytest

from firmware.modules.commander import modes as nav
from tests.gcs.helpers import use_dialect
from tests.mavlink.conftest import open_commander_session

mav = None


@pytest.fixture(scope="module")
def vehicle(tmp_path_factory):
    global mav
    s = open_commander_session(tmp_path_factory.mktemp("modes"))
    mav = use_dialect(s.gcs)
    yield s
    s.close()


def _request_modes(gcs, index):
    mark = gcs.mark()
    ack = gcs.command_long(mav.MAV_CMD_REQUEST_MESSAGE,
                           [mav.MAVLINK_MSG_ID_AVAILABLE_MODES, index])
    gcs.step(0.05)
    return ack, gcs.messages("AVAILABLE_MODES", mark)


def test_all_modes_listed_with_standard_modes_names_and_properties(vehicle):
    ack, msgs = _request_modes(vehicle.gcs, 0)
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    n = len(nav.VALID_NAV_STATES)
    assert [m.mode_index for m in msgs] == list(range(1, n + 1))
    assert {m.number_modes for m in msgs} == {n}
    # in navigation-state order; each with the HEARTBEAT's custom mode (Descend shares Land's
    # and Termination Manual's, as in PX4's get_px4_custom_mode)
    by_nav = dict(zip(nav.VALID_NAV_STATES, msgs, strict=True))
    for n_state, m in by_nav.items():
        main, sub = nav.nav_to_custom(n_state)
        assert m.custom_mode == (main << 16) | (sub << 24), n_state

    def mode(main, sub=0):
        return by_nav[nav.custom_to_nav(main, sub)]

    pos, alt = mode(3), mode(2)
    assert pos.standard_mode == mav.MAV_STANDARD_MODE_POSITION_HOLD and pos.properties == 0
    assert alt.standard_mode == mav.MAV_STANDARD_MODE_ALTITUDE_HOLD and alt.properties == 0
    assert mode(4, 4).standard_mode == mav.MAV_STANDARD_MODE_MISSION
    assert mode(4, 5).standard_mode == mav.MAV_STANDARD_MODE_SAFE_RECOVERY
    assert mode(4, 2).standard_mode == mav.MAV_STANDARD_MODE_TAKEOFF
    assert mode(4, 6).standard_mode == mav.MAV_STANDARD_MODE_LAND
    hold = mode(4, 3)
    assert hold.standard_mode == mav.MAV_STANDARD_MODE_NON_STANDARD
    assert hold.mode_name == "Hold" and hold.properties == mav.MAV_MODE_PROPERTY_ADVANCED
    assert mode(6).mode_name == "Offboard" and mode(7).mode_name == "Stabilized"
    assert pos.mode_name == ""               # standard modes carry no name (PX4)
    precland = mode(4, 9)
    assert precland.mode_name == "Precision Landing"
    assert precland.properties & mav.MAV_MODE_PROPERTY_NOT_USER_SELECTABLE
    assert by_nav[nav.TERMINATION].mode_name == "Termination"
    assert sum(1 for m in msgs if m.properties & mav.MAV_MODE_PROPERTY_NOT_USER_SELECTABLE) == 1


def test_one_mode_by_index_and_bad_indices_denied(vehicle):
    ack, msgs = _request_modes(vehicle.gcs, 3)
    assert ack.result == mav.MAV_RESULT_ACCEPTED and len(msgs) == 1
    assert msgs[0].mode_index == 3 and msgs[0].custom_mode == 3 << 16   # POSCTL, 3rd state
    for bad in (len(nav.VALID_NAV_STATES) + 1, -1, float("nan")):
        ack, msgs = _request_modes(vehicle.gcs, bad)
        assert ack.result == mav.MAV_RESULT_DENIED and msgs == []


def test_current_mode_on_change_and_at_half_a_hertz(vehicle):
    gcs = vehicle.gcs
    assert gcs.set_mode(1).result == mav.MAV_RESULT_ACCEPTED       # Manual
    gcs.step(0.1)
    mark = gcs.mark()
    assert gcs.set_mode(3).result == mav.MAV_RESULT_ACCEPTED       # Position (or Manual: no fix)
    m = gcs.wait_message("CURRENT_MODE", since=mark, timeout_s=0.2)  # at once, not in 2 s
    status = vehicle.topic("vehicle_status")
    assert m.custom_mode >> 16 == {0: 1, 2: 3}[status["nav_state"]]
    assert m.intended_custom_mode == 3 << 16
    mark = gcs.mark()
    gcs.step(4.1)
    periodic = gcs.messages("CURRENT_MODE", mark)
    assert 2 <= len(periodic) <= 3, len(periodic)                 # PX4's 0.5 Hz


def test_monitor_only_after_the_set_of_modes_changed(vehicle):
    gcs = vehicle.gcs
    mark = gcs.mark()
    gcs.step(3.5)
    assert gcs.messages("AVAILABLE_MODES_MONITOR", mark) == []    # nothing changed since boot
    svc = vehicle.udp_instance().available_modes
    # what an external mode's registration does in PX4: the selectable set changes
    svc.selectable = svc.selectable - {nav.OFFBOARD}
    mark = gcs.mark()
    gcs.step(3.5)
    mons = gcs.messages("AVAILABLE_MODES_MONITOR", mark)
    assert mons and {m.seq for m in mons} == {1}                   # 0.3 Hz, one change
    _, msgs = _request_modes(gcs, 0)
    off = next(m for m in msgs if m.custom_mode == 6 << 16)
    assert off.properties & mav.MAV_MODE_PROPERTY_NOT_USER_SELECTABLE
    svc.selectable = svc.selectable | {nav.OFFBOARD}
    mark = gcs.mark()
    gcs.step(3.5)
    assert {m.seq for m in gcs.messages("AVAILABLE_MODES_MONITOR", mark)} == {2}


def test_sys_status_load_is_cpuload_in_permille(vehicle):
    """SYS_STATUS.load is load_mon's cpuload (PX4), not a figure of the link's own."""
    gcs = vehicle.gcs
    gcs.step(1.0)
    before = vehicle.topic("cpuload")["load"]
    assert 0.0 < before < 1.0
    mark = gcs.mark()
    ack = gcs.command_long(mav.MAV_CMD_REQUEST_MESSAGE, [mav.MAVLINK_MSG_ID_SYS_STATUS])
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    m = gcs.wait_message("SYS_STATUS", since=mark)
    after = vehicle.topic("cpuload")["load"]
    assert m.load in {round(before * 1000), round(after * 1000)}
