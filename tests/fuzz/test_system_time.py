"""Fuzz target for SYSTEM_TIME from a GCS: any uint64 UTC and uint32 boot time through a
booted FMU's link."""

from __future__ import annotations

from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mav

from firmware.modules.mavlink.systime import PX4_EPOCH_US
from tests.fuzzing import fuzz
from tests.mavlink.conftest import open_session

_UTC = st.one_of(st.integers(0, (1 << 64) - 1), st.sampled_from([0, PX4_EPOCH_US,
                                                                  PX4_EPOCH_US + 1]))


@pytest.fixture(scope="module")
def fmu(tmp_path_factory):
    s = open_session(tmp_path_factory.mktemp("fuzz_system_time"))
    s.gcs.wait_heartbeat()
    yield s
    s.close()


@fuzz(examples=40)
@given(utc_us=_UTC, boot_ms=st.integers(0, (1 << 32) - 1))
def test_gcs_system_time_never_breaks_the_clock(fmu: Any, utc_us: int, boot_ms: int) -> None:
    """Invariant: no handler raises; the vehicle's SYSTEM_TIME still comes (REQUEST_MESSAGE
    ACCEPTED) with a UTC that is 0 (unknown) or after PX4's epoch, and a GCS sets it at
    most once."""
    gcs = fmu.gcs
    inst = fmu.udp_instance()
    errors = inst.rx_handler_errors
    gcs.send(mav.MAVLink_system_time_message(utc_us, boot_ms))
    gcs.step(0.02)
    mark = gcs.mark()
    ack = gcs.command_long(mav.MAV_CMD_REQUEST_MESSAGE, [mav.MAVLINK_MSG_ID_SYSTEM_TIME])
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    m = gcs.wait_message("SYSTEM_TIME", since=mark)
    assert m.time_unix_usec == 0 or m.time_unix_usec > PX4_EPOCH_US
    assert inst.rx_handler_errors == errors
    assert inst.systime.clock_sets <= 1
