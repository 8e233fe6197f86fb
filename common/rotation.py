"""PX4's sensor rotations (``rotation.h``): how a chip is mounted on a board.

A rotation enum's matrix takes sensor axes to board axes (roll, pitch, yaw in degrees, Z-Y-X
Euler order). Drivers apply it to raw data (:func:`rotation_matrix`); device models apply its
transpose to the board's physical quantities (:func:`board_to_sensor`). One table serves both,
so a model and its driver can never disagree about a mounting: it lives in the bottom package,
which device models and firmware may both import (a model importing firmware was the smell).
"""


from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Final

__all__ = ["PX4_ROTATIONS", "Matrix3", "board_to_sensor", "euler_matrix", "rotation_matrix"]

Matrix3 = tuple[tuple[float, float, float], tuple[float, float, float],
                tuple[float, float, float]]

#: PX4 rotation enum -> (name, roll, pitch, yaw) in degrees.
PX4_ROTATIONS: Final[dict[int, tuple[str, float, float, float]]] = {
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
_BY_NAME: Final = {name: code for code, (name, *_rest) in PX4_ROTATIONS.items()}


def _snap(v: float) -> float:
    # cos(90 deg) is 6e-17, not 0: snap so that axis swaps are exact and deterministic.
    r = round(v)
    return float(r) if abs(v - r) < 1e-12 else v


def euler_matrix(roll_deg: float, pitch_deg: float, yaw_deg: float) -> Matrix3:
    """Direction cosine matrix Rz(yaw) Ry(pitch) Rx(roll) (PX4's ``Dcmf(Eulerf(...))``)."""
    cr, sr = math.cos(math.radians(roll_deg)), math.sin(math.radians(roll_deg))
    cp, sp = math.cos(math.radians(pitch_deg)), math.sin(math.radians(pitch_deg))
    cy, sy = math.cos(math.radians(yaw_deg)), math.sin(math.radians(yaw_deg))
    m = ((cp * cy, -cr * sy + sr * sp * cy, sr * sy + cr * sp * cy),
         (cp * sy, cr * cy + sr * sp * sy, -sr * cy + cr * sp * sy),
         (-sp, sr * cp, cr * cp))
    return tuple(tuple(_snap(v) for v in row) for row in m)  # type: ignore[return-value]


def board_to_sensor(rotation: int | str | Sequence[Sequence[float]] | None) -> Matrix3 | None:
    """The board->sensor matrix for ``rotation``, or None for identity (the fast path).

    ``rotation`` is a PX4 enum (int or name such as ``"ROTATION_YAW_180"``): its matrix is
    sensor->board, so the transpose is returned. A 3x3 matrix is used as given.
    """
    if rotation is None:
        return None
    if isinstance(rotation, str):
        if rotation not in _BY_NAME:
            raise ValueError(f"unknown PX4 rotation {rotation!r}; known: {', '.join(_BY_NAME)}")
        rotation = _BY_NAME[rotation]
    if isinstance(rotation, int):
        if rotation not in PX4_ROTATIONS:
            raise ValueError(f"unknown PX4 rotation enum {rotation}; known 0..{max(PX4_ROTATIONS)}")
        if rotation == 0:
            return None
        _, r, p, y = PX4_ROTATIONS[rotation]
        m = euler_matrix(r, p, y)
        return tuple(tuple(m[j][i] for j in range(3)) for i in range(3))  # type: ignore
    rows = [tuple(float(v) for v in row) for row in rotation]
    if len(rows) != 3 or any(len(row) != 3 for row in rows):
        raise ValueError(f"rotation matrix must be 3x3, got {rotation!r}")
    if rows == [(1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)]:
        return None
    return tuple(rows)  # type: ignore[return-value]


def rotation_matrix(rotation: int | str) -> Matrix3 | None:
    """Sensor->board matrix of a PX4 rotation (enum or name); None for ROTATION_NONE so a
    driver's hot path can skip the multiply."""
    code = _BY_NAME.get(rotation) if isinstance(rotation, str) else rotation
    if code not in PX4_ROTATIONS:
        raise ValueError(f"unknown PX4 rotation {rotation!r}")
    if code == 0:
        return None
    _, r, p, y = PX4_ROTATIONS[code]
    return euler_matrix(r, p, y)
