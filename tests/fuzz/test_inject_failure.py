"""Fuzz targets for MAV_CMD_INJECT_FAILURE: random parameters through a booted FMU's link
(with the orchestrator's fault injector installed, SYS_FAILURE_EN on or off), and random
requests straight into the injector's hook."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mav

from hil.faults import Injector
from hil.faults.inject_failure import FAILURE_TYPES, FAILURE_UNITS, FailureInjection
from tests.fuzzing import fuzz
from tests.mavlink.conftest import open_session

CMD = mav.MAV_CMD_INJECT_FAILURE
RESULTS = (mav.MAV_RESULT_ACCEPTED, mav.MAV_RESULT_DENIED, mav.MAV_RESULT_UNSUPPORTED,
           mav.MAV_RESULT_FAILED)
#: known units and types often, any float (NaN, infinities, huge, fractional) too
_PARAM = st.one_of(st.sampled_from(sorted(FAILURE_UNITS)), st.sampled_from(sorted(FAILURE_TYPES)),
                   st.integers(-3, 300).map(float), st.floats(width=32))


@pytest.fixture(scope="module")
def fmu(tmp_path_factory):
    s = open_session(tmp_path_factory.mktemp("fuzz_inject_failure"))
    s.gcs.wait_heartbeat()
    s.injector = Injector(s.orch, {"gcs": s.gcs}).install()
    yield s
    s.close()


@fuzz(examples=60)
@given(p=st.tuples(_PARAM, _PARAM, _PARAM, st.floats(width=32)), enabled=st.booleans(),
       as_int=st.booleans())
def test_inject_failure_gets_exactly_one_ack(fmu: Any, p: tuple, enabled: bool,
                                             as_int: bool) -> None:
    """Invariant: any INJECT_FAILURE, as COMMAND_LONG or COMMAND_INT, gets exactly one
    COMMAND_ACK with one of the four results within 50 ms (DENIED whenever SYS_FAILURE_EN
    is 0), no handler raises, the FMU keeps running; and whatever it started can be undone."""
    gcs, inj = fmu.gcs, fmu.injector
    inst = fmu.udp_instance()
    errors, since_us = inst.rx_handler_errors, fmu.dmesg_mark()
    fmu.shell(f"param set SYS_FAILURE_EN {int(enabled)}")
    mark = gcs.mark()
    if as_int:
        gcs.send(mav.MAVLink_command_int_message(1, 1, mav.MAV_FRAME_LOCAL_NED, CMD, 0, 0,
                                                 *p, 0, 0, 0.0))
    else:
        gcs.send(mav.MAVLink_command_long_message(1, 1, CMD, 0, *p, 0.0, 0.0, 0.0))
    gcs.step(0.05)
    acks = [a for a in gcs.messages("COMMAND_ACK", mark) if a.command == CMD]
    for af in inj.history:
        inj.stop(af)
    assert not fmu.orch.dead, fmu.orch.dead
    assert fmu.mavlink_errors(since_us) == [] and inst.rx_handler_errors == errors
    assert len(acks) == 1, acks
    assert acks[0].result in RESULTS
    if not enabled:
        assert acks[0].result == mav.MAV_RESULT_DENIED
    if any(not math.isfinite(x) for x in p[:3]):
        assert acks[0].result == mav.MAV_RESULT_DENIED


class _Orch:
    t_ns = 0
    on_quantum: list = []
    request_hooks: dict = {}

    def call(self, *args: Any) -> None:
        pass


@fuzz(examples=800)
@given(payload=st.one_of(
    st.tuples(st.integers(0, 0xFFFF), st.integers(-5, 300), st.integers(-5, 10),
              st.integers(-5, 300)),
    st.lists(st.one_of(st.integers(), st.floats(), st.text(max_size=3), st.none()),
             max_size=6).map(tuple),
    st.none(), st.text(max_size=5)))
def test_the_hook_never_raises(payload: Any) -> None:
    """Invariant: the orchestrator's hook answers any payload with (seq, result, text), a
    known MAV_RESULT, and never raises (a rig without the devices gives FAILED)."""
    fi = FailureInjection(Injector(_Orch(), {}))
    seq, result, text = fi.handle("fmu", payload)
    assert result in RESULTS and isinstance(text, str) and isinstance(seq, int)
