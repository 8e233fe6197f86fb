"""The mission protocol against dataman: upload, download, current item, clear, other types."""

import math

import pytest
from pymavlink.dialects.v20 import common as mav

WAYPOINTS = [(47.3977419, 8.5455938, 10.0, mav.MAV_CMD_NAV_TAKEOFF),
             (47.3980000, 8.5460000, 20.0),
             (47.3985000, 8.5450000, 25.0),
             (47.3977419, 8.5455938, 0.0, mav.MAV_CMD_NAV_LAND)]


@pytest.fixture(scope="module")
def dataman(session):
    if "dataman: running" not in session.orch.call("fmu", "shell", "dataman status")[1]:
        session.shell("dataman start")  # rcS starts it once the navigator's owners add it
    return session


def _store(s):
    return s.orch.handles["fmu"].endpoint.board.system.modules.get("dataman").store


def test_upload_download_round_trip(dataman):
    gcs = dataman.gcs
    assert gcs.upload_mission(WAYPOINTS) == mav.MAV_MISSION_ACCEPTED
    items = _store(dataman).items()
    assert len(items) == 4
    assert [int(i.nav_cmd) for i in items] == [22, 16, 16, 21]
    assert math.isclose(items[1].lat, 47.398, abs_tol=1e-7) and items[2].altitude == 25.0
    assert all(i.altitude_is_relative for i in items)
    mission = dataman.topic("mission")
    assert mission["count"] == 4
    back = gcs.download_mission()
    assert [(m.x, m.y, m.z, m.command, m.frame) for m in back] == [
        (round(w[0] * 1e7), round(w[1] * 1e7), w[2], w[3] if len(w) > 3 else 16,
         mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT) for w in WAYPOINTS]
    assert back[0].current == 1 and back[1].current == 0


def test_set_current_reported_by_mission_current(dataman):
    gcs = dataman.gcs
    mark = gcs.mark()
    gcs.send(mav.MAVLink_mission_set_current_message(1, 1, 2))
    cur = gcs.wait_message("MISSION_CURRENT", lambda m: m.seq == 2, since=mark)
    assert cur.total == 4
    assert _store(dataman).current_seq == 2


def test_unsupported_item_rejects_upload_and_keeps_mission(dataman):
    gcs = dataman.gcs
    item = mav.MAVLink_mission_item_int_message(1, 1, 0, mav.MAV_FRAME_MISSION,
                                                mav.MAV_CMD_DO_SET_SERVO, 0, 1, 5, 1500, 0, 0,
                                                0, 0, 0.0, 0)
    assert gcs.upload_mission([item]) == mav.MAV_MISSION_UNSUPPORTED
    assert _store(dataman).count == 4  # the half-uploaded mission never became active


def test_change_speed_item_round_trips(dataman):
    # MAVSDK adds DO_CHANGE_SPEED when a mission item has a speed; PX4 accepts it.
    gcs = dataman.gcs
    wp = (47.3978, 8.5456, 10.0)
    speed = mav.MAVLink_mission_item_int_message(1, 1, 1, mav.MAV_FRAME_MISSION,
                                                 mav.MAV_CMD_DO_CHANGE_SPEED, 0, 1, 1, 3.5, -1,
                                                 0, 0, 0, 0.0, 0)
    assert gcs.upload_mission([wp, speed, wp]) == mav.MAV_MISSION_ACCEPTED
    items = gcs.download_mission()
    assert [it.command for it in items] == [mav.MAV_CMD_NAV_WAYPOINT,
                                           mav.MAV_CMD_DO_CHANGE_SPEED, mav.MAV_CMD_NAV_WAYPOINT]
    assert items[1].param2 == 3.5


def test_an_unknown_mission_type_is_unsupported(dataman):
    # fence and rally lists are supported (test_mavlink_fence_rally.py); 3 is no list type
    gcs = dataman.gcs
    for mtype in (3,):
        mark = gcs.mark()
        gcs.send(mav.MAVLink_mission_count_message(1, 1, 3, mtype))
        ack = gcs.wait_message("MISSION_ACK", since=mark)
        assert (ack.type, ack.mission_type) == (mav.MAV_MISSION_UNSUPPORTED, mtype)
        mark = gcs.mark()
        gcs.send(mav.MAVLink_mission_request_list_message(1, 1, mtype))
        ack = gcs.wait_message("MISSION_ACK", since=mark)
        assert ack.type == mav.MAV_MISSION_UNSUPPORTED


