"""Ground truth of the world at one instant, in SI units and PX4 frames: the truth record schema.

The world (hil/) fills it, the FMU board (board/) feeds its sensors from it as a plain tuple in
:data:`TRUTH_FIELDS` order, tests and calibration jigs build it: so it lives in the bottom
package, which every layer may import.

Frames: body FRD (x forward, y right, z down), navigation NED (north, east, down) at the
vehicle. Vectors are tuples of floats (cheap to build, immutable, no numpy overhead per step).

Conventions worth checking twice:

* ``accel_body_m_s2`` is the specific force at the IMU (what an ideal accelerometer reads):
  at rest and level it is (0, 0, -g), as PX4's sensor_accel reports (z ~ -9.81 m/s^2).
* ``gyro_rad_s`` is the body rate relative to inertial space (what a gyro reads; includes the
  Earth's rotation, 7.3e-5 rad/s).
* ``q_nb`` (w, x, y, z) is the attitude as PX4's vehicle_attitude.q: the rotation from NED to
  the body frame, i.e. q = q_yaw * q_pitch * q_roll, and its DCM maps body vectors into NED
  (v_ned = R(q) v_body). ``euler_rad`` is (roll, pitch, yaw) of the same rotation.
* ``alt_m`` is the altitude of the IMU above the WGS-84 ellipsoid, which the world uses as
  mean sea level (no geoid). ``pos_ned_m`` is relative to the start point (north/east on the
  local tangent plane, down = start altitude - altitude).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from common.quaternion import Quat, Vec3

__all__ = ["TRUTH_FIELDS", "Truth", "dcm_nb_from_euler", "rotate_ned_to_body"]


@dataclass(slots=True)
class Truth:
    """World state at ``t_ns``. Treat as read-only (it may be shared by several readers)."""

    t_ns: int
    accel_body_m_s2: Vec3  # specific force at the IMU, body FRD
    gyro_rad_s: Vec3  # inertial angular rate, body FRD
    q_nb: Quat  # attitude quaternion (w, x, y, z), PX4 convention
    euler_rad: Vec3  # roll, pitch, yaw
    mag_body_gauss: Vec3  # Earth field in body FRD
    pressure_pa: float  # static pressure at the vehicle
    temperature_c: float  # static air temperature at the vehicle
    lat_deg: float
    lon_deg: float
    alt_m: float  # AMSL (= WGS-84 ellipsoid height here)
    agl_m: float  # height of the IMU above the terrain
    pos_ned_m: Vec3  # from the start point
    vel_ned_m_s: Vec3  # ground velocity
    airspeed_m_s: float  # true airspeed
    diff_pressure_pa: float  # dynamic pressure (what a pitot-static sensor measures)
    battery_v: float
    battery_a: float
    # appended last (issue 23), so older records' field indices stay valid; defaults for
    # truth sources without a wing (calibration jig)
    aoa_rad: float = 0.0  # angle of attack, atan2(w, u) of the air-relative body velocity
    sideslip_rad: float = 0.0  # sideslip, asin(v / airspeed), positive: wind from the right


#: Field order of a truth record, as it crosses from the world to the FMU board.
TRUTH_FIELDS: tuple[str, ...] = tuple(Truth.__dataclass_fields__)


def dcm_nb_from_euler(roll: float, pitch: float, yaw: float) -> tuple[Vec3, Vec3, Vec3]:
    """Rows of the matrix that maps NED vectors into body FRD (transpose of R(q))."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return (
        (cp * cy, cp * sy, -sp),
        (sr * sp * cy - cr * sy, sr * sp * sy + cr * cy, sr * cp),
        (cr * sp * cy + sr * sy, cr * sp * sy - sr * cy, cr * cp),
    )


def rotate_ned_to_body(v_ned: Vec3, roll: float, pitch: float, yaw: float) -> Vec3:
    """Express a NED vector in body FRD axes."""
    r0, r1, r2 = dcm_nb_from_euler(roll, pitch, yaw)
    x, y, z = v_ned
    return (
        r0[0] * x + r0[1] * y + r0[2] * z,
        r1[0] * x + r1[1] * y + r1[2] * z,
        r2[0] * x + r2[1] * y + r2[2] * z,
    )
