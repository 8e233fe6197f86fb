"""Standard ROS views of the vehicle's uORB topics, and mavros's position setpoint back.

What a ROS 1 user's tools expect (rviz, robot_localization, navigation), in the frames and
sign conventions mavros publishes (ENU ``map`` world, FLU ``base_link`` body; common/frames.py):

=================================  ===========================  =================================
topic                              type                         from
=================================  ===========================  =================================
``/fmu/imu/data``                  sensor_msgs/Imu              vehicle_attitude, sensor_combined
``/fmu/local_position/pose``       geometry_msgs/PoseStamped    vehicle_local_position, attitude
``/fmu/local_position/odom``       nav_msgs/Odometry            the same (twist in base_link)
``/fmu/global_position/global``    sensor_msgs/NavSatFix        vehicle_global_position
``/fmu/battery``                   sensor_msgs/BatteryState     battery_status
=================================  ===========================  =================================

Stamps are the uORB message's own ``timestamp`` (virtual time since boot, the time ``/clock``
carries), so a node on ``use_sim_time`` sees them in its own clock.

The way back: ``/fmu/setpoint_position/local`` (geometry_msgs/PoseStamped, ENU) becomes, as in
mavros's setpoint_position plugin and PX4's handling of SET_POSITION_TARGET_LOCAL_NED, a
``trajectory_setpoint`` (NED position and yaw; velocity, acceleration, jerk and yaw rate NaN:
not controlled) and an ``offboard_control_mode`` with ``position`` set.
"""

from __future__ import annotations

import math
from typing import Any, Final

from common.frames import (enu_to_ned, frd_to_flu, ned_to_enu, q_enu_flu_from_ned_frd,
                           yaw_ned_from_enu)
from common.quaternion import q_conj, q_rotate, q_yaw
from hil.ros.msggen import ros_python_path

ros_python_path()

import genpy  # noqa: E402
from geometry_msgs.msg import PoseStamped  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from sensor_msgs.msg import BatteryState, Imu, NavSatFix, NavSatStatus  # noqa: E402

__all__ = ["BODY_FRAME", "WORLD_FRAME", "battery", "imu", "navsat", "odom", "pose",
           "setpoint_from_pose", "stamp"]

#: frame ids, mavros's defaults
WORLD_FRAME: Final = "map"
BODY_FRAME: Final = "base_link"
NAN: Final = float("nan")


