"""PREFLIGHT_CALIBRATION with any parameters a ground station may send (NaN, infinities,
huge, negative, fractional): exactly one COMMAND_ACK each, a result MAVLink defines for it,
never a crash; a calibration it starts is cancelled by QGC's all-zero command."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mav

from tests.calibration.conftest import CAL
from tests.fuzzing import fuzz

values = st.one_of(st.sampled_from([0.0, 1.0, 2.0, 3.0, 4.0, -1.0, 0.5, 1.4999, math.nan,
                                    math.inf, -math.inf, 1e30, -1e30]),
                   st.floats(width=32, allow_nan=True, allow_infinity=True))
RESULTS = {mav.MAV_RESULT_ACCEPTED, mav.MAV_RESULT_DENIED, mav.MAV_RESULT_UNSUPPORTED}


@fuzz(examples=40)
@given(params=st.lists(values, min_size=7, max_size=7))
def test_random_calibration_parameters(rig, params: list[float]) -> None:
    gcs = rig.gcs
    mark = gcs.mark()
    gcs.send(mav.MAVLink_command_long_message(1, 1, CAL, 0, *params))
    gcs.step(0.03)
    acks = [a for a in gcs.messages("COMMAND_ACK", mark) if a.command == CAL]
    assert len(acks) == 1 and acks[0].result in RESULTS, (params, acks)
    runner = next((w for w in rig.board.system.modules.get("commander").work_items
                   if type(w).__name__ == "CalibrationRunner"), None)
    if runner is not None and runner.busy:
        assert acks[0].result == mav.MAV_RESULT_ACCEPTED
        assert rig.calibrate(0, 0, 0, 0, 0, 0, 0).result == mav.MAV_RESULT_ACCEPTED
        gcs.step(0.02)
        assert not runner.busy
    assert not rig.orch.dead
