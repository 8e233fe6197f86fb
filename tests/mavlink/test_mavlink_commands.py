"""Commands: to vehicle_command and the commander, acks back; the ones the link answers itself."""

import math

import pytest
from pymavlink.dialects.v20 import common as mav

from hil.gcs import GcsTimeout


def _text(m):
    return m.text if isinstance(m.text, str) else m.text.decode("latin-1")


@pytest.fixture(scope="module")
def commander(session):
    session.shell("commander start")
    session.gcs.step(0.5)
    return session


def test_arm_denied_preflight_with_a_reason(commander):
    gcs = commander.gcs
    mark = gcs.mark()
    ack = gcs.arm()
    assert ack.result in (mav.MAV_RESULT_TEMPORARILY_REJECTED, mav.MAV_RESULT_DENIED)
    assert ack.target_system == 255 and ack.target_component == gcs.mav.srcComponent
    gcs.step(0.1)
    reasons = [_text(m) for m in gcs.messages("STATUSTEXT", mark)]
    assert any("Preflight" in r or "rming" in r for r in reasons), reasons
    assert not gcs.last["HEARTBEAT"].base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED


def test_force_arm_then_disarm(commander):
    gcs = commander.gcs
    assert gcs.arm(force=True).result == mav.MAV_RESULT_ACCEPTED
    hb = gcs.wait_message("HEARTBEAT", lambda m: m.get_srcSystem() == 1
                          and m.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED)
    assert hb.system_status in (mav.MAV_STATE_ACTIVE, mav.MAV_STATE_CRITICAL)
    assert gcs.disarm(force=True).result == mav.MAV_RESULT_ACCEPTED


def test_command_int_reaches_vehicle_command(commander):
    gcs = commander.gcs
    before = (commander.topic("vehicle_command") or {}).get("_count", 0)
    gcs.send(mav.MAVLink_command_int_message(1, 1, mav.MAV_FRAME_GLOBAL_INT,
                                             mav.MAV_CMD_DO_REPOSITION, 0, 0, -1, 1, 0,
                                             float("nan"), 473977420, 85455940, 500.0))
    gcs.wait_message("COMMAND_ACK", lambda m: m.command == mav.MAV_CMD_DO_REPOSITION)
    cmd = commander.topic("vehicle_command")
    assert cmd["_count"] == before + 1 and cmd["command"] == mav.MAV_CMD_DO_REPOSITION
    assert math.isclose(cmd["param5"], 47.397742, abs_tol=1e-7)
    assert math.isclose(cmd["param6"], 8.545594, abs_tol=1e-7)
    assert cmd["param7"] == 500.0 and cmd["from_external"] and cmd["source_system"] == 255


def test_wrongly_addressed_command_ignored(session):
    gcs = session.gcs
    before = session.counters()["rx_not_for_us"]
    mark = gcs.mark()
    gcs.send(mav.MAVLink_command_long_message(42, 1, mav.MAV_CMD_COMPONENT_ARM_DISARM, 0,
                                              1, 0, 0, 0, 0, 0, 0))
    gcs.step(0.2)
    assert not gcs.messages("COMMAND_ACK", mark)
    assert session.counters()["rx_not_for_us"] == before + 1


def test_autopilot_version_and_protocol_version_on_request(session):
    gcs = session.gcs
    mark = gcs.mark()
    ack = gcs.command_long(mav.MAV_CMD_REQUEST_MESSAGE, [mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION])
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    av = gcs.wait_message("AUTOPILOT_VERSION", since=mark)
    assert av.capabilities & mav.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE
    assert av.capabilities & mav.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    assert av.capabilities & mav.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE  # as PX4 (issue 21)
    assert av.capabilities & mav.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY
    ack = gcs.command_long(mav.MAV_CMD_REQUEST_PROTOCOL_VERSION, [1])
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    pv = gcs.wait_message("UNKNOWN_300", since=mark)  # not in pymavlink's dialects
    buf = bytes(pv.get_msgbuf())
    payload = buf[10:10 + buf[1]].ljust(22, b"\0")  # MAVLink 2 strips trailing zeros
    assert payload == bytes([200, 0, 100, 0, 200, 0]) + bytes(16)
    assert gcs.command_long(mav.MAV_CMD_REQUEST_MESSAGE, [9999]).result == \
        mav.MAV_RESULT_UNSUPPORTED


