"""QGroundControl's set-up-page messages and commands (issue 21): SYSTEM_TIME,
RUN_PREARM_CHECKS, motor and actuator test, against a booted FMU over its UDP link."""

import math

import pytest
from pymavlink.dialects.v20 import common as mav

from firmware.modules.mavlink.systime import PX4_EPOCH_US
from tests.mavlink.conftest import open_commander_session, open_session


@pytest.fixture(scope="module")
def fresh(tmp_path_factory):
    """A board of its own: the GCS-set clock is module state that other tests must not see."""
    s = open_session(tmp_path_factory.mktemp("setup_pages"))
    s.gcs.wait_heartbeat()
    yield s
    s.close()


def _system_time_now(gcs):
    mark = gcs.mark()
    ack = gcs.command_long(mav.MAV_CMD_REQUEST_MESSAGE, [mav.MAVLINK_MSG_ID_SYSTEM_TIME])
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    return gcs.wait_message("SYSTEM_TIME", since=mark)


def test_system_time_before_gps_unknown_then_gcs_sets_it_once(fresh):
    """Before the GPS has UTC (its first UTC comes ~2.2 s after boot here) the time is
    unknown (0); a GCS time before PX4's epoch is ignored, a valid one sets the clock, a
    second one does not move it (PX4's handle_message_system_time)."""
    gcs = fresh.gcs
    assert fresh.topic("sensor_gps") is None or not fresh.topic("sensor_gps")["time_utc_usec"]
    assert _system_time_now(gcs).time_unix_usec == 0
    gcs.send(mav.MAVLink_system_time_message(PX4_EPOCH_US - 1, 0))
    gcs.step(0.02)
    assert _system_time_now(gcs).time_unix_usec == 0
    utc_us = 1_700_000_000_000_000
    gcs.send(mav.MAVLink_system_time_message(utc_us, 0))
    gcs.step(0.02)
    m = _system_time_now(gcs)
    assert 0 <= m.time_unix_usec - utc_us <= 100_000, m.time_unix_usec - utc_us
    gcs.send(mav.MAVLink_system_time_message(utc_us + 3_600_000_000, 0))  # set already
    gcs.step(0.02)
    later = _system_time_now(gcs)
    assert later.time_unix_usec - m.time_unix_usec == pytest.approx(
        (later.time_boot_ms - m.time_boot_ms) * 1000, abs=1000)
    assert fresh.udp_instance().systime.clock_sets == 1


def test_system_time_streamed_at_1hz_from_gps_utc(fresh):
    gcs = fresh.gcs
    gcs.wait_for(lambda: (fresh.topic("sensor_gps") or {}).get("time_utc_usec"), 5.0)
    mark = gcs.mark()
    gcs.step(3.05)
    msgs = gcs.messages("SYSTEM_TIME", mark)
    assert 2 <= len(msgs) <= 4, len(msgs)   # PX4's default 1 Hz
    boot = [m.time_boot_ms for m in msgs]
    assert boot == sorted(boot) and 900 <= boot[1] - boot[0] <= 1100
    gps = fresh.topic("sensor_gps")
    gps_offset_us = gps["time_utc_usec"] - gps["timestamp"]
    # the GPS's UTC, which sets the clock (as PX4's GPS driver does)
    assert abs(msgs[-1].time_unix_usec - msgs[-1].time_boot_ms * 1000 - gps_offset_us) \
        < 300_000
    gcs.send(mav.MAVLink_system_time_message(gps["time_utc_usec"] + 10**12, 0))  # ignored
    gcs.step(0.02)
    m = _system_time_now(gcs)
    assert abs(m.time_unix_usec - m.time_boot_ms * 1000 - gps_offset_us) < 300_000


@pytest.fixture(scope="module")
def commander(tmp_path_factory):
    s = open_commander_session(tmp_path_factory.mktemp("setup_pages_commander"))
    yield s
    s.close()


def _texts(gcs, mark):
    return [m.text if isinstance(m.text, str) else m.text.decode("latin-1")
            for m in gcs.messages("STATUSTEXT", mark)]


