"""PX4's ``VehicleAcceleration``: the selected accelerometer, low-passed, for the controllers.

Part of the ``sensors`` work item. PX4 filters the raw samples; here the input is each
``sensor_combined`` interval's mean specific force (:class:`VehicleIMU`, 250 Hz whatever the
accelerometer's rate), through a first-order IMU_ACCEL_CUTOFF low-pass, published as
``vehicle_acceleration`` at the same rate.
"""

from __future__ import annotations

from typing import Any

from firmware.platform.uorb import Publication
from common.units import G0_M_S2

__all__ = ["VehicleAcceleration"]


class VehicleAcceleration:
    """First-order low-pass of the mean specific force, m/s^2 in body axes."""

    def __init__(self, pub: Publication, msg: Any) -> None:
        self._pub = pub
        self._msg = msg
        self.cutoff_hz = 0.0
        self._x = self._y = 0.0
        self._z = -G0_M_S2

    def update(self, ax: float, ay: float, az: float, dt_us: int, t_sample: int,
               now: int) -> None:
        """Filter one interval's mean (``dt_us`` long, closing at ``t_sample``) and publish."""
        k = self.cutoff_hz
        dt_s = dt_us * 1e-6
        alpha = 1.0 if k <= 0.0 else dt_s / (dt_s + 1.0 / (6.283185307179586 * k))
        self._x += alpha * (ax - self._x)
        self._y += alpha * (ay - self._y)
        self._z += alpha * (az - self._z)
        m = self._msg
        m.timestamp = now
        m.timestamp_sample = t_sample
        xyz = m.xyz
        xyz[0], xyz[1], xyz[2] = self._x, self._y, self._z
        self._pub.publish(m)
