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


def test_fence_and_rally_are_unsupported(dataman):
    gcs = dataman.gcs
    for mtype in (mav.MAV_MISSION_TYPE_FENCE, mav.MAV_MISSION_TYPE_RALLY):
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
