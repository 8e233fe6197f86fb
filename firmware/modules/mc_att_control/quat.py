"""Quaternion helpers on plain tuples (w, x, y, z), Hamilton convention, PX4's frames.

A quaternion ``q`` of vehicle_attitude rotates NED into body FRD; its rotation matrix maps body
vectors into NED (``v_ned = R(q) v_body``). Tuples of floats keep the 250 Hz attitude loop free
of numpy's per-call overhead, which dominates for 3- and 4-vectors.
"""

from __future__ import annotations

import math

__all__ = [
    "Quat",
    "body_z_ned",
    "ned_z_body",
    "qconj",
    "qfrom_axis_angle",
    "qfrom_dcm_columns",
    "qfrom_euler",
    "qmul",
    "qnormalize",
    "qrotate",
    "qto_euler",
    "qyaw",
]

Quat = tuple[float, float, float, float]


def qmul(a: Quat, b: Quat) -> Quat:
    """Hamilton product a * b (apply b, then a, for frame-rotation chains)."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


def qconj(q: Quat) -> Quat:
    return (q[0], -q[1], -q[2], -q[3])


def qnormalize(q: Quat) -> Quat:
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    if n < 1e-12:
        return (1.0, 0.0, 0.0, 0.0)
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


def qfrom_euler(roll: float, pitch: float, yaw: float) -> Quat:
    """3-2-1 Euler angles (yaw, then pitch, then roll) to a quaternion."""
    cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
    cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


def qto_euler(q: Quat) -> tuple[float, float, float]:
    """Roll, pitch, yaw (3-2-1) of a quaternion."""
    w, x, y, z = q
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    s = 2.0 * (w * y - z * x)
    pitch = math.asin(-1.0 if s < -1.0 else (min(s, 1.0)))
    yaw = math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
    return roll, pitch, yaw


def qyaw(q: Quat) -> float:
    """The 3-2-1 yaw of a quaternion (heading)."""
    w, x, y, z = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def qfrom_axis_angle(rx: float, ry: float, rz: float) -> Quat:
    """Quaternion of the rotation vector (rx, ry, rz) (axis times angle, rad)."""
    a = math.sqrt(rx * rx + ry * ry + rz * rz)
    if a < 1e-9:
        return (1.0, 0.5 * rx, 0.5 * ry, 0.5 * rz)
    s = math.sin(0.5 * a) / a
    return (math.cos(0.5 * a), rx * s, ry * s, rz * s)


def qfrom_dcm_columns(c0: tuple[float, float, float], c1: tuple[float, float, float],
                      c2: tuple[float, float, float]) -> Quat:
    """Quaternion of the rotation matrix with these columns (body axes expressed in NED)."""
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
    return qnormalize(q)


def body_z_ned(q: Quat) -> tuple[float, float, float]:
    """The body z axis (down through the motors) expressed in NED: third column of R(q)."""
    w, x, y, z = q
    return (2.0 * (x * z + w * y), 2.0 * (y * z - w * x), w * w - x * x - y * y + z * z)


def ned_z_body(q: Quat) -> tuple[float, float, float]:
    """The NED down axis expressed in body: third row of R(q)."""
    w, x, y, z = q
    return (2.0 * (x * z - w * y), 2.0 * (y * z + w * x), w * w - x * x - y * y + z * z)


def qrotate(q: Quat, v: tuple[float, float, float]) -> tuple[float, float, float]:
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
