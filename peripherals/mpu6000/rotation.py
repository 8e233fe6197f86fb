"""Mounting of the chip: the shared PX4 rotation table (common/rotation.py)."""

from common.rotation import PX4_ROTATIONS, Matrix3, board_to_sensor, euler_matrix

__all__ = ["PX4_ROTATIONS", "Matrix3", "board_to_sensor", "euler_matrix"]
