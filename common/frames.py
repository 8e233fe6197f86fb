"""Frames between PX4 and ROS: PX4's NED world and FRD body, ROS's ENU world and FLU body.

PX4 states positions and velocities in a local North-East-Down frame and attitudes as the
rotation from the Forward-Right-Down body frame to NED (``vehicle_attitude.q``, w x y z). ROS
(REP 103, REP 105) uses East-North-Up for ``map``/``odom`` and Forward-Left-Up for
``base_link``, and mavros converts between the two at its boundary; so does the ROS edge here,
with the same conventions, so that a ROS user's nodes work unchanged against PX4 with mavros
and against this emulator:

* world vectors: ``(x, y, z)_ENU = (y, x, -z)_NED`` (a 180 degree rotation about the axis
  between north and east, its own inverse);
* body vectors: ``(x, y, z)_FLU = (x, -y, -z)_FRD`` (180 degrees about the roll axis);
* orientations: ``q_ENU<-FLU = q_ENU<-NED * q_NED<-FRD * q_FRD<-FLU``, so a vehicle level and
  nose north (PX4: identity) is, in ROS, yawed +90 degrees from east;
* headings: ``yaw_ENU = pi/2 - yaw_NED`` (both wrapped to [-pi, pi]).

Pure functions on tuples (no rospy, no numpy; quaternions from :mod:`common.quaternion`, w x y
z, Hamilton, as PX4's and ROS's), in the bottom package since frames are every layer's
business: unit tested in tests/ros/test_ros_convert.py.
"""

from __future__ import annotations

import math
from typing import Final

from common.quaternion import Quat, Vec3, q_conj, q_mul, q_norm, wrap_pi

__all__ = ["Q_ENU_NED", "Q_FRD_FLU", "enu_to_ned", "flu_to_frd", "frd_to_flu", "ned_to_enu",
           "q_enu_flu_from_ned_frd", "q_ned_frd_from_enu_flu", "yaw_enu_from_ned",
           "yaw_ned_from_enu"]

_H: Final = math.sqrt(0.5)
#: the rotation taking NED vectors to ENU ones (180 degrees about (1, 1, 0)/sqrt 2)
Q_ENU_NED: Final[Quat] = (0.0, _H, _H, 0.0)
#: the rotation taking FLU vectors to FRD ones (180 degrees about x); its own inverse
Q_FRD_FLU: Final[Quat] = (0.0, 1.0, 0.0, 0.0)


def ned_to_enu(v: Vec3) -> Vec3:
    """A world vector (position, velocity, acceleration) from NED to ENU."""
    return (v[1], v[0], -v[2])


def enu_to_ned(v: Vec3) -> Vec3:
    """A world vector from ENU to NED (the same swap: the rotation is its own inverse)."""
    return (v[1], v[0], -v[2])


def frd_to_flu(v: Vec3) -> Vec3:
    """A body vector (rates, specific force, body velocity) from FRD to FLU."""
    return (v[0], -v[1], -v[2])


def flu_to_frd(v: Vec3) -> Vec3:
    return (v[0], -v[1], -v[2])


def q_enu_flu_from_ned_frd(q: Quat) -> Quat:
    """PX4's attitude (FRD body -> NED) as ROS's orientation (FLU body -> ENU)."""
    return q_norm(q_mul(q_mul(Q_ENU_NED, q), Q_FRD_FLU))


def q_ned_frd_from_enu_flu(q: Quat) -> Quat:
    """A ROS orientation (FLU -> ENU) as PX4's attitude (FRD -> NED): the inverse map."""
    return q_norm(q_mul(q_mul(q_conj(Q_ENU_NED), q), q_conj(Q_FRD_FLU)))


def yaw_ned_from_enu(yaw_enu: float) -> float:
    """A ROS heading (from east, counter-clockwise) as PX4's (from north, clockwise)."""
    return wrap_pi(math.pi / 2.0 - yaw_enu)


def yaw_enu_from_ned(yaw_ned: float) -> float:
    return wrap_pi(math.pi / 2.0 - yaw_ned)
