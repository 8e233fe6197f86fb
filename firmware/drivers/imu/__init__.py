"""IMU drivers, and PX4's sensor rotations they apply to raw data.

A rotation enum names how a sensor is mounted; its matrix takes sensor axes to board axes
(PX4 ``rotation.h``: roll, pitch, yaw in degrees, Z-Y-X order). The table lives in
``common/rotation.py``, shared with the device models.
"""

from __future__ import annotations

from common.rotation import PX4_ROTATIONS, rotation_matrix

__all__ = ["PX4_ROTATIONS", "rotation_matrix"]