def test_set_message_interval_changes_a_stream(session):
    gcs = session.gcs
    ack = gcs.command_long(mav.MAV_CMD_SET_MESSAGE_INTERVAL,
                           [mav.MAVLINK_MSG_ID_SYS_STATUS, 100_000])
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    mark = gcs.mark()
    gcs.step(1.0)
    assert 9 <= len(gcs.messages("SYS_STATUS", mark)) <= 11
    gcs.command_long(mav.MAV_CMD_SET_MESSAGE_INTERVAL, [mav.MAVLINK_MSG_ID_SYS_STATUS, 0])
    mark = gcs.mark()
    gcs.step(2.0)
    assert 1 <= len(gcs.messages("SYS_STATUS", mark)) <= 3  # back to the default 1 Hz
    assert gcs.command_long(mav.MAV_CMD_SET_MESSAGE_INTERVAL, [9999, 1000]).result == \
        mav.MAV_RESULT_UNSUPPORTED


def test_timesync_and_ping_answered(session):
    gcs = session.gcs
    mark = gcs.mark()
    gcs.send(mav.MAVLink_timesync_message(0, 123456789))
    ts = gcs.wait_message("TIMESYNC", lambda m: m.ts1 == 123456789, since=mark)
    assert ts.tc1 > 0
    gcs.send(mav.MAVLink_ping_message(42, 7, 0, 0))
    ping = gcs.wait_message("PING", since=mark)
    assert (ping.seq, ping.target_system) == (7, 255)


def test_no_ack_means_timeout_not_hang(session):
    gcs = session.gcs
    t0 = session.orch.t_ns
    gcs.target_system = 42  # nobody answers for another vehicle
    try:
        with pytest.raises(GcsTimeout):
            gcs.command_long(mav.MAV_CMD_COMPONENT_ARM_DISARM, [1], timeout_s=0.3, retries=0)
    finally:
        gcs.target_system = 1
    assert session.orch.t_ns - t0 <= 400_000_000


@pytest.mark.parametrize(("command", "params"), [
    (mav.MAV_CMD_REQUEST_MESSAGE, [math.nan]),
    (mav.MAV_CMD_REQUEST_MESSAGE, [math.inf]),
    (mav.MAV_CMD_REQUEST_MESSAGE, [-1e30]),
    (mav.MAV_CMD_SET_MESSAGE_INTERVAL, [math.nan, 100_000]),
    (mav.MAV_CMD_SET_MESSAGE_INTERVAL, [-math.inf, 100_000]),
    (mav.MAV_CMD_SET_MESSAGE_INTERVAL, [mav.MAVLINK_MSG_ID_SYS_STATUS, math.nan]),
    (mav.MAV_CMD_SET_MESSAGE_INTERVAL, [mav.MAVLINK_MSG_ID_SYS_STATUS, math.inf]),
    (mav.MAV_CMD_GET_MESSAGE_INTERVAL, [math.nan]),
    (mav.MAV_CMD_GET_MESSAGE_INTERVAL, [3e38]),
])
def test_bad_message_id_or_interval_denied(session, command, params):
    """Defect 6: a NaN, infinite or out-of-range message id or interval is MAV_RESULT_DENIED
    (it used to raise in the handler and leave the command unanswered)."""
    gcs = session.gcs
    ack = gcs.command_long(command, params, retries=0, timeout_s=0.5)
    assert ack.result == mav.MAV_RESULT_DENIED
    gcs.step(0.05)
    assert not session.orch.dead
    # the stream configuration did not change: SYS_STATUS still at its 1 Hz default
    assert gcs.command_long(mav.MAV_CMD_GET_MESSAGE_INTERVAL,
                            [mav.MAVLINK_MSG_ID_SYS_STATUS]).result == mav.MAV_RESULT_ACCEPTED


