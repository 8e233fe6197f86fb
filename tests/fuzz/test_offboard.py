"""Fuzz target for offboard setpoints: SET_POSITION_TARGET_LOCAL_NED, SET_POSITION_TARGET_GLOBAL_INT
and SET_ATTITUDE_TARGET with random fields (NaN, infinities, any type_mask, any frame), through a
real link of one booted FMU that is in Offboard mode (switched while disarmed, which PX4 allows),
so every accepted setpoint is published."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mav

from tests.fuzzing import fuzz
from tests.mavlink.conftest import open_session

_F = st.one_of(st.floats(width=32), st.sampled_from([math.nan, math.inf, -math.inf, 0.0, 1.0]))
_MASK = st.one_of(st.integers(0, 0xFFFF),
                  st.sampled_from([0b110111111000, 0b110111000111, 0b110000111111, 0, 0x7]))
_FRAME = st.one_of(st.sampled_from([1, 8, 5, 6]), st.integers(0, 255))


def _local(target: int, frame: int, mask: int, f: list[float]) -> Any:
    return mav.MAVLink_set_position_target_local_ned_message(0, target, 1, frame, mask, *f)


def _global(target: int, frame: int, mask: int, f: list[float], lat: int, lon: int) -> Any:
    return mav.MAVLink_set_position_target_global_int_message(
        0, target, 1, frame, mask, lat, lon, *f[2:])


def _attitude(target: int, mask: int, f: list[float]) -> Any:
    return mav.MAVLink_set_attitude_target_message(0, target, 1, mask & 0xFF, f[:4], *f[4:8])


@pytest.fixture(scope="module")
def fmu(tmp_path_factory):
    s = open_session(tmp_path_factory.mktemp("fuzz_offboard"))
    s.gcs.wait_heartbeat()
    s.shell("commander start")
    s.gcs.step(0.3)
    for _ in range(5):
        s.gcs.send(_local(1, 1, 0b110111111000, [0.0, 0.0, -2.0] + [0.0] * 8))
        s.gcs.step(0.05)
    assert s.gcs.set_mode(6).result == mav.MAV_RESULT_ACCEPTED
    assert s.topic("vehicle_status")["nav_state"] == 14
    yield s
    s.close()


def _count(fmu: Any, topic: str) -> int:
    m = fmu.topic(topic)
    return -1 if m is None else int(m["_count"])


@fuzz(examples=40)
@given(kind=st.sampled_from(["local", "global", "attitude"]),
       target=st.sampled_from([0, 1, 1, 7]), frame=_FRAME, mask=_MASK,
       fields=st.lists(_F, min_size=11, max_size=11),
       lat=st.integers(-2**31, 2**31 - 1), lon=st.integers(-2**31, 2**31 - 1))
def test_setpoints_never_raise_and_published_ones_are_flyable(
        fmu: Any, kind: str, target: int, frame: int, mask: int, fields: list[float],
        lat: int, lon: int) -> None:
    """Invariant: no setpoint makes a handler raise or the FMU stop; what is published has no
    infinity (NaN only marks an axis not given), offboard_control_mode says what the
    trajectory setpoint holds, an attitude setpoint is a unit quaternion with thrust 0..1,
    rates are finite; a message for another vehicle publishes nothing."""
    gcs = fmu.gcs
    inst = fmu.udp_instance()
    errors, since_us = inst.rx_handler_errors, fmu.dmesg_mark()
    before = {t: _count(fmu, t) for t in ("trajectory_setpoint", "vehicle_attitude_setpoint",
                                          "vehicle_rates_setpoint", "offboard_control_mode")}
    msg = (_local(target, frame, mask, fields) if kind == "local" else
           _global(target, frame, mask, fields, lat, lon) if kind == "global" else
           _attitude(target, mask, fields))
    gcs.send(msg)
    gcs.step(0.03)
    assert not fmu.orch.dead, fmu.orch.dead
    assert fmu.mavlink_errors(since_us) == [] and inst.rx_handler_errors == errors
    after = {t: _count(fmu, t) for t in before}
    if target == 7:
        assert after == before
        return
    if after["trajectory_setpoint"] != before["trajectory_setpoint"]:
        t = fmu.topic("trajectory_setpoint")
        ocm = fmu.topic("offboard_control_mode")
        values = [*t["position"], *t["velocity"], *t["acceleration"], t["yaw"], t["yawspeed"]]
        assert not any(math.isinf(x) for x in values), t
        for group in ("position", "velocity", "acceleration"):
            assert ocm[group] == any(math.isfinite(x) for x in t[group]), (group, t, ocm)
    if after["vehicle_attitude_setpoint"] != before["vehicle_attitude_setpoint"]:
        a = fmu.topic("vehicle_attitude_setpoint")
        assert math.isclose(sum(x * x for x in a["q_d"]), 1.0, rel_tol=1e-4), a
        assert 0.0 <= -a["thrust_body"][2] <= 1.0 and math.isfinite(a["yaw_sp_move_rate"])
    if after["vehicle_rates_setpoint"] != before["vehicle_rates_setpoint"]:
        r = fmu.topic("vehicle_rates_setpoint")
        assert all(math.isfinite(r[k]) for k in ("roll", "pitch", "yaw")), r
