"""Joystick and offboard input: MANUAL_CONTROL to manual_control_setpoint; setpoints only in
Offboard mode."""

import math

import pytest

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


# -- a joystick flies Position mode (issue 21) -------------------------------------------------

def _joystick(v, seconds, x=0, y=0, z=500, r=0, rate_hz=20):
    """MANUAL_CONTROL at ``rate_hz`` for ``seconds`` of virtual time (z 500: throttle centre)."""
    for _ in range(int(seconds * rate_hz)):
        v.gcs.send(mav.MAVLink_manual_control_message(1, x, y, z, r, 0))
        v.run(1.0 / rate_hz)


@pytest.mark.slow
@pytest.mark.parametrize("hil_vehicle", [{"rc": None, "params": {"COM_RC_IN_MODE": 1}}],
                         indirect=True)
def test_joystick_flies_position_mode_without_rc(hil_vehicle):
    """COM_RC_IN_MODE 1 (MAVLink only), no RC receiver: the joystick is the manual-control
    source, so Position mode arms, climbs on throttle, holds at centre and moves on pitch.
    It used to be published on another instance than the controllers read, so the vehicle
    descended and disarmed. When the joystick stops, manual control is lost."""
    v = hil_vehicle
    gcs = v.gcs
    v.wait_for("home_set", within=40.0, step=0.2)
    v.dev["safety"].press(v.orch.t_ns + 100_000_000, hold_s=1.5)
    _joystick(v, 2.0)
    assert v.read("topic.manual_control_setpoint.data_source") >= 2  # MAVLink link
    assert gcs.set_mode(3).result == mav.MAV_RESULT_ACCEPTED
    assert gcs.arm(timeout_s=2.0).result == mav.MAV_RESULT_ACCEPTED
    _joystick(v, 4.0, z=900)             # throttle up: climb
    alt = v.read("alt_agl_m")
    assert alt > 2.0, alt
    _joystick(v, 1.0)                    # centre: stop climbing, then hold altitude
    held = v.read("alt_agl_m")
    _joystick(v, 2.0)
    assert abs(v.read("alt_agl_m") - held) < 0.7
    _joystick(v, 3.0, x=700)             # pitch forward: fly
    assert v.read("speed_m_s") > 1.5
    assert v.read("armed") and v.read("nav_state").lower() == "position"
    assert v.read("alt_agl_m") > 1.5
    v.wait_for("rc_signal_lost", within=2.0)  # the joystick stopped
