"""Geofence and rally point lists over the mission protocol (issue 21), with pymavlink on the
board's MAVLink link: upload, download, clear, the mission beside them, bad fences (each with
its MAV_MISSION_* result, the previous fence kept), a power cycle, and SYS_STATUS's geofence
bit."""

from __future__ import annotations

import math
from typing import Any

import pytest
from pymavlink.dialects.v20 import common as mav

from tests.mavlink.conftest import open_commander_session, open_session

FENCE, RALLY = mav.MAV_MISSION_TYPE_FENCE, mav.MAV_MISSION_TYPE_RALLY
REL_INT = mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
LAT0, LON0 = 473_977_419, 85_455_938  # degE7
GEOFENCE_BIT = mav.MAV_SYS_STATUS_GEOFENCE


def item(seq: int, cmd: int, lat_e7: int, lon_e7: int, p1: float = 0.0, z: float = 0.0,
         mtype: int = FENCE, frame: int = REL_INT) -> Any:
    return mav.MAVLink_mission_item_int_message(1, 1, seq, frame, cmd, 0, 0, p1, 0.0, 0.0, 0.0,
                                                lat_e7, lon_e7, z, mtype)


def square(n_e7: int = 20_000, cmd: int = mav.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
           count: float = 4.0) -> list[Any]:
    """An axis-aligned square around (LAT0, LON0), ``n_e7`` degE7 from the centre."""
    corners = [(-n_e7, -n_e7), (-n_e7, n_e7), (n_e7, n_e7), (n_e7, -n_e7)]
    return [item(0, cmd, LAT0 + a, LON0 + b, count) for a, b in corners]


PLAN_FENCE = square() + [
    item(0, mav.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, LAT0 + 10_000, LON0 + 10_000, 15.0),
    item(0, mav.MAV_CMD_NAV_FENCE_RETURN_POINT, LAT0, LON0 + 1_000, z=12.0)]
PLAN_RALLY = [item(0, mav.MAV_CMD_NAV_RALLY_POINT, LAT0 + 5_000, LON0 - 5_000, z=8.0,
                   mtype=RALLY)]


def upload(gcs: Any, mtype: int, items: list[Any], timeout_s: float = 5.0) -> int:
    """Upload ``items`` as list ``mtype``; the MISSION_ACK's result. Every request the
    vehicle sends must be for this list type."""
    for seq, it in enumerate(items):
        it.seq, it.mission_type = seq, mtype
    mark = gcs.mark()
    gcs.send(mav.MAVLink_mission_count_message(1, 1, len(items), mtype))
    cursor = [mark]

    def serve() -> Any:
        for m in gcs.messages(None, cursor[0]):
            if m.get_type() in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
                assert m.mission_type == mtype
                if m.seq < len(items):
                    gcs.send(items[m.seq])
            elif m.get_type() == "MISSION_ACK":
                assert m.mission_type == mtype
                return m
        cursor[0] = gcs.mark()
        return None
    return gcs.wait_for(serve, timeout_s).type


def download(gcs: Any, mtype: int) -> list[Any]:
    mark = gcs.mark()
    gcs.send(mav.MAVLink_mission_request_list_message(1, 1, mtype))
    count = gcs.wait_message("MISSION_COUNT", lambda m: m.mission_type == mtype, since=mark).count
    out = []
    for seq in range(count):
        mark = gcs.mark()
        gcs.send(mav.MAVLink_mission_request_int_message(1, 1, seq, mtype))
        out.append(gcs.wait_message("MISSION_ITEM_INT", lambda m, s=seq: m.seq == s,
                                    since=mark))
    gcs.send(mav.MAVLink_mission_ack_message(1, 1, mav.MAV_MISSION_ACCEPTED, mtype))
    return out


def fields(m: Any) -> tuple:
    return (m.seq, m.frame, m.command, m.param1, m.x, m.y, m.z, m.mission_type)


def clear(gcs: Any, mtype: int) -> int:
    mark = gcs.mark()
    gcs.send(mav.MAVLink_mission_clear_all_message(1, 1, mtype))
    return gcs.wait_message("MISSION_ACK", lambda m: m.mission_type == mtype, since=mark).type


