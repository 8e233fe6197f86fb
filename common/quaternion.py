"""Quaternions on plain tuples (w, x, y, z), Hamilton convention, PX4's frames.

A quaternion ``q`` of vehicle_attitude rotates NED into body FRD; its rotation matrix maps body
vectors into NED (``v_ned = R(q) v_body``) and ``R(a * b) = R(a) R(b)``. The estimator runs
these at the IMU rate and the controllers at 250 Hz, where a numpy call per operation would cost
more than the arithmetic: hence tuples and unrolled formulas, and one library for both (the
estimator's and the attitude controller's were two until issue 19).
"""

from __future__ import annotations

import math
from typing import Final

__all__ = [
    "Quat",
    "Vec3",
    "body_z_ned",
    "dcm",
    "ned_z_body",
    "q_conj",
    "q_from_dcm_columns",
    "q_from_euler",
    "q_from_rotvec",
    "q_mul",
    "q_norm",
    "q_rotate",
    "q_to_euler",
    "q_yaw",
    "wrap_pi",
]

Quat = tuple[float, float, float, float]
Vec3 = tuple[float, float, float]

_PI: Final = math.pi
_TWO_PI: Final = 2.0 * math.pi


def wrap_pi(a: float) -> float:
    """Angle wrapped to [-pi, pi)."""
    if -_PI <= a < _PI:
        return a
    return (a + _PI) % _TWO_PI - _PI


def q_mul(a: Quat, b: Quat) -> Quat:
    """Hamilton product a * b (apply b, then a, for frame-rotation chains)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


def q_conj(q: Quat) -> Quat:
    return (q[0], -q[1], -q[2], -q[3])


def q_norm(q: Quat) -> Quat:
    """The unit quaternion with w >= 0, as PX4 publishes attitudes (one reciprocal)."""
    w, x, y, z = q
    n = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
    if w < 0.0:
        n = -n
    return (w * n, x * n, y * n, z * n)


def q_from_rotvec(x: float, y: float, z: float) -> Quat:
    """Rotation by the angle |v| about v (small angles by the series, exact otherwise)."""
    a2 = x * x + y * y + z * z
    if a2 < 1e-8:
        # cos(a/2) ~ 1 - a^2/8, sin(a/2)/a ~ 1/2 - a^2/48: exact to float precision here
        s = 0.5 - a2 / 48.0
        return (1.0 - a2 / 8.0, x * s, y * s, z * s)
    a = math.sqrt(a2)
    s = math.sin(0.5 * a) / a
    return (math.cos(0.5 * a), x * s, y * s, z * s)


def q_from_euler(roll: float, pitch: float, yaw: float) -> Quat:
    """3-2-1 Euler angles: q = q_yaw * q_pitch * q_roll (PX4's Eulerf -> Quatf)."""
    cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
    cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


def q_to_euler(q: Quat) -> tuple[float, float, float]:
    """Roll, pitch, yaw (3-2-1) of a quaternion; a NaN quaternion gives NaN angles."""
    w, x, y, z = q
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    s = 2.0 * (w * y - z * x)
    pitch = math.asin(-1.0 if s < -1.0 else (min(s, 1.0)))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


def q_yaw(q: Quat) -> float:
    """The 3-2-1 yaw of a quaternion (heading)."""
    w, x, y, z = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def dcm(q: Quat) -> tuple[float, float, float, float, float, float, float, float, float]:
    """R(q) row-major: body -> NED."""
    w, x, y, z = q
    ww, xx, yy, zz = w * w, x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return (ww + xx - yy - zz, 2.0 * (xy - wz), 2.0 * (xz + wy),
            2.0 * (xy + wz), ww - xx + yy - zz, 2.0 * (yz - wx),
            2.0 * (xz - wy), 2.0 * (yz + wx), ww - xx - yy + zz)


def q_from_dcm_columns(c0: Vec3, c1: Vec3, c2: Vec3) -> Quat:
    """Quaternion of the rotation matrix with these columns (body axes expressed in NED), w >= 0.

    Shepperd's method on the largest diagonal term, then a normalisation by division (the
    position controller's attitude setpoint is built this way every cycle; its logs depend on
    this exact arithmetic)."""
    r00, r10, r20 = c0
    r01, r11, r21 = c1
    r02, r12, r22 = c2
    tr = r00 + r11 + r22
    if tr > 0.0:
        s = math.sqrt(tr + 1.0) * 2.0
        q = (0.25 * s, (r21 - r12) / s, (r02 - r20) / s, (r10 - r01) / s)
    elif r00 > r11 and r00 > r22:
        s = math.sqrt(1.0 + r00 - r11 - r22) * 2.0
        q = ((r21 - r12) / s, 0.25 * s, (r01 + r10) / s, (r02 + r20) / s)
    elif r11 > r22:
        s = math.sqrt(1.0 + r11 - r00 - r22) * 2.0
        q = ((r02 - r20) / s, (r01 + r10) / s, 0.25 * s, (r12 + r21) / s)
    else:
        s = math.sqrt(1.0 + r22 - r00 - r11) * 2.0
        q = ((r10 - r01) / s, (r02 + r20) / s, (r12 + r21) / s, 0.25 * s)
    if q[0] < 0.0:
        q = (-q[0], -q[1], -q[2], -q[3])
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    if n < 1e-12:
        return (1.0, 0.0, 0.0, 0.0)
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def body_z_ned(q: Quat) -> Vec3:
    """The body z axis (down through the motors) expressed in NED: third column of R(q)."""
    w, x, y, z = q
    return (2.0 * (x * z + w * y), 2.0 * (y * z - w * x), w * w - x * x - y * y + z * z)


def ned_z_body(q: Quat) -> Vec3:
    """The NED down axis expressed in body: third row of R(q)."""
    w, x, y, z = q
    return (2.0 * (x * z - w * y), 2.0 * (y * z + w * x), w * w - x * x - y * y + z * z)


def q_rotate(q: Quat, v: Vec3) -> Vec3:
    """R(q) v: a body vector expressed in NED."""
    w, x, y, z = q
    vx, vy, vz = v
    # t = 2 * (q.xyz x v); v' = v + w t + q.xyz x t
    tx = 2.0 * (y * vz - z * vy)
    ty = 2.0 * (z * vx - x * vz)
    tz = 2.0 * (x * vy - y * vx)
    return (vx + w * tx + (y * tz - z * ty),
            vy + w * ty + (z * tx - x * tz),
            vz + w * tz + (x * ty - y * tx))