def test_a_failing_command_handler_is_acked_failed_counted_and_logged(session):
    """Defect 6 at the root: whatever a command handler raises becomes COMMAND_ACK
    MAV_RESULT_FAILED: a command never goes unanswered. Review: the FAILED ack hid the
    handler's exception from everything that looks for bugs (``rx_handler_errors``, which the
    fuzz targets check); it is now counted and logged as an ERR naming the command and the
    exception, local or forwarded."""
    inst = session.udp_instance()
    svc = inst.commands
    saved = svc.local[mav.MAV_CMD_REQUEST_PROTOCOL_VERSION]

    def broken(m):
        raise RuntimeError("a bug in a handler")
    errors, mark = inst.rx_handler_errors, session.dmesg_mark()
    svc.local[mav.MAV_CMD_REQUEST_PROTOCOL_VERSION] = broken
    try:
        ack = session.gcs.command_long(mav.MAV_CMD_REQUEST_PROTOCOL_VERSION, [1], retries=0,
                                       timeout_s=0.5)
    finally:
        svc.local[mav.MAV_CMD_REQUEST_PROTOCOL_VERSION] = saved
    assert ack.result == mav.MAV_RESULT_FAILED
    assert inst.rx_handler_errors == errors + 1
    assert session.mavlink_errors(mark) == [
        f"COMMAND_LONG {mav.MAV_CMD_REQUEST_PROTOCOL_VERSION}: RuntimeError: a bug in a handler"]


def test_an_interval_message_interval_cannot_carry_is_denied(session):
    """Found by the command fuzz target once handler errors counted: SET_MESSAGE_INTERVAL
    with 3e38 µs was accepted, and the next GET_MESSAGE_INTERVAL raised packing an interval
    beyond MESSAGE_INTERVAL's int32 (acked FAILED). Intervals beyond int32 µs (~36 min) are
    now DENIED, and a stream rate however low keeps an interval the message can report."""
    gcs = session.gcs
    inst = session.udp_instance()
    errors = inst.rx_handler_errors
    sys_status = mav.MAVLINK_MSG_ID_SYS_STATUS
    assert gcs.command_long(mav.MAV_CMD_SET_MESSAGE_INTERVAL, [sys_status, 3e38], retries=0,
                            timeout_s=0.5).result == mav.MAV_RESULT_DENIED
    assert inst.set_stream_rate("SYS_STATUS", 1e-30)  # the shell's `mavlink stream -r`
    try:
        mark = gcs.mark()
        assert gcs.command_long(mav.MAV_CMD_GET_MESSAGE_INTERVAL, [sys_status], retries=0,
                                timeout_s=0.5).result == mav.MAV_RESULT_ACCEPTED
        assert gcs.wait_message("MESSAGE_INTERVAL", since=mark).interval_us == 0x7FFFFFFF
    finally:
        assert gcs.command_long(mav.MAV_CMD_SET_MESSAGE_INTERVAL,
                                [sys_status, 0]).result == mav.MAV_RESULT_ACCEPTED
    assert inst.rx_handler_errors == errors


# -- every command gets exactly one ack (issue 21) ---------------------------------------------

@pytest.fixture(scope="module")
def throwaway(tmp_path_factory):
    """A board of its own: the commands below arm, change modes, load and reset parameters."""
    from tests.mavlink.conftest import open_session

    s = open_session(tmp_path_factory.mktemp("every_command"))
    s.gcs.wait_heartbeat()
    s.shell("commander start")
    s.shell("navigator start")  # answers DO_CHANGE_SPEED itself
    s.gcs.step(0.3)
    yield s
    s.close()


def test_every_common_command_gets_exactly_one_ack(throwaway):
    """Every id of the common dialect's MAV_CMD enum, sent as COMMAND_LONG with zero
    parameters, is answered by exactly one COMMAND_ACK carrying its id: none is left to a
    time-out (calibration, storage, DO_CHANGE_SPEED, camera, mission-only items...), none is
    answered twice (the navigator's DO_CHANGE_SPEED is not also acked by the commander).
    PREFLIGHT_REBOOT_SHUTDOWN with param1 0 does not reboot (UNSUPPORTED), so it is not
    special; the reboot itself is tests/mavlink/test_mavlink_reboot.py's."""
    from pymavlink import mavutil

    gcs = throwaway.gcs
    ids = sorted(c for c, e in mavutil.mavlink.enums["MAV_CMD"].items()
                 if e.name != "MAV_CMD_ENUM_END")
    assert len(ids) > 200
    mark = gcs.mark()
    for i in range(0, len(ids), 3):  # vehicle_command_ack queues 4: 3 per 20 ms
        for command in ids[i:i + 3]:
            gcs.send(mav.MAVLink_command_long_message(1, 1, command, 0, 0, 0, 0, 0, 0, 0, 0))
        gcs.step(0.02)
    gcs.step(0.3)
    acks: dict[int, list[int]] = {}
    for a in gcs.messages("COMMAND_ACK", mark):
        acks.setdefault(a.command, []).append(a.result)
    missing = [c for c in ids if c not in acks]
    doubled = {c: r for c, r in acks.items() if len(r) != 1}
    assert not missing and not doubled, (missing, doubled)
    assert set(acks) == set(ids)
    assert acks[mav.MAV_CMD_DO_CHANGE_SPEED] == [mav.MAV_RESULT_ACCEPTED]
    # 0 loads, and this board's FRAM holds no saved parameters yet: FAILED, as PX4's
    # param_load_default fails without a parameter file
    assert acks[mav.MAV_CMD_PREFLIGHT_STORAGE] == [mav.MAV_RESULT_FAILED]
    assert acks[mav.MAV_CMD_PREFLIGHT_CALIBRATION] == [mav.MAV_RESULT_ACCEPTED]  # all 0: end
    assert acks[mav.MAV_CMD_NAV_WAYPOINT] == [mav.MAV_RESULT_UNSUPPORTED]
    assert acks[mav.MAV_CMD_IMAGE_START_CAPTURE] == [mav.MAV_RESULT_UNSUPPORTED]