def _dataman(s: Any) -> Any:
    return s.orch.handles["fmu"].endpoint.board.system.modules.get("dataman")


@pytest.fixture(scope="module")
def vehicle(tmp_path_factory):
    s = open_commander_session(tmp_path_factory.mktemp("fence"))
    yield s
    s.close()


def test_plan_uploads_downloads_identical_beside_the_mission_and_clears(vehicle):
    gcs = vehicle.gcs
    assert gcs.upload_mission([(47.3978, 8.5456, 10.0, mav.MAV_CMD_NAV_TAKEOFF),
                               (47.3980, 8.5460, 10.0)]) == mav.MAV_MISSION_ACCEPTED
    assert upload(gcs, FENCE, PLAN_FENCE) == mav.MAV_MISSION_ACCEPTED
    assert upload(gcs, RALLY, PLAN_RALLY) == mav.MAV_MISSION_ACCEPTED
    assert [fields(m) for m in download(gcs, FENCE)] == [fields(m) for m in PLAN_FENCE]
    assert [fields(m) for m in download(gcs, RALLY)] == [fields(m) for m in PLAN_RALLY]
    dm = _dataman(vehicle)
    assert dm.fence.count == 6 and dm.rally.count == 1 and dm.store.count == 2
    # the mission is untouched by them, and still uploads beside them
    assert [m.command for m in gcs.download_mission()] == [22, 16]
    assert gcs.upload_mission([(47.3979, 8.5457, 15.0)]) == mav.MAV_MISSION_ACCEPTED
    assert dm.fence.count == 6 and dm.rally.count == 1 and dm.store.count == 1
    # the float protocol gives the same list (MISSION_REQUEST -> MISSION_ITEM)
    mark = gcs.mark()
    gcs.send(mav.MAVLink_mission_request_message(1, 1, 4, FENCE))
    circle = gcs.wait_message("MISSION_ITEM", since=mark)
    assert (circle.command, circle.param1, circle.mission_type) == (
        mav.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, 15.0, FENCE)
    assert math.isclose(circle.x, (LAT0 + 10_000) / 1e7, abs_tol=1e-5)
    assert clear(gcs, RALLY) == mav.MAV_MISSION_ACCEPTED
    assert download(gcs, RALLY) == [] and dm.fence.count == 6
    assert clear(gcs, mav.MAV_MISSION_TYPE_ALL) == mav.MAV_MISSION_ACCEPTED
    assert (dm.fence.count, dm.rally.count, dm.store.count) == (0, 0, 0)


def _bowtie() -> list[Any]:
    cmd = mav.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
    pts = [(-1, -1), (1, 1), (1, -1), (-1, 1)]
    return [item(0, cmd, LAT0 + 10_000 * a, LON0 + 10_000 * b, 4.0) for a, b in pts]


def _float_vertex(lat: float, lon: float, z: float = 0.0) -> Any:
    return mav.MAVLink_mission_item_message(
        1, 1, 0, mav.MAV_FRAME_GLOBAL_RELATIVE_ALT,
        mav.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 0, 0, 3.0, 0, 0, 0, lat, lon, z, FENCE)


_INCL = mav.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
BAD_FENCES = {
    # the polygon says 4 vertices, a circle comes after 3
    "vertex count mismatch": (square()[:3] + [
        item(0, mav.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION, LAT0, LON0, 50.0)],
        mav.MAV_MISSION_INVALID_PARAM1),
    "polygon cut short": (square()[:3], mav.MAV_MISSION_INVALID_PARAM1),
    "fewer than 3 vertices": (square(count=2.0)[:2], mav.MAV_MISSION_ERROR),
    "more vertices than the storage holds": (square(count=40.0), mav.MAV_MISSION_NO_SPACE),
    "self-intersecting": (_bowtie(), mav.MAV_MISSION_ERROR),
    "NaN latitude": ([_float_vertex(math.nan, 8.5) for _ in range(3)],
                     mav.MAV_MISSION_INVALID_PARAM5_X),
    "NaN altitude": ([_float_vertex(47.39, 8.54, math.nan) for _ in range(3)],
                     mav.MAV_MISSION_INVALID_PARAM7),
    "NaN vertex count": (square(count=math.nan), mav.MAV_MISSION_INVALID_PARAM1),
    "zero radius": ([item(0, mav.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, LAT0, LON0, 0.0)],
                    mav.MAV_MISSION_INVALID_PARAM1),
    "a waypoint in a fence": ([item(0, mav.MAV_CMD_NAV_WAYPOINT, LAT0, LON0)],
                              mav.MAV_MISSION_UNSUPPORTED),
    "a local frame": ([item(0, _INCL, 1, 1, 3.0, frame=mav.MAV_FRAME_LOCAL_NED)
                       for _ in range(3)], mav.MAV_MISSION_UNSUPPORTED_FRAME),
}