def test_request_repeated_when_the_gcs_is_silent(dataman):
    gcs = dataman.gcs
    mark = gcs.mark()
    gcs.send(mav.MAVLink_mission_count_message(1, 1, 2, 0))
    gcs.step(1.2)
    reqs = [m for m in gcs.messages("MISSION_REQUEST_INT", mark)]
    assert len(reqs) >= 3 and all(m.seq == 0 for m in reqs)
    assert gcs.upload_mission(WAYPOINTS[:2]) == mav.MAV_MISSION_ACCEPTED  # a new upload


def test_clear_all(dataman):
    gcs = dataman.gcs
    mark = gcs.mark()
    gcs.send(mav.MAVLink_mission_clear_all_message(1, 1, 0))
    assert gcs.wait_message("MISSION_ACK", since=mark).type == mav.MAV_MISSION_ACCEPTED
    assert _store(dataman).count == 0
    assert gcs.download_mission() == []


# -- robustness (issue 18): capacity, storage failure, invalid items, downloads ----------------

def _ack_after(gcs, msg, mark=None):
    mark = gcs.mark() if mark is None else mark
    gcs.send(msg)
    return gcs.wait_message("MISSION_ACK", since=mark)


def _item(seq, x, y, z, cmd=mav.MAV_CMD_NAV_WAYPOINT, frame=mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
          params=(0.0, 0.0, 0.0, math.nan)):
    return mav.MAVLink_mission_item_int_message(1, 1, seq, frame, cmd, 0, 1, *params, x, y, z, 0)


def _fitem(seq, x, y, z, cmd=mav.MAV_CMD_NAV_WAYPOINT, frame=mav.MAV_FRAME_GLOBAL_RELATIVE_ALT,
           params=(0.0, 0.0, 0.0, math.nan)):
    return mav.MAVLink_mission_item_message(1, 1, seq, frame, cmd, 0, 1, *params, x, y, z, 0)


def _upload(gcs, items, timeout_s=10.0):
    """Upload with MISSION_ITEM (float) or MISSION_ITEM_INT messages as given (the client's
    upload_mission speaks only the int protocol); the MISSION_ACK's type."""
    msgs = []
    for seq, it in enumerate(items):
        if isinstance(it, (mav.MAVLink_mission_item_message, mav.MAVLink_mission_item_int_message)):
            it.seq = seq
            msgs.append(it)
        else:
            msgs.extend(m for m in gcs._mission_items([it]))
            msgs[-1].seq, msgs[-1].current = seq, int(seq == 0)
    mark = gcs.mark()
    gcs.send(mav.MAVLink_mission_count_message(1, 1, len(msgs), 0))
    cursor = [mark]

    def serve():
        for m in gcs.messages(None, cursor[0]):
            if m.get_type() in ("MISSION_REQUEST_INT", "MISSION_REQUEST") and m.seq < len(msgs):
                gcs.send(msgs[m.seq])
            elif m.get_type() == "MISSION_ACK":
                return m
        cursor[0] = gcs.mark()
        return None
    return gcs.wait_for(serve, timeout_s).type


def _reopen_with_dataman(root):
    from tests.mavlink.conftest import open_session

    s = open_session(root)
    s.gcs.wait_heartbeat()
    if "dataman: running" not in s.orch.call("fmu", "shell", "dataman status")[1]:
        s.shell("dataman start")
    return s


