"""Frames at the ROS edge (common/frames.py, hil/ros/views.py): PX4's NED/FRD against ROS's
ENU/FLU, as mavros converts them. Known attitudes, round trips, and the views built from uORB
messages (no ROS master needed: only the message classes)."""

from __future__ import annotations

import math
import random

import pytest

from firmware.platform.msgdef import default_registry
from common.frames import (enu_to_ned, frd_to_flu, ned_to_enu, q_enu_flu_from_ned_frd,
                           q_ned_frd_from_enu_flu, yaw_enu_from_ned, yaw_ned_from_enu)
from common.quaternion import q_from_euler, q_mul, q_rotate, q_yaw

REG = default_registry()


def _new(topic, **kw):
    return REG.cls(topic)(**kw)


def _close(a, b, tol=1e-9):
    return all(abs(x - y) <= tol for x, y in zip(a, b, strict=True))


def _same_rotation(a, b, tol=1e-9):
    return _close(a, b, tol) or _close(a, tuple(-c for c in b), tol)


def _random_quat(rng):
    q = [rng.gauss(0, 1) for _ in range(4)]
    n = math.sqrt(sum(c * c for c in q))
    return tuple(c / n for c in q)


def test_world_vectors():
    assert ned_to_enu((1.0, 2.0, 3.0)) == (2.0, 1.0, -3.0)   # north 1, east 2, down 3
    assert enu_to_ned(ned_to_enu((1.0, -2.0, 3.5))) == (1.0, -2.0, 3.5)
    assert frd_to_flu((1.0, 2.0, 3.0)) == (1.0, -2.0, -3.0)


def test_level_nose_north_is_yaw_90_in_enu():
    q = q_enu_flu_from_ned_frd((1.0, 0.0, 0.0, 0.0))
    assert _close(q, (math.sqrt(0.5), 0.0, 0.0, math.sqrt(0.5)))
    assert q_yaw(q) == pytest.approx(math.pi / 2)


def test_nose_east_is_identity_in_enu():
    q = q_enu_flu_from_ned_frd(q_from_euler(0.0, 0.0, math.pi / 2))  # PX4 yaw +90: nose east
    assert _same_rotation(q, (1.0, 0.0, 0.0, 0.0), 1e-12)


def test_right_wing_down_roll():
    """PX4 roll +30 deg (right wing down), nose north: ROS's body left axis points west and up."""
    r = math.radians(30)
    q_ned = (math.cos(r / 2), math.sin(r / 2), 0.0, 0.0)
    q = q_enu_flu_from_ned_frd(q_ned)
    assert _close(q_rotate(q, (1.0, 0.0, 0.0)), (0.0, 1.0, 0.0))  # forward: north
    assert _close(q_rotate(q, (0.0, 1.0, 0.0)), (-math.cos(r), 0.0, math.sin(r)))


def test_orientation_round_trip_and_body_vectors():
    rng = random.Random(24)
    for _ in range(200):
        q = _random_quat(rng)
        back = q_ned_frd_from_enu_flu(q_enu_flu_from_ned_frd(q))
        assert _same_rotation(back, q, 1e-9)
        # a body vector seen in the world is the same physical vector in both conventions
        v = (rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-5, 5))
        assert _close(ned_to_enu(q_rotate(q, v)),
                      q_rotate(q_enu_flu_from_ned_frd(q), frd_to_flu(v)), 1e-9)


def test_headings():
    assert yaw_enu_from_ned(0.0) == pytest.approx(math.pi / 2)    # north
    assert yaw_enu_from_ned(math.pi / 2) == pytest.approx(0.0)    # east
    assert yaw_ned_from_enu(math.pi) == pytest.approx(-math.pi / 2)  # west
    for y in (-3.0, -1.0, 0.2, 2.9):
        assert yaw_ned_from_enu(yaw_enu_from_ned(y)) == pytest.approx(y)
        q = q_mul(q_from_euler(0.0, 0.0, y), (1.0, 0.0, 0.0, 0.0))
        assert q_yaw(q_enu_flu_from_ned_frd(q)) == pytest.approx(yaw_enu_from_ned(y))