@pytest.mark.parametrize("name", list(BAD_FENCES))
def test_a_bad_fence_gets_its_result_and_keeps_the_previous_fence(vehicle, name):
    gcs = vehicle.gcs
    assert upload(gcs, FENCE, square(10_000)) == mav.MAV_MISSION_ACCEPTED
    before = [fields(m) for m in download(gcs, FENCE)]
    mark = gcs.mark()
    items, code = BAD_FENCES[name]
    assert upload(gcs, FENCE, items) == code
    assert any(m.severity <= mav.MAV_SEVERITY_CRITICAL for m in gcs.messages("STATUSTEXT", mark))
    assert [fields(m) for m in download(gcs, FENCE)] == before
    assert upload(gcs, FENCE, PLAN_FENCE) == mav.MAV_MISSION_ACCEPTED  # the link works on


def test_too_many_items_is_no_space_before_any_request_and_rally_takes_only_rally(vehicle):
    gcs = vehicle.gcs
    dm = _dataman(vehicle)
    for mtype, store in ((FENCE, dm.fence), (RALLY, dm.rally)):
        mark = gcs.mark()
        gcs.send(mav.MAVLink_mission_count_message(1, 1, store.capacity + 1, mtype))
        ack = gcs.wait_message("MISSION_ACK", since=mark)
        assert (ack.type, ack.mission_type) == (mav.MAV_MISSION_NO_SPACE, mtype)
        assert not gcs.messages("MISSION_REQUEST_INT", mark)
    assert upload(gcs, RALLY, square()[:1]) == mav.MAV_MISSION_UNSUPPORTED
    assert upload(gcs, FENCE, PLAN_RALLY[:1]) == mav.MAV_MISSION_UNSUPPORTED


def test_sys_status_geofence_bit(vehicle):
    """Healthy without a fence (MAVProxy said "fence breach" on every connect when the bit
    was clear), present and enabled once a fence is uploaded (GF_ACTION Hold by default)."""
    gcs = vehicle.gcs
    assert clear(gcs, FENCE) == mav.MAV_MISSION_ACCEPTED
    gcs.step(1.2)
    st = gcs.last["SYS_STATUS"]
    assert st.onboard_control_sensors_health & GEOFENCE_BIT
    assert not st.onboard_control_sensors_present & GEOFENCE_BIT
    assert upload(gcs, FENCE, PLAN_FENCE) == mav.MAV_MISSION_ACCEPTED
    mark = gcs.mark()
    st = gcs.wait_message("SYS_STATUS", since=mark)
    gcs.step(1.2)
    st = gcs.last["SYS_STATUS"]
    assert st.onboard_control_sensors_present & GEOFENCE_BIT
    assert st.onboard_control_sensors_enabled & GEOFENCE_BIT
    assert st.onboard_control_sensors_health & GEOFENCE_BIT


def test_fence_and_rally_survive_a_power_cycle(tmp_path):
    s = open_session(tmp_path)
    try:
        s.gcs.wait_heartbeat()
        assert upload(s.gcs, FENCE, PLAN_FENCE) == mav.MAV_MISSION_ACCEPTED
        assert upload(s.gcs, RALLY, PLAN_RALLY) == mav.MAV_MISSION_ACCEPTED
    finally:
        s.close()
    s = open_session(tmp_path)
    try:
        s.gcs.wait_heartbeat()
        assert [fields(m) for m in download(s.gcs, FENCE)] == [fields(m) for m in PLAN_FENCE]
        assert [fields(m) for m in download(s.gcs, RALLY)] == [fields(m) for m in PLAN_RALLY]
    finally:
        s.close()