def stamp(t_us: int) -> genpy.Time:
    """A ROS time from microseconds of virtual time."""
    t_us = max(0, int(t_us))
    return genpy.Time(t_us // 1_000_000, (t_us % 1_000_000) * 1000)


def _q(att: Any) -> tuple[float, float, float, float]:
    q = att.q
    return q_enu_flu_from_ned_frd((float(q[0]), float(q[1]), float(q[2]), float(q[3])))


def _set_q(dst: Any, q: tuple[float, float, float, float]) -> None:
    dst.w, dst.x, dst.y, dst.z = q


def imu(att: Any, sc: Any) -> Imu:
    """Orientation (ENU/FLU) from ``vehicle_attitude``, rates and specific force (FLU) from
    ``sensor_combined``; covariances unknown (0, as mavros's imu/data without a model)."""
    m = Imu()
    m.header.stamp = stamp(sc.timestamp)
    m.header.frame_id = BODY_FRAME
    _set_q(m.orientation, _q(att))
    g = frd_to_flu((sc.gyro_rad[0], sc.gyro_rad[1], sc.gyro_rad[2]))
    a = frd_to_flu((sc.accelerometer_m_s2[0], sc.accelerometer_m_s2[1],
                    sc.accelerometer_m_s2[2]))
    m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z = g
    m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = a
    return m


def pose(lpos: Any, att: Any) -> PoseStamped:
    m = PoseStamped()
    m.header.stamp = stamp(lpos.timestamp)
    m.header.frame_id = WORLD_FRAME
    p = ned_to_enu((lpos.x, lpos.y, lpos.z))
    m.pose.position.x, m.pose.position.y, m.pose.position.z = p
    _set_q(m.pose.orientation, _q(att))
    return m


def odom(lpos: Any, att: Any, sc: Any | None) -> Odometry:
    """Pose in ``map`` (ENU), twist in ``base_link`` (FLU), as mavros's local_position/odom."""
    m = Odometry()
    m.header.stamp = stamp(lpos.timestamp)
    m.header.frame_id = WORLD_FRAME
    m.child_frame_id = BODY_FRAME
    q = _q(att)
    m.pose.pose.position.x, m.pose.pose.position.y, m.pose.pose.position.z = ned_to_enu(
        (lpos.x, lpos.y, lpos.z))
    _set_q(m.pose.pose.orientation, q)
    v_body = q_rotate(q_conj(q), ned_to_enu((lpos.vx, lpos.vy, lpos.vz)))
    m.twist.twist.linear.x, m.twist.twist.linear.y, m.twist.twist.linear.z = v_body
    if sc is not None:
        w = frd_to_flu((sc.gyro_rad[0], sc.gyro_rad[1], sc.gyro_rad[2]))
        m.twist.twist.angular.x, m.twist.twist.angular.y, m.twist.twist.angular.z = w
    return m


def navsat(gpos: Any) -> NavSatFix:
    """Latitude and longitude in degrees, altitude above the WGS84 ellipsoid (NavSatFix's
    definition; AMSL when the estimator gives no ellipsoid height), covariance from eph/epv."""
    m = NavSatFix()
    m.header.stamp = stamp(gpos.timestamp)
    m.header.frame_id = BODY_FRAME
    m.status.status = NavSatStatus.STATUS_FIX
    m.status.service = NavSatStatus.SERVICE_GPS
    m.latitude, m.longitude = float(gpos.lat), float(gpos.lon)
    alt_e = float(gpos.alt_ellipsoid)
    m.altitude = alt_e if alt_e != 0.0 and math.isfinite(alt_e) else float(gpos.alt)
    eph2, epv2 = float(gpos.eph) ** 2, float(gpos.epv) ** 2
    m.position_covariance = [eph2, 0.0, 0.0, 0.0, eph2, 0.0, 0.0, 0.0, epv2]
    m.position_covariance_type = NavSatFix.COVARIANCE_TYPE_DIAGONAL_KNOWN
    return m


def battery(bat: Any) -> BatteryState:
    """sensor_msgs/BatteryState: current negative while discharging (its definition; mavros
    negates PX4's current the same way), percentage 0..1, NaN for what is not measured."""
    m = BatteryState()
    m.header.stamp = stamp(bat.timestamp)
    m.voltage = float(bat.voltage_filtered_v or bat.voltage_v)
    m.current = -float(bat.current_filtered_a or bat.current_a)
    m.charge = NAN
    m.capacity = NAN
    m.design_capacity = float(bat.capacity) / 1000.0 if bat.capacity else NAN
    m.percentage = float(bat.remaining)
    m.temperature = float(bat.temperature)
    m.power_supply_status = BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
    m.power_supply_health = BatteryState.POWER_SUPPLY_HEALTH_UNKNOWN
    m.power_supply_technology = BatteryState.POWER_SUPPLY_TECHNOLOGY_LIPO
    m.present = bool(bat.connected)
    m.cell_voltage = [NAN] * max(0, int(bat.cell_count))
    return m


def setpoint_from_pose(msg: PoseStamped, now_us: int, orb_new: Any) -> tuple[Any, Any]:
    """``(trajectory_setpoint, offboard_control_mode)`` uORB messages for a mavros-style
    position setpoint (ENU pose); ``orb_new(topic, **fields)`` makes a uORB message. A pose
    with a non-finite coordinate is refused (ValueError): NaN would mean "not controlled"."""
    p = msg.pose.position
    o = msg.pose.orientation
    xyz = (float(p.x), float(p.y), float(p.z))
    if not all(math.isfinite(c) for c in xyz):
        raise ValueError(f"setpoint position not finite: {xyz}")
    qn = math.sqrt(o.w * o.w + o.x * o.x + o.y * o.y + o.z * o.z)
    # an all-zero orientation (a user who set only the position): keep heading north (PX4 0)
    yaw_ned = 0.0 if not qn > 1e-6 or not math.isfinite(qn) else yaw_ned_from_enu(
        q_yaw((o.w / qn, o.x / qn, o.y / qn, o.z / qn)))
    ned = enu_to_ned(xyz)
    sp = orb_new("trajectory_setpoint", timestamp=now_us, position=list(ned),
                 velocity=[NAN] * 3, acceleration=[NAN] * 3, jerk=[NAN] * 3,
                 yaw=yaw_ned, yawspeed=NAN)
    mode = orb_new("offboard_control_mode", timestamp=now_us, position=True)
    return sp, mode
