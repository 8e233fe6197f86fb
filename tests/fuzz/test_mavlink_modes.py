"""Fuzz target for SET_MODE (#11): any base mode and any 32-bit custom mode, for this vehicle
or another, through a real link of one booted FMU."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mav

from tests.fuzzing import fuzz
from tests.mavlink.conftest import open_commander_session

#: PX4 main modes 0..8 and AUTO's sub modes 0..10 often; any byte and any word too
_CUSTOM = st.one_of(
    st.builds(lambda main, sub: (main << 16) | (sub << 24), st.integers(0, 9),
              st.integers(0, 10)),
    st.integers(0, 2**32 - 1))


@pytest.fixture(scope="module")
def fmu(tmp_path_factory):
    s = open_commander_session(tmp_path_factory.mktemp("fuzz_set_mode"))
    yield s
    s.close()


@fuzz(examples=40)
@given(target=st.sampled_from([0, 1, 1, 7]), base=st.integers(0, 255), custom=_CUSTOM,
       armed=st.booleans())
def test_set_mode_answers_once_or_not_at_all(fmu: Any, target: int, base: int, custom: int,
                                             armed: bool) -> None:
    """Invariant: SET_MODE never makes a handler raise; for this vehicle (target 0 or 1) it
    gets exactly one COMMAND_ACK for DO_SET_MODE with a result PX4 gives (accepted, rejected,
    unsupported), for another none; the FMU keeps running and reports a custom mode whose
    main mode is one of PX4's."""
    gcs = fmu.gcs
    inst = fmu.udp_instance()
    errors, since_us = inst.rx_handler_errors, fmu.dmesg_mark()
    if armed:
        gcs.command_long(400, [1.0, 21196.0])
    mark = gcs.mark()
    gcs.send(mav.MAVLink_set_mode_message(target, base, custom))
    gcs.step(0.05)
    acks = [a for a in gcs.messages("COMMAND_ACK", mark) if a.command == 176]
    gcs.command_long(400, [0.0, 21196.0])  # disarm (forced) whatever it did
    gcs.command_long(176, [1.0, 1.0, 0.0])  # back to Manual
    assert not fmu.orch.dead, fmu.orch.dead
    assert fmu.mavlink_errors(since_us) == [] and inst.rx_handler_errors == errors
    if target in (0, 1):
        assert len(acks) == 1, acks
        assert acks[0].result in (mav.MAV_RESULT_ACCEPTED, mav.MAV_RESULT_TEMPORARILY_REJECTED,
                                  mav.MAV_RESULT_UNSUPPORTED)
    else:
        assert acks == []
    status = fmu.topic("vehicle_status")
    assert status["nav_state"] in (0, 1, 2, 3, 4, 5, 10, 12, 13, 14, 15, 17, 18, 20)


@fuzz(examples=40)
@given(sticks=st.lists(st.tuples(*[st.integers(-32768, 32767)] * 4), min_size=1, max_size=4),
       target=st.sampled_from([0, 1, 7]))
def test_manual_control_stays_in_range(fmu: Any, sticks: list, target: int) -> None:
    """Invariant: MANUAL_CONTROL with any int16 axes never makes a handler raise; what the
    selector publishes on manual_control_setpoint (the joystick is the first source on this
    board without RC) is a valid MAVLink input with every axis within -1..1."""
    gcs = fmu.gcs
    inst = fmu.udp_instance()
    errors, since_us = inst.rx_handler_errors, fmu.dmesg_mark()
    for x, y, z, r in sticks:
        gcs.send(mav.MAVLink_manual_control_message(target, x, y, z, r, 0))
        gcs.step(0.02)
    assert fmu.mavlink_errors(since_us) == [] and inst.rx_handler_errors == errors
    m = fmu.topic("manual_control_setpoint")
    if m is not None:
        assert m["data_source"] >= 2 and m["valid"]
        assert all(-1.0 <= m[a] <= 1.0 for a in ("roll", "pitch", "yaw", "throttle"))