# -- a flight: the uploaded fence breached, GF_ACTION Return, to the rally point --------------

def _texts(gcs: Any, mark: int) -> list[str]:
    return [m.text if isinstance(m.text, str) else m.text.decode("latin-1")
            for m in gcs.messages("STATUSTEXT", mark)]


@pytest.mark.slow
@pytest.mark.parametrize("hil_vehicle", [{"params": {
    "EKF2_MAG_DECL": 2.6, "GF_ACTION": 3, "COM_FAIL_ACT_T": 0.0, "RTL_RETURN_ALT": 4.0,
    "RTL_DESCEND_ALT": 3.0, "RTL_LAND_DELAY": 0.0}}], indirect=True)
def test_breach_returns_to_the_rally_point(hil_vehicle):
    """The whole vehicle (boards, world, RC, pymavlink GCS): an inclusion square 12 m around
    home and four rally points 7 m from home (north, east, south, west) are uploaded. In a
    4 m hover in Position mode the pilot holds the pitch stick forward and flies out (PX4
    refuses missions and repositions beyond the fence, so the pilot is the way out). At the
    edge the commander reports the violation and returns (GF_ACTION 3); Return goes to the
    rally point closest to where it starts, closer than home (RTL_TYPE 0), lands there and
    disarms."""
    from firmware.modules.navigator.geo import offset_deg

    v = hil_vehicle
    gcs = v.gcs
    v.wait_for("home_set", within=40.0, step=0.2)
    home = gcs.last["HOME_POSITION"]
    lat0, lon0 = home.latitude / 1e7, home.longitude / 1e7

    def e7(north_m: float, east_m: float) -> tuple[int, int]:
        lat, lon = offset_deg(lat0, lon0, north_m, east_m)
        return round(lat * 1e7), round(lon * 1e7)

    fence = [item(0, _INCL, *e7(n, e), 4.0) for n, e in ((-12, -12), (-12, 12), (12, 12),
                                                          (12, -12))]
    rally = [item(0, mav.MAV_CMD_NAV_RALLY_POINT, *e7(n, e), z=0.0, mtype=RALLY)
             for n, e in ((7, 0), (0, 7), (-7, 0), (0, -7))]
    assert upload(gcs, FENCE, fence) == mav.MAV_MISSION_ACCEPTED
    assert upload(gcs, RALLY, rally) == mav.MAV_MISSION_ACCEPTED
    v.dev["safety"].press(v.orch.t_ns + 100_000_000, hold_s=1.5)
    v.wait_for("topic.px4io_status.status_safety_off", within=5.0)
    mark = gcs.mark()
    assert gcs.arm(timeout_s=2.0).result == mav.MAV_RESULT_ACCEPTED
    assert gcs.takeoff(4.0).result == mav.MAV_RESULT_ACCEPTED
    v.wait_for("alt_agl_m > 3.5", within=15.0, step=0.1)
    v.dev["rc"].tx.set_sticks(v.orch.t_ns, roll=0.0, pitch=0.0, yaw=0.0, throttle=0.5)
    assert gcs.set_mode(3).result == mav.MAV_RESULT_ACCEPTED  # Position
    v.wait_for("nav_state == 'Position'", within=2.0, step=0.1)
    push = v.fault("vehicle.geofence_breach", "pilot", stick=0.6)
    v.wait_for("nav_state == 'Return'", within=20.0, step=0.1)
    v.clear(push)
    assert 11.0 < v.read("home_distance_m") < 16.0   # at the fence
    texts = _texts(gcs, mark)
    assert "[commander] Geofence violation" in texts
    assert "[commander] Failsafe: geofence breached, return" in texts
    v.wait_for("not armed", within=40.0, step=0.2)
    assert v.read("on_ground")
    assert abs(v.read("home_distance_m") - 7.0) < 2.0   # landed at a rally point, not home
    assert any(t.startswith("[navigator] Return: to rally point") for t in _texts(gcs, mark))
