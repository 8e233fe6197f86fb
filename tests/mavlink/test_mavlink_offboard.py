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
    # Self-contained (xdist may run it without the test above): ours first, then another's.
    gcs = session.gcs
    gcs.send(mav.MAVLink_manual_control_message(1, 500, -250, 750, 100, 0))
    gcs.step(0.05)
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


# -- offboard mode (issue 21) ---------------------------------------------------------------

POS_ONLY = 0b0000_1111_1111_1000   # x, y, z used; velocity, acceleration, yaw rate ignored
VEL_ONLY = 0b0000_1101_1100_0111   # vx, vy, vz and yaw used


def _lpos(v):
    """The estimator's local position (NED, m) now."""
    v.sampler.new_sample()
    return v.sampler.topic("vehicle_local_position")


def _stream(v, seconds, pos=None, vel=None, yaw=0.0, rate_hz=20, until=None):
    """SET_POSITION_TARGET_LOCAL_NED at ``rate_hz`` (position or velocity) for up to ``seconds``
    of virtual time, or until ``until()`` holds; returns the seconds streamed."""
    mask = POS_ONLY if pos is not None else VEL_ONLY
    x, y, z = pos if pos is not None else (0.0, 0.0, 0.0)
    vx, vy, vz = vel if vel is not None else (0.0, 0.0, 0.0)
    n = int(seconds * rate_hz)
    for i in range(n):
        v.gcs.send(mav.MAVLink_set_position_target_local_ned_message(
            0, 1, 1, mav.MAV_FRAME_LOCAL_NED, mask, x, y, z, vx, vy, vz, 0, 0, 0, yaw, 0))
        v.run(1.0 / rate_hz)
        if until is not None and until():
            return (i + 1) / rate_hz
    return n / rate_hz


ATT_ONLY = 0b0000_0111   # the attitude and thrust used; body rates ignored
RATES_ONLY = 0b1000_0000  # the body rates and thrust used; the attitude ignored


def _stream_attitude(v, seconds, q=(1.0, 0.0, 0.0, 0.0), rates=(0.0, 0.0, 0.0), thrust=0.5,
                     rate_hz=50):
    """SET_ATTITUDE_TARGET at ``rate_hz`` for ``seconds`` of virtual time: the attitude when
    ``rates`` is all zero, else the body rates (attitude ignored)."""
    mask = RATES_ONLY if any(rates) else ATT_ONLY
    for _ in range(int(seconds * rate_hz)):
        v.gcs.send(mav.MAVLink_set_attitude_target_message(
            0, 1, 1, mask, list(q), rates[0], rates[1], rates[2], thrust))
        v.run(1.0 / rate_hz)


def _yaw(v):
    """The estimator's heading (rad)."""
    v.sampler.new_sample()
    w, x, y, z = v.sampler.topic("vehicle_attitude")["q"]
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


