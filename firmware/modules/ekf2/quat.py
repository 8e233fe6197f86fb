"""Quaternion helpers in plain floats (w, x, y, z), Hamilton convention.

A quaternion ``q`` here is PX4's attitude: it rotates body vectors into NED
(``v_ned = R(q) v_body``), ``R(a * b) = R(a) R(b)``. These run at the IMU rate, where a numpy
call per operation would cost more than the arithmetic, hence tuples and unrolled formulas.
"""

from __future__ import annotations

import math
from typing import Final

__all__ = [
    "Quat",
    "dcm",
    "q_from_euler",
    "q_from_rotvec",
    "q_mul",
    "q_norm",
    "q_to_euler",
    "q_yaw",
    "wrap_pi",
]

Quat = tuple[float, float, float, float]

_PI: Final = math.pi
_TWO_PI: Final = 2.0 * math.pi


def wrap_pi(a: float) -> float:
    """Angle wrapped to [-pi, pi)."""
    if -_PI <= a < _PI:
        return a
    return (a + _PI) % _TWO_PI - _PI


def q_mul(a: Quat, b: Quat) -> Quat:
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


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


def q_norm(q: Quat) -> Quat:
    w, x, y, z = q
    n = 1.0 / math.sqrt(w * w + x * x + y * y + z * z)
    if w < 0.0:
        n = -n  # keep w >= 0, as PX4 publishes
    return (w * n, x * n, y * n, z * n)


def q_from_euler(roll: float, pitch: float, yaw: float) -> Quat:
    """q = q_yaw * q_pitch * q_roll (Z-Y-X, as PX4's Eulerf -> Quatf)."""
    cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
    cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
    cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
    return (cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy)


def q_yaw(q: Quat) -> float:
    w, x, y, z = q
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def q_to_euler(q: Quat) -> tuple[float, float, float]:
    w, x, y, z = q
    roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
    s = 2.0 * (w * y - z * x)
    pitch = math.asin(max(-1.0, min(1.0, s)))
    return roll, pitch, math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def dcm(q: Quat) -> tuple[float, float, float, float, float, float, float, float, float]:
    """R(q) row-major: body -> NED."""
    w, x, y, z = q
    ww, xx, yy, zz = w * w, x * x, y * y, z * z
    xy, xz, yz = x * y, x * z, y * z
    wx, wy, wz = w * x, w * y, w * z
    return (ww + xx - yy - zz, 2.0 * (xy - wz), 2.0 * (xz + wy),
            2.0 * (xy + wz), ww - xx + yy - zz, 2.0 * (yz - wx),
            2.0 * (xz - wy), 2.0 * (yz + wx), ww - xx - yy + zz)
