"""IMU drivers, and PX4's sensor rotations they apply to raw data.

A rotation enum names how a sensor is mounted; its matrix takes sensor axes to board axes
(PX4 ``rotation.h``: roll, pitch, yaw in degrees, Z-Y-X order). It belongs in a shared
``firmware/lib/conversion`` module once one exists; it lives here until then.
"""

from __future__ import annotations

import math

__all__ = ["PX4_ROTATIONS", "rotation_matrix"]

#: PX4 rotation enum -> (name, roll, pitch, yaw) in degrees.
PX4_ROTATIONS: dict[int, tuple[str, float, float, float]] = {
    0: ("ROTATION_NONE", 0, 0, 0), 1: ("ROTATION_YAW_45", 0, 0, 45),
    2: ("ROTATION_YAW_90", 0, 0, 90), 3: ("ROTATION_YAW_135", 0, 0, 135),
    4: ("ROTATION_YAW_180", 0, 0, 180), 5: ("ROTATION_YAW_225", 0, 0, 225),
    6: ("ROTATION_YAW_270", 0, 0, 270), 7: ("ROTATION_YAW_315", 0, 0, 315),
    8: ("ROTATION_ROLL_180", 180, 0, 0), 9: ("ROTATION_ROLL_180_YAW_45", 180, 0, 45),
    10: ("ROTATION_ROLL_180_YAW_90", 180, 0, 90), 11: ("ROTATION_ROLL_180_YAW_135", 180, 0, 135),
    12: ("ROTATION_PITCH_180", 0, 180, 0), 13: ("ROTATION_ROLL_180_YAW_225", 180, 0, 225),
    14: ("ROTATION_ROLL_180_YAW_270", 180, 0, 270),
    15: ("ROTATION_ROLL_180_YAW_315", 180, 0, 315),
    16: ("ROTATION_ROLL_90", 90, 0, 0), 17: ("ROTATION_ROLL_90_YAW_45", 90, 0, 45),
    18: ("ROTATION_ROLL_90_YAW_90", 90, 0, 90), 19: ("ROTATION_ROLL_90_YAW_135", 90, 0, 135),
    20: ("ROTATION_ROLL_270", 270, 0, 0), 21: ("ROTATION_ROLL_270_YAW_45", 270, 0, 45),
    22: ("ROTATION_ROLL_270_YAW_90", 270, 0, 90), 23: ("ROTATION_ROLL_270_YAW_135", 270, 0, 135),
    24: ("ROTATION_PITCH_90", 0, 90, 0), 25: ("ROTATION_PITCH_270", 0, 270, 0),
}
_BY_NAME = {name: code for code, (name, *_rest) in PX4_ROTATIONS.items()}


def rotation_matrix(rotation: int | str) -> tuple[tuple[float, ...], ...] | None:
    """Sensor->board matrix of a PX4 rotation (enum or name); None for ROTATION_NONE so the
    hot path can skip the multiply."""
    code = _BY_NAME.get(rotation) if isinstance(rotation, str) else rotation
    if code not in PX4_ROTATIONS:
        raise ValueError(f"unknown PX4 rotation {rotation!r}")
    if code == 0:
        return None
    _, roll, pitch, yaw = PX4_ROTATIONS[code]
    cr, sr = math.cos(math.radians(roll)), math.sin(math.radians(roll))
    cp, sp = math.cos(math.radians(pitch)), math.sin(math.radians(pitch))
    cy, sy = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    m = ((cp * cy, -cr * sy + sr * sp * cy, sr * sy + cr * sp * cy),
         (cp * sy, cr * cy + sr * sp * sy, -sr * cy + cr * sp * sy),
         (-sp, sr * cp, cr * cp))
    # Snap cos(90 deg) = 6e-17 to 0 so axis swaps are exact.
    return tuple(tuple(float(round(v)) if abs(v - round(v)) < 1e-12 else v for v in row)
                 for row in m)