def test_views_from_uorb():
    from hil.ros import views

    yaw = 0.3
    att = _new("vehicle_attitude", timestamp=2_500_000, q=list(q_from_euler(0.0, 0.0, yaw)))
    lpos = _new("vehicle_local_position", timestamp=2_600_000, x=2.0, y=1.0, z=-3.0,
                vx=1.0, vy=0.0, vz=-0.5)
    sc = _new("sensor_combined", timestamp=2_700_001, gyro_rad=[0.1, 0.2, 0.3],
              accelerometer_m_s2=[0.0, 0.0, -9.81])
    p = views.pose(lpos, att)
    assert (p.pose.position.x, p.pose.position.y, p.pose.position.z) == (1.0, 2.0, 3.0)
    assert p.header.stamp.secs == 2 and p.header.stamp.nsecs == 600_000_000
    assert p.header.frame_id == "map"
    o = p.pose.orientation
    assert q_yaw((o.w, o.x, o.y, o.z)) == pytest.approx(math.pi / 2 - yaw)
    imu = views.imu(att, sc)
    assert (imu.angular_velocity.x, imu.angular_velocity.y, imu.angular_velocity.z) == \
        pytest.approx((0.1, -0.2, -0.3))
    assert imu.linear_acceleration.z == pytest.approx(9.81)  # at rest: +g up in FLU
    assert imu.header.stamp.nsecs == 700_001_000
    od = views.odom(lpos, att, sc)
    # 1 m/s north, 0.5 m/s up; the nose 0.3 rad east of north, so north is ahead and to the left
    assert (od.twist.twist.linear.x, od.twist.twist.linear.y, od.twist.twist.linear.z) == \
        pytest.approx((math.cos(yaw), math.sin(yaw), 0.5))
    assert od.child_frame_id == "base_link"
    bat = views.battery(_new("battery_status", timestamp=1, connected=True, voltage_v=16.0,
                             voltage_filtered_v=15.9, current_a=8.0, current_filtered_a=7.5,
                             remaining=0.8, cell_count=4))
    assert bat.voltage == pytest.approx(15.9) and bat.current == pytest.approx(-7.5)
    assert bat.percentage == pytest.approx(0.8) and len(bat.cell_voltage) == 4
    fix = views.navsat(_new("vehicle_global_position", timestamp=1, lat=47.39, lon=8.54,
                            alt=488.0, eph=0.9, epv=1.5))
    assert (fix.latitude, fix.longitude, fix.altitude) == (47.39, 8.54, 488.0)
    assert fix.position_covariance[8] == pytest.approx(2.25)


def test_setpoint_from_pose():
    """mavros's setpoint_position/local: ENU (1, 2, 3) facing east -> NED (2, 1, -3), yaw 90 deg,
    the rest NaN (not controlled), offboard_control_mode position."""
    from geometry_msgs.msg import PoseStamped

    from hil.ros import views

    m = PoseStamped()
    m.pose.position.x, m.pose.position.y, m.pose.position.z = 1.0, 2.0, 3.0
    m.pose.orientation.w = 1.0
    sp, mode = views.setpoint_from_pose(m, 123, _new)
    assert sp.position == [2.0, 1.0, -3.0] and sp.timestamp == 123
    assert sp.yaw == pytest.approx(math.pi / 2)
    assert all(math.isnan(v) for v in (*sp.velocity, *sp.acceleration, sp.yawspeed))
    assert mode.position and not mode.velocity and mode.timestamp == 123
    m.pose.orientation.w = 0.0  # no orientation given: heading north
    assert views.setpoint_from_pose(m, 1, _new)[0].yaw == 0.0
    m.pose.position.z = float("nan")
    with pytest.raises(ValueError, match="not finite"):
        views.setpoint_from_pose(m, 1, _new)


def test_edge_records_and_drops():
    """The edge (hil/ros/link.py) without a master: what ROS sends becomes records the
    companion's ros_bridge accepts, at the next quantum's time; what does not fit is counted
    and dropped, as are bad records from the board."""
    from geometry_msgs.msg import PoseStamped

    from firmware.modules.ros_bridge.module import check_record
    from hil.ros import msggen
    from hil.ros.link import RosLink, load_topics

    topics = load_topics()
    link = RosLink(topics, log=lambda text: None)
    link.run_until(7_000_000)  # the quantum's end: what arrives now is stamped 7 ms
    VehicleCommand = msggen.ros_class("vehicle_command")
    link._on_in(VehicleCommand(command=400, param1=1.0, target_system=1), "vehicle_command")
    link._on_in(VehicleCommand(command=400, target_system=300), "vehicle_command")  # > uint8
    m = PoseStamped()
    m.pose.position.x, m.pose.position.z = 3.0, 4.0
    link._on_setpoint(m)  # needs views (rospy message classes only)
    m.pose.position.y = float("inf")
    link._on_setpoint(m)
    m.pose.position.y = 1e300  # finite, but no float32
    link._on_setpoint(m)
    link.run_until(7_000_000)
    out = link.outputs(7_000_000)
    sizes = {t: REG.topic(t).size for t in topics.inbound_names()}
    got = [check_record(p, sizes) for _port, _t, p in out]
    assert [g[0] for g in got] == ["vehicle_command", "offboard_control_mode",
                                   "trajectory_setpoint"]
    assert {t for _p, t, _v in out} == {7_000_000}
    cmd = REG.cls("vehicle_command").unpack(got[0][2])
    assert cmd.command == 400 and cmd.param1 == 1.0 and cmd.timestamp == 7000  # stamped now
    sp = REG.cls("trajectory_setpoint").unpack(got[2][2])
    assert sp.position == [0.0, 3.0, -4.0]
    assert sp.timestamp == 7000
    assert link.stats()["ros_dropped"] == 3 and link.stats()["records_to_board"] == 3
    link.input("ros", 1, ("vehicle_attitude", 0, b"short"))
    link.input("ros", 1, ("vehicle_attitude", 0, bytes(REG.topic("vehicle_attitude").size)))
    assert link.stats()["bad_records"] == 1 and link.stats()["records_from_board"] == 1