def test_preflight_calibration_unsupported_with_a_reason(throwaway):
    """A calibration without a routine (ESC, param7) is UNSUPPORTED at once (PX4's answer for
    a calibration it has no routine for), with a STATUSTEXT; the routines themselves are
    tests/calibration's."""
    gcs = throwaway.gcs
    mark = gcs.mark()
    ack = gcs.command_long(mav.MAV_CMD_PREFLIGHT_CALIBRATION, [0, 0, 0, 0, 0, 0, 1], retries=0,
                           timeout_s=0.5)
    assert ack.result == mav.MAV_RESULT_UNSUPPORTED
    gcs.step(0.1)
    assert any("calibration" in _text(m) for m in gcs.messages("STATUSTEXT", mark))


def test_preflight_storage_saves_resets_and_loads_parameters(throwaway):
    """PREFLIGHT_STORAGE through the parameter store (PX4's commander): 1 saves to FRAM, 2
    resets all but CAL_* to defaults, 0 loads FRAM's values back; refused while armed."""
    gcs = throwaway.gcs
    params = throwaway.orch.handles["fmu"].endpoint.board.system.params
    params.autosave_delay_us = -1  # only the command saves
    try:
        params.set("MPC_XY_CRUISE", 7.0)
        saves = params.save_count
        assert gcs.command_long(mav.MAV_CMD_PREFLIGHT_STORAGE, [1]).result == \
            mav.MAV_RESULT_ACCEPTED
        assert params.save_count == saves + 1
        assert gcs.command_long(mav.MAV_CMD_PREFLIGHT_STORAGE, [2]).result == \
            mav.MAV_RESULT_ACCEPTED
        assert params["MPC_XY_CRUISE"] == params.defs["MPC_XY_CRUISE"].default
        assert gcs.command_long(mav.MAV_CMD_PREFLIGHT_STORAGE, [0]).result == \
            mav.MAV_RESULT_ACCEPTED
        assert params["MPC_XY_CRUISE"] == 7.0
        assert gcs.command_long(mav.MAV_CMD_PREFLIGHT_STORAGE, [9]).result == \
            mav.MAV_RESULT_UNSUPPORTED
        assert gcs.arm(force=True).result == mav.MAV_RESULT_ACCEPTED
        assert gcs.command_long(mav.MAV_CMD_PREFLIGHT_STORAGE, [1]).result == \
            mav.MAV_RESULT_TEMPORARILY_REJECTED
    finally:
        gcs.disarm(force=True)
        params.reset("MPC_XY_CRUISE")
        params.autosave_delay_us = 300_000


def test_do_change_speed_sets_the_navigators_cruise_speed(throwaway):
    """DO_CHANGE_SPEED (PX4's navigator): param2 > 0 is the cruise speed; 0, -1 or NaN goes
    back to the default (-1: MPC_XY_CRUISE)."""
    gcs = throwaway.gcs
    nav = throwaway.orch.handles["fmu"].endpoint.board.system.modules.get("navigator")
    assert gcs.command_long(mav.MAV_CMD_DO_CHANGE_SPEED, [1, 3.5, -1]).result == \
        mav.MAV_RESULT_ACCEPTED
    assert nav.cruise_speed == 3.5
    assert gcs.command_long(mav.MAV_CMD_DO_CHANGE_SPEED, [1, math.nan]).result == \
        mav.MAV_RESULT_ACCEPTED
    assert nav.cruise_speed == -1.0