def test_mission_beyond_fram_capacity_is_no_space_and_keeps_the_old_one(tmp_path):
    """Defect 3: 62 items do not fit the FRAM's mission region (61): MISSION_COUNT is
    answered MAV_MISSION_NO_SPACE before any item is requested, and after a power cycle the
    mission that was accepted before is still the one stored."""
    s = _reopen_with_dataman(tmp_path)
    try:
        gcs = s.gcs
        assert gcs.upload_mission(WAYPOINTS) == mav.MAV_MISSION_ACCEPTED
        mark = gcs.mark()
        gcs.send(mav.MAVLink_mission_count_message(1, 1, 62, 0))
        ack = gcs.wait_message("MISSION_ACK", since=mark)
        assert ack.type == mav.MAV_MISSION_NO_SPACE
        assert not gcs.messages("MISSION_REQUEST_INT", mark)
        assert _store(s).count == 4
        # 61 items do fit, and survive the power cycle
        square = [(47.3977 + i * 1e-5, 8.5455, 10.0) for i in range(61)]
        assert gcs.upload_mission(square, timeout_s=30) == mav.MAV_MISSION_ACCEPTED
    finally:
        s.close()
    s = _reopen_with_dataman(tmp_path)
    try:
        assert _store(s).count == 61
    finally:
        s.close()


class _FailingPartition:
    """The FRAM waypoint partition with its writes failing (a worn or unplugged part)."""

    def __init__(self, inner):
        self.inner, self.size = inner, inner.size

    def read(self, offset, n):
        return self.inner.read(offset, n)

    def write(self, offset, data):
        return False


def test_storage_failure_is_mission_error_and_keeps_the_old_mission(dataman):
    """Defect 3: a failed save is MAV_MISSION_ERROR, not ACCEPTED; the old mission stays."""
    gcs = dataman.gcs
    assert gcs.upload_mission(WAYPOINTS) == mav.MAV_MISSION_ACCEPTED
    store = _store(dataman)
    before = [(i.lat, i.lon, i.altitude) for i in store.items()]
    good = store.partition
    store.partition = _FailingPartition(good)
    try:
        assert gcs.upload_mission(WAYPOINTS[:2]) == mav.MAV_MISSION_ERROR
    finally:
        store.partition = good
    assert [(i.lat, i.lon, i.altitude) for i in store.items()] == before
    assert [(m.x, m.y) for m in gcs.download_mission()] == [
        (round(w[0] * 1e7), round(w[1] * 1e7)) for w in WAYPOINTS]


@pytest.mark.parametrize(("item", "code"), [
    (_fitem(0, math.nan, 8.5, 10.0), mav.MAV_MISSION_INVALID_PARAM5_X),
    (_fitem(0, 47.4, math.inf, 10.0), mav.MAV_MISSION_INVALID_PARAM6_Y),
    (_fitem(0, 47.4, 8.5, math.nan), mav.MAV_MISSION_INVALID_PARAM7),
    (_item(0, 950_000_000, 85_000_000, 10.0), mav.MAV_MISSION_INVALID_PARAM5_X),
    (_item(0, 473_977_419, -1_850_000_000, 10.0), mav.MAV_MISSION_INVALID_PARAM6_Y),
    (_item(0, 473_977_419, 85_455_938, math.inf), mav.MAV_MISSION_INVALID_PARAM7),
    (_item(0, 473_977_419, 85_455_938, 10.0, params=(math.inf, 0, 0, 0)),
     mav.MAV_MISSION_INVALID_PARAM1),
    (_item(0, 473_977_419, 85_455_938, 10.0, params=(0, -math.inf, 0, 0)),
     mav.MAV_MISSION_INVALID_PARAM2),
    (_item(0, 473_977_419, 85_455_938, 10.0, params=(0, 0, 0, math.inf)),
     mav.MAV_MISSION_INVALID_PARAM4),
    (_item(0, 473_977_419, 85_455_938, 10.0, frame=99), mav.MAV_MISSION_UNSUPPORTED_FRAME),
    (_item(0, 473_977_419, 85_455_938, 10.0, cmd=60001), mav.MAV_MISSION_UNSUPPORTED),
])
def test_invalid_item_rejected_with_its_code_and_keeps_the_mission(dataman, item, code):
    """Defect 4: NaN, infinite and out-of-range fields abort the upload with the code for
    the field (the emulator's stricter check: PX4 would store them for the navigator's
    feasibility check to refuse); a bad frame or command with PX4's code. The previous
    mission stays active."""
    gcs = dataman.gcs
    assert gcs.upload_mission(WAYPOINTS) == mav.MAV_MISSION_ACCEPTED
    assert _upload(gcs, [WAYPOINTS[0], item]) == code
    assert _store(dataman).count == len(WAYPOINTS)
    assert len(gcs.download_mission()) == len(WAYPOINTS)


