"""Fuzz target for the set-up pages' requests (AVAILABLE_MODES with any index,
COMPONENT_METADATA / COMPONENT_INFORMATION / CURRENT_MODE with any other parameters) through a
booted FMU's link: exactly one COMMAND_ACK, the right number of AVAILABLE_MODES, no handler
error."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from firmware.modules.commander.modes import VALID_NAV_STATES
from tests.fuzzing import fuzz
from tests.gcs.helpers import use_dialect
from tests.mavlink.conftest import open_session

_FLOATS = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=32),
                    st.sampled_from([0.0, 1.0, 14.0, 15.0, -1.0, 0.5, 1.5, 255.0, 1e9]))
_IDS = st.sampled_from([435, 436, 437, 395, 397])


@pytest.fixture(scope="module")
def fmu(tmp_path_factory):
    s = open_session(tmp_path_factory.mktemp("fuzz_setup_pages"))
    s.mav = use_dialect(s.gcs)
    s.gcs.wait_heartbeat()
    yield s
    s.close()


@fuzz(examples=25)
@given(msg_id=_IDS, params=st.lists(_FLOATS, min_size=6, max_size=6))
def test_requests_get_one_ack_and_the_promised_messages(fmu: Any, msg_id: int,
                                                        params: list[float]) -> None:
    mav = fmu.mav
    gcs = fmu.gcs
    inst = fmu.udp_instance()
    errors = inst.rx_handler_errors
    mark = gcs.mark()
    ack = gcs.command_long(mav.MAV_CMD_REQUEST_MESSAGE, [msg_id, *params], retries=0)
    gcs.step(0.03)
    acks = [m for m in gcs.messages("COMMAND_ACK", mark)
            if m.command == mav.MAV_CMD_REQUEST_MESSAGE]
    assert len(acks) == 1 and acks[0].result == ack.result
    modes = gcs.messages("AVAILABLE_MODES", mark)
    if msg_id == 435:
        n = len(VALID_NAV_STATES)
        want = 0
        if math.isfinite(params[0]):
            index = math.floor(abs(params[0]) + 0.5) * (1 if params[0] >= 0 else -1)  # roundf
            want = n if index == 0 else 1 if 1 <= index <= n else 0
        assert len(modes) == want
        assert ack.result == (mav.MAV_RESULT_ACCEPTED if want else mav.MAV_RESULT_DENIED)
    else:
        assert modes == []
        assert ack.result in (mav.MAV_RESULT_ACCEPTED, mav.MAV_RESULT_UNSUPPORTED,
                              mav.MAV_RESULT_TEMPORARILY_REJECTED)
    assert inst.rx_handler_errors == errors