def test_run_prearm_checks_reports_every_failure_again(commander):
    """RUN_PREARM_CHECKS: ACCEPTED, and each failing check's STATUSTEXT again (they were
    reported once at boot; the command forces the report), with SYS_STATUS and
    vehicle_status saying the checks fail (no RC on this bench board)."""
    gcs = commander.gcs
    gcs.step(1.0)  # the boot-time reports are out
    mark = gcs.mark()
    gcs.step(1.0)
    assert not [t for t in _texts(gcs, mark) if "Preflight Fail" in t]
    mark = gcs.mark()
    ack = gcs.command_long(mav.MAV_CMD_RUN_PREARM_CHECKS)
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    gcs.step(0.3)
    fails = [t for t in _texts(gcs, mark) if "Preflight Fail" in t]
    # STATUSTEXT carries "[commander] " and is chunked at 50 characters
    assert "[commander] Preflight Fail: No manual control inpu" in fails, fails
    assert "[commander] Preflight Fail: battery not connected" in fails, fails
    assert len(fails) == len(set(fails))  # each once
    assert not commander.topic("vehicle_status")["pre_flight_checks_pass"]
    sys_status = gcs.wait_message("SYS_STATUS", since=mark)
    assert sys_status.onboard_control_sensors_present & ~sys_status.onboard_control_sensors_health


def test_run_prearm_checks_rejected_when_armed(commander):
    gcs = commander.gcs
    assert gcs.arm(force=True).result == mav.MAV_RESULT_ACCEPTED
    try:
        mark = gcs.mark()
        ack = gcs.command_long(mav.MAV_CMD_RUN_PREARM_CHECKS)
        assert ack.result == mav.MAV_RESULT_TEMPORARILY_REJECTED
        gcs.step(0.2)
        assert not [t for t in _texts(gcs, mark) if "Preflight Fail" in t]
    finally:
        assert gcs.disarm(force=True).result == mav.MAV_RESULT_ACCEPTED


# -- motor test: the FMU, the IO and the world's ESCs ------------------------------------------

S, MS = 1_000_000_000, 1_000_000


@pytest.fixture(scope="module")
def vehicle(tmp_path_factory):
    """FMU + IO + world (the ESCs on the IO's pins), safety pressed off: the bench on which
    QGroundControl's Motors page spins a motor."""
    from hil.system import SystemConfig, build_system

    orch, dev = build_system(SystemConfig(seed=4, out_dir=str(tmp_path_factory.mktemp("mt")),
                                          rc="sbus", gcs=True))
    orch.start()
    gcs = dev["gcs"]
    gcs.attach(orch)
    gcs.wait_heartbeat(timeout_s=10)
    gcs.step(1.0)
    dev["safety"].press(orch.t_ns + 100 * MS, hold_s=1.5)
    gcs.wait_for(lambda: (orch.call("fmu", "topic", "px4io_status") or {})
                 .get("status_safety_off"), timeout_s=5)
    yield orch, dev
    orch.close()


def _pulses(dev):
    return [e.pulse_us for e in dev["world"].world.escs[:4]]


def test_motor_test_spins_one_motor_for_its_timeout(vehicle):
    orch, dev = vehicle
    gcs = dev["gcs"]
    gcs.step(0.2)
    idle = _pulses(dev)
    assert all(p < 1000 for p in idle), idle  # disarmed PWM (900)
    ack = gcs.command_long(mav.MAV_CMD_DO_MOTOR_TEST,
                           [2, mav.MOTOR_TEST_THROTTLE_PERCENT, 20, 1.0, 0, 0, 0])
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    t0 = orch.t_ns
    gcs.step(0.3)
    during = _pulses(dev)
    assert 1360 <= during[1] <= 1380, during  # the F450's PWM_MIN 1230 + 20 % of 1230..1950
    assert all(p < 1000 for i, p in enumerate(during) if i != 1), during
    io_pwm = orch.call("fmu", "topic", "px4io_status")["pwm"][:4]
    assert 1360 <= io_pwm[1] <= 1380 and all(p < 1000 for i, p in enumerate(io_pwm) if i != 1)
    gcs.step(0.5)
    assert 1360 <= _pulses(dev)[1] <= 1380           # still spinning before the 1 s timeout
    gcs.step(0.4)
    assert orch.t_ns - t0 >= 1.1 * S
    assert all(p < 1000 for p in _pulses(dev)), _pulses(dev)  # back to disarmed after it
    assert not orch.call("fmu", "topic", "actuator_armed")["armed"]


def test_actuator_test_spins_a_motor_and_nan_stops_it(vehicle):
    orch, dev = vehicle
    gcs = dev["gcs"]
    ack = gcs.command_long(mav.MAV_CMD_ACTUATOR_TEST, [0.5, 3.0, 0, 0, 104, 0, 0])
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    gcs.step(0.3)
    p = _pulses(dev)
    assert 1580 <= p[3] <= 1600 and all(x < 1000 for x in p[:3]), p
    ack = gcs.command_long(mav.MAV_CMD_ACTUATOR_TEST, [math.nan, 0, 0, 0, 104, 0, 0])
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    gcs.step(0.2)
    assert all(x < 1000 for x in _pulses(dev)), _pulses(dev)
    ack = gcs.command_long(mav.MAV_CMD_ACTUATOR_TEST, [0.5, 1.0, 0, 0, 201, 0, 0])  # a servo
    assert ack.result == mav.MAV_RESULT_UNSUPPORTED


