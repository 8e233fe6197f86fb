"""MAV_CMD_INJECT_FAILURE over a booted FMU's UDP link, with pymavlink (hil/gcs.py).

PX4's rules (docs "System Failure Injection"; mavlink_receiver): SYS_FAILURE_EN 0 denies the
command; enabled, the failure_injector module hands it to the orchestrator's fault injector,
which maps (unit, type) onto a catalogue fault (hil/faults/inject_failure.py) and answers.
The board here runs alone in an orchestrator (tests/mavlink/conftest.py), first without a
fault injector, then with one installed, so every answer is checked at its source.
"""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import common as mav

from hil.faults import Injector
from hil.faults.inject_failure import INSTANCES, MAPPING, lookup
from tests.mavlink.conftest import open_session

CMD = mav.MAV_CMD_INJECT_FAILURE
GPS, BARO, GYRO, FLOW, MOTOR = (mav.FAILURE_UNIT_SENSOR_GPS, mav.FAILURE_UNIT_SENSOR_BARO,
                                mav.FAILURE_UNIT_SENSOR_GYRO,
                                mav.FAILURE_UNIT_SENSOR_OPTICAL_FLOW,
                                mav.FAILURE_UNIT_SYSTEM_MOTOR)
OK, OFF, STUCK, SLOW = (mav.FAILURE_TYPE_OK, mav.FAILURE_TYPE_OFF, mav.FAILURE_TYPE_STUCK,
                        mav.FAILURE_TYPE_SLOW)


@pytest.fixture(scope="module")
def fi_session(tmp_path_factory):
    s = open_session(tmp_path_factory.mktemp("fmu_fi"))
    s.gcs.wait_heartbeat()
    yield s
    s.close()


def _inject(s, unit: float, ftype: float, instance: float = 0.0):
    """Send the command; (COMMAND_ACK, [the STATUSTEXTs after it, joined], virtual s to the
    ack)."""
    mark = s.gcs.mark()
    t0 = s.orch.t_ns
    ack = s.gcs.command_long(CMD, [unit, ftype, instance], timeout_s=2.0, retries=0)
    s.gcs.step(0.05)  # the STATUSTEXT follows the ack within a link cycle
    # long texts come in 50-character chunks (STATUSTEXT's id / chunk_seq): joined, they read
    texts = ["".join(m.text for m in s.gcs.messages("STATUSTEXT", since=mark))]
    acks = [m for m in s.gcs.messages("COMMAND_ACK", since=mark) if m.command == CMD]
    assert len(acks) == 1, f"expected one COMMAND_ACK, got {acks}"
    return ack, texts, (s.orch.t_ns - t0) / 1e9


def _chip(s, name: str):
    return s.orch.handles["fmu"].endpoint.board.devices[name].faults


def test_denied_while_sys_failure_en_is_0(fi_session):
    s = fi_session
    assert s.gcs.param_get("SYS_FAILURE_EN") == 0  # PX4's default
    ack, texts, _ = _inject(s, GPS, OFF)
    assert ack.result == mav.MAV_RESULT_DENIED
    assert any("SYS_FAILURE_EN" in t for t in texts), texts


def test_without_a_fault_injector_the_answer_says_so(fi_session):
    s = fi_session
    s.gcs.param_set("SYS_FAILURE_EN", 1)
    ack, texts, took_s = _inject(s, GPS, OFF)
    assert ack.result == mav.MAV_RESULT_UNSUPPORTED
    assert any("no fault injector attached" in t for t in texts), texts
    assert 0.9 < took_s < 1.3  # the module's 1 s reply timeout: nobody served the request


def test_mapped_pair_acts_on_the_chip_and_ok_clears_it(fi_session):
    s = fi_session
    s.gcs.param_set("SYS_FAILURE_EN", 1)
    inj = Injector(s.orch, {"gcs": s.gcs}).install()
    ack, texts, took_s = _inject(s, BARO, OFF)
    assert ack.result == mav.MAV_RESULT_ACCEPTED, texts
    assert took_s < 0.1
    assert _chip(s, "ms5611").absent  # the register-level fault, not a flight-stack flag
    assert [a.kind.name for a in inj.history if a.active] == ["sensor.absent"]
    assert any("sensor.absent ms5611" in t for t in texts), texts
    ack, texts, _ = _inject(s, BARO, OK)
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    assert not _chip(s, "ms5611").absent
    assert not any(a.active for a in inj.history)
    # gyro stuck on instance 2 is the L3GD20's frozen registers, and only it
    ack, _, _ = _inject(s, GYRO, STUCK, 2)
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    assert _chip(s, "l3gd20").frozen and not _chip(s, "mpu6000").frozen
    ack, _, _ = _inject(s, GYRO, OK, 0)
    assert not _chip(s, "l3gd20").frozen


@pytest.mark.parametrize("unit, ftype, instance, result, text", [
    (FLOW, OFF, 0, mav.MAV_RESULT_UNSUPPORTED, "no such fault"),     # no flow sensor fitted
    (GPS, SLOW, 0, mav.MAV_RESULT_UNSUPPORTED, "no such fault"),     # no catalogue fault
    (42, OFF, 0, mav.MAV_RESULT_UNSUPPORTED, "unknown failure unit"),
    (GPS, 9, 0, mav.MAV_RESULT_UNSUPPORTED, "unknown failure type"),
    (GYRO, OFF, 3, mav.MAV_RESULT_DENIED, "no gyro instance 3"),     # the FMUv2 has two
    (MOTOR, OFF, 5, mav.MAV_RESULT_DENIED, "no motor instance 5"),
    (math.nan, OFF, 0, mav.MAV_RESULT_DENIED, "bad parameters"),
    (GPS, OFF, 1.5, mav.MAV_RESULT_DENIED, "bad parameters"),
    (GPS, -1, 0, mav.MAV_RESULT_DENIED, "bad parameters"),
])
def test_refusals(fi_session, unit, ftype, instance, result, text):
    s = fi_session
    s.gcs.param_set("SYS_FAILURE_EN", 1)
    if not s.orch.request_hooks:
        Injector(s.orch, {"gcs": s.gcs}).install()
    ack, texts, _ = _inject(s, unit, ftype, instance)
    assert ack.result == result
    assert any(text in t for t in texts), texts


def test_mapping_table_names_catalogue_faults_with_valid_targets():
    """Every mapped pair starts a kind that exists, on targets that kind accepts."""
    from hil.faults import get_kind

    assert lookup(GPS, OFF).kind == "gps.absent"
    assert lookup(MOTOR, OFF).kind == "vehicle.motor_failure"
    assert lookup(mav.FAILURE_UNIT_SENSOR_MAG, STUCK).kind == "sensor.stuck"
    assert lookup(FLOW, OFF) is None and lookup(GPS, SLOW) is None
    for (unit, _type), m in MAPPING.items():
        kind = get_kind(m.kind)
        targets = (m.target,) if m.target is not None else INSTANCES[unit]
        for t in targets:
            kind.check(t, dict(m.params))  # raises FaultError on a bad target or parameter
