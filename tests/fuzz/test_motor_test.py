"""Fuzz target for the Motors page's commands: random DO_MOTOR_TEST and ACTUATOR_TEST
parameters through a booted FMU's link with the commander running."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mav

from tests.fuzzing import fuzz
from tests.mavlink.conftest import open_commander_session

RESULTS = (mav.MAV_RESULT_ACCEPTED, mav.MAV_RESULT_DENIED, mav.MAV_RESULT_UNSUPPORTED)
_P = st.one_of(st.integers(-2, 300).map(float), st.floats(width=32))


@pytest.fixture(scope="module")
def fmu(tmp_path_factory):
    s = open_commander_session(tmp_path_factory.mktemp("fuzz_motor_test"))
    yield s
    s.close()


@fuzz(examples=40)
@given(command=st.sampled_from([mav.MAV_CMD_DO_MOTOR_TEST, mav.MAV_CMD_ACTUATOR_TEST]),
       p=st.tuples(_P, _P, _P, _P, _P))
def test_motor_test_gets_one_ack_and_a_bounded_test(fmu: Any, command: int, p: tuple) -> None:
    """Invariant: exactly one COMMAND_ACK (accepted, denied or unsupported), no handler error,
    and whatever test_motor went out is a motor 0..7, a value 0..1 and a timeout 1..3000 ms."""
    gcs = fmu.gcs
    inst = fmu.udp_instance()
    errors, since_us = inst.rx_handler_errors, fmu.dmesg_mark()
    mark = gcs.mark()
    gcs.send(mav.MAVLink_command_long_message(1, 1, command, 0, *p[:4], p[4], 0, 0))
    gcs.step(0.05)
    acks = [a for a in gcs.messages("COMMAND_ACK", mark) if a.command == command]
    assert len(acks) == 1 and acks[0].result in RESULTS, acks
    assert inst.rx_handler_errors == errors and not fmu.mavlink_errors(since_us)
    tm = fmu.topic("test_motor")
    if tm is not None:
        assert 0 <= tm["motor_number"] < 8 and 0.0 <= tm["value"] <= 1.0
        assert 1 <= tm["timeout_ms"] <= 3000