def test_motor_test_denied_when_armed(vehicle):
    orch, dev = vehicle
    gcs = dev["gcs"]
    assert gcs.arm(force=True).result == mav.MAV_RESULT_ACCEPTED
    try:
        ack = gcs.command_long(mav.MAV_CMD_DO_MOTOR_TEST,
                               [1, mav.MOTOR_TEST_THROTTLE_PERCENT, 50, 2.0, 0, 0, 0])
        assert ack.result == mav.MAV_RESULT_DENIED
        ack = gcs.command_long(mav.MAV_CMD_ACTUATOR_TEST, [0.5, 2.0, 0, 0, 101, 0, 0])
        assert ack.result == mav.MAV_RESULT_DENIED
        gcs.step(0.3)
        assert orch.call("fmu", "topic", "actuator_armed")["armed"]
    finally:
        assert gcs.disarm(force=True).result == mav.MAV_RESULT_ACCEPTED


def test_motor_test_denied_with_the_safety_on(vehicle):
    """PX4's commander refuses the motor and actuator tests while the safety switch is on:
    DENIED with a STATUSTEXT, no pulse reaches an ESC; with the safety off again they run."""
    orch, dev = vehicle
    gcs = dev["gcs"]

    def safety_off():
        return (orch.call("fmu", "topic", "px4io_status") or {}).get("status_safety_off")

    gcs.step(1.6)   # the fixture's press may still be held (it waits for safety off only)
    dev["safety"].press(orch.t_ns + 100 * MS, hold_s=1.5)       # a long press: safety on
    gcs.wait_for(lambda: not safety_off(), timeout_s=5)
    try:
        mark = gcs.mark()
        ack = gcs.command_long(mav.MAV_CMD_DO_MOTOR_TEST,
                               [1, mav.MOTOR_TEST_THROTTLE_PERCENT, 30, 1.0, 0, 0, 0])
        assert ack.result == mav.MAV_RESULT_DENIED
        ack = gcs.command_long(mav.MAV_CMD_ACTUATOR_TEST, [0.5, 1.0, 0, 0, 101, 0, 0])
        assert ack.result == mav.MAV_RESULT_DENIED
        gcs.step(0.3)
        assert all(p < 1000 for p in _pulses(dev)), _pulses(dev)
        texts = [m.text for m in gcs.messages("STATUSTEXT", mark)]
        assert any("safety switch not off" in t for t in texts), texts
    finally:
        gcs.step(1.6)
        dev["safety"].press(orch.t_ns + 100 * MS, hold_s=1.5)   # off again
        gcs.wait_for(safety_off, timeout_s=5)
        gcs.step(1.6)   # released, so that a later press is a press of its own
    ack = gcs.command_long(mav.MAV_CMD_DO_MOTOR_TEST,
                           [1, mav.MOTOR_TEST_THROTTLE_PERCENT, 20, 0.3, 0, 0, 0])
    assert ack.result == mav.MAV_RESULT_ACCEPTED


def test_motor_test_denied_when_com_mot_test_en_is_0(vehicle):
    """COM_MOT_TEST_EN 0 disables the motor and actuator tests (PX4: DENIED)."""
    orch, dev = vehicle
    gcs = dev["gcs"]
    gcs.param_set("COM_MOT_TEST_EN", 0)
    try:
        gcs.step(0.1)
        ack = gcs.command_long(mav.MAV_CMD_DO_MOTOR_TEST,
                               [3, mav.MOTOR_TEST_THROTTLE_PERCENT, 30, 1.0, 0, 0, 0])
        assert ack.result == mav.MAV_RESULT_DENIED
        ack = gcs.command_long(mav.MAV_CMD_ACTUATOR_TEST, [0.5, 1.0, 0, 0, 103, 0, 0])
        assert ack.result == mav.MAV_RESULT_DENIED
        gcs.step(0.3)
        assert all(p < 1000 for p in _pulses(dev)), _pulses(dev)
    finally:
        gcs.param_set("COM_MOT_TEST_EN", 1)
        gcs.step(0.1)
    ack = gcs.command_long(mav.MAV_CMD_DO_MOTOR_TEST,
                           [3, mav.MOTOR_TEST_THROTTLE_PERCENT, 20, 0.3, 0, 0, 0])
    assert ack.result == mav.MAV_RESULT_ACCEPTED