def test_nan_yaw_and_speed_mean_unchanged_and_are_accepted(dataman):
    """PX4 allows NaN where MAVLink gives it a meaning: yaw (param4) and DO_CHANGE_SPEED."""
    gcs = dataman.gcs
    speed = _item(1, 0, 0, 0.0, cmd=mav.MAV_CMD_DO_CHANGE_SPEED, frame=mav.MAV_FRAME_MISSION,
                  params=(1, math.nan, -1, 0))
    assert gcs.upload_mission([WAYPOINTS[0], speed]) == mav.MAV_MISSION_ACCEPTED
    items = _store(dataman).items()
    assert math.isnan(items[0].yaw) and items[1].speed_m_s == -1.0


def test_whatever_is_stored_can_be_downloaded(dataman):
    """Defect 4 (defence in depth): an item no upload could store (NaN and out-of-range
    positions, written into the store directly) still downloads, in both protocols."""
    gcs = dataman.gcs
    store = _store(dataman)
    store.store_mission([store.new_item(nav_cmd=16, lat=math.nan, lon=400.0, altitude=10.0),
                         store.new_item(nav_cmd=16, lat=-1e300, lon=math.inf,
                                        altitude=math.nan)])
    items = gcs.download_mission()
    assert [it.seq for it in items] == [0, 1]
    mark = gcs.mark()
    gcs.send(mav.MAVLink_mission_request_message(1, 1, 1, 0))
    assert gcs.wait_message("MISSION_ITEM", since=mark).seq == 1
    gcs.send(mav.MAVLink_mission_clear_all_message(1, 1, 0))
    gcs.step(0.05)


def test_download_during_an_upload_is_ignored_as_px4_does(dataman):
    """Found by the fuzzer: a download asked for while an upload waits for its items got a
    MISSION_COUNT and then silence. PX4 (handle_mission_request_list) ignores it with the
    STATUSTEXT "Mission download request ignored, already active": no count, no ack; the
    uploader may cancel its upload with MISSION_ACK OPERATION_CANCELLED, and then the
    download works."""
    gcs = dataman.gcs
    assert gcs.upload_mission(WAYPOINTS) == mav.MAV_MISSION_ACCEPTED
    mark = gcs.mark()
    gcs.send(mav.MAVLink_mission_count_message(1, 1, 3, 0))
    gcs.send(mav.MAVLink_mission_request_list_message(1, 1, 0))
    gcs.step(0.1)
    assert not gcs.messages("MISSION_COUNT", mark) and not gcs.messages("MISSION_ACK", mark)
    assert any(t.text == "Mission download request ignored, already active"
               for t in gcs.messages("STATUSTEXT", mark))
    gcs.send(mav.MAVLink_mission_ack_message(1, 1, mav.MAV_MISSION_OPERATION_CANCELLED, 0))
    assert len(gcs.download_mission()) == len(WAYPOINTS)
    assert _store(dataman).count == len(WAYPOINTS)


def test_a_failing_mission_handler_is_counted_and_logged(dataman):
    """Review of defect 4: the mission protocol's guard answered MAV_MISSION_ERROR but kept
    the exception from ``rx_handler_errors`` (what the fuzz targets check), so a handler bug
    looked like a polite refusal. It is now counted and logged as an ERR."""
    gcs = dataman.gcs
    assert gcs.upload_mission(WAYPOINTS) == mav.MAV_MISSION_ACCEPTED
    inst = dataman.udp_instance()
    store = _store(dataman)
    errors, mark = inst.rx_handler_errors, dataman.dmesg_mark()

    def broken(seq):
        raise RuntimeError("a bug in a handler")
    store.item = broken
    try:
        ack = _ack_after(gcs, mav.MAVLink_mission_request_int_message(1, 1, 0, 0))
    finally:
        del store.item
    assert ack.type == mav.MAV_MISSION_ERROR
    assert inst.rx_handler_errors == errors + 1
    assert dataman.mavlink_errors(mark) == ["MISSION_REQUEST_INT: RuntimeError: a bug in a handler"]
    assert len(gcs.download_mission()) == len(WAYPOINTS)
