"""Joystick and offboard input: MANUAL_CONTROL to manual_control_setpoint; setpoints only in
Offboard mode."""

import math

from pymavlink.dialects.v20 import common as mav

from firmware.modules.mavlink.offboard import project


def _find_manual(session):
    for i in range(4):
        m = session.topic("manual_control_setpoint", i)
        if m is not None and m["data_source"] >= 2:
            return m
    return None


def test_manual_control_published_with_mavlink_source(session):
    gcs = session.gcs
    gcs.send(mav.MAVLink_manual_control_message(1, 500, -250, 750, 100, 0))
    gcs.step(0.05)
    m = _find_manual(session)
    assert m is not None and m["valid"] and m["data_source"] == 2 + 1  # link #1 (UDP)
    assert (m["pitch"], m["roll"], m["yaw"]) == (0.5, -0.25, 0.1)
    assert math.isclose(m["throttle"], 0.5)


def test_manual_control_for_another_vehicle_ignored(session):
    gcs = session.gcs
    gcs.send(mav.MAVLink_manual_control_message(9, 0, 0, 0, 0, 0))
    gcs.step(0.05)
    assert _find_manual(session)["pitch"] == 0.5  # unchanged


def test_position_target_ignored_outside_offboard(session):
    gcs = session.gcs
    before = session.topic("trajectory_setpoint")
    gcs.send(mav.MAVLink_set_position_target_local_ned_message(
        0, 1, 1, mav.MAV_FRAME_LOCAL_NED, 0b110111111000, 1.0, 2.0, -3.0, 0, 0, 0, 0, 0, 0,
        0, 0))
    gcs.step(0.05)
    after = session.topic("trajectory_setpoint")
    assert (before or {}).get("_count") == (after or {}).get("_count")


def test_projection_round_numbers():
    n, e = project(47.0 + 1e-3, 8.0, 47.0, 8.0)
    assert math.isclose(n, 111.195, rel_tol=1e-3) and abs(e) < 1e-6
    n, e = project(47.0, 8.0 + 1e-3, 47.0, 8.0)
    assert math.isclose(e, 111.195 * math.cos(math.radians(47.0)), rel_tol=1e-3)