@pytest.mark.slow
def test_offboard_square_velocity_and_loss(hil_vehicle):
    """pymavlink as an offboard companion, PX4's rules (in one flight, to keep it short):
    without a setpoint stream the switch to Offboard is refused; with one at 20 Hz it is
    accepted; a square of four 5 m position setpoints at 4 m is flown corner by corner (each
    reached within 1 m); 1 m/s north in velocity setpoints moves the vehicle north at about
    that speed; an attitude setpoint (heading east) is flown, then body rates (0.5 rad/s yaw)
    reach the rate controller unchanged; when the stream stops, after COM_OF_LOSS_T (1 s) the
    commander says so and flies COM_OBL_RC_ACT's mode (0: Position, RC being there)."""
    v = hil_vehicle
    gcs = v.gcs
    v.wait_for("home_set", within=40.0, step=0.2)
    v.dev["safety"].press(v.orch.t_ns + 100_000_000, hold_s=1.5)
    v.wait_for("topic.px4io_status.status_safety_off", within=5.0)
    assert gcs.arm(timeout_s=2.0).result == mav.MAV_RESULT_ACCEPTED
    assert gcs.takeoff(4.0).result == mav.MAV_RESULT_ACCEPTED
    v.wait_for("alt_agl_m > 3.6", within=15.0, step=0.1)

    # (1) no stream: refused, the vehicle stays where it was
    ack = gcs.set_mode(6)
    assert ack.result != mav.MAV_RESULT_ACCEPTED
    assert v.read("nav_state").lower() != "offboard"

    # a stream first (hold here), then the switch
    lp = _lpos(v)
    x0, y0, z0 = lp["x"], lp["y"], lp["z"]
    _stream(v, 0.5, pos=(x0, y0, z0))
    mark = gcs.mark()
    assert gcs.set_mode(6).result == mav.MAV_RESULT_ACCEPTED
    _stream(v, 0.3, pos=(x0, y0, z0))
    assert v.read("nav_state").lower() == "offboard"

    # (2) the square
    for dx, dy in ((5.0, 0.0), (5.0, 5.0), (0.0, 5.0), (0.0, 0.0)):
        tx, ty = x0 + dx, y0 + dy

        def there(tx=tx, ty=ty):
            p = _lpos(v)
            return math.hypot(p["x"] - tx, p["y"] - ty) < 1.0 and abs(p["z"] - z0) < 1.0
        took = _stream(v, 10.0, pos=(tx, ty, z0), until=there)
        assert there(), (dx, dy, _lpos(v))
        assert took < 10.0
    assert v.read("nav_state").lower() == "offboard"

    # (3) velocity: 1 m/s north for 3 s; speed measured over the last 2 s
    _stream(v, 1.0, vel=(1.0, 0.0, 0.0))
    xa, ta = _lpos(v)["x"], v.t_s
    _stream(v, 2.0, vel=(1.0, 0.0, 0.0))
    lp = _lpos(v)
    speed_n = (lp["x"] - xa) / (v.t_s - ta)
    assert 0.75 < speed_n < 1.25, speed_n
    assert abs(lp["vy"]) < 0.3 and abs(lp["z"] - z0) < 1.0

    # (3b) attitude: level, heading 90 deg east, hover thrust; the vehicle turns to it
    hover = v.read("topic.hover_thrust_estimate.hover_thrust") or 0.5
    east = (math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4))
    _stream_attitude(v, 3.0, q=east, thrust=hover)
    yaw = _yaw(v)
    assert abs(math.remainder(yaw - math.pi / 2, 2 * math.pi)) < math.radians(10), \
        math.degrees(yaw)
    assert abs(_lpos(v)["z"] - z0) < 1.5

    # (3c) body rates (attitude ignored): 0.5 rad/s yaw, level, hover thrust; the rate
    # controller gets them unchanged (mc_att_control stands aside, as PX4), the vehicle turns
    _stream_attitude(v, 0.5, rates=(0.0, 0.0, 0.5), thrust=hover)
    y0, t0 = _yaw(v), v.t_s
    _stream_attitude(v, 1.0, rates=(0.0, 0.0, 0.5), thrust=hover)
    rate = math.remainder(_yaw(v) - y0, 2 * math.pi) / (v.t_s - t0)
    assert 0.35 < rate < 0.65, rate
    sp = v.read("topic.vehicle_rates_setpoint.yaw")
    assert abs(sp - 0.5) < 1e-6, sp
    assert v.read("nav_state").lower() == "offboard"

    # (4) the stream stops: COM_OF_LOSS_T (1 s) later the failsafe takes over
    took = v.wait_for("nav_state != Offboard", within=1.6, step=0.05)
    assert took > 0.8, took
    assert v.read("nav_state").lower() == "position" and v.read("failsafe")
    texts = [m.text for m in gcs.messages("STATUSTEXT", since=mark)]
    assert any("offboard control lost" in t.lower() for t in texts), texts
