"""PX4's ``VehicleMagnetometer``: the selected magnetometer averaged into
``vehicle_magnetometer``.

Part of the ``sensors`` work item, which feeds it the selected magnetometer's calibrated samples;
every 1/SENS_MAG_RATE their mean (gauss, body axes) goes out.
"""

from __future__ import annotations

from typing import Any

from firmware.modules.sensors.voter import SensorInstance
from firmware.platform.uorb import Publication

__all__ = ["VehicleMagnetometer"]


class VehicleMagnetometer:
    """Mean of the selected magnetometer over one SENS_MAG_RATE interval."""

    def __init__(self, pub: Publication, msg: Any, now: int) -> None:
        self._pub = pub
        self._msg = msg
        self.interval_us = 20_000
        self._x = self._y = self._z = 0.0
        self._ts = self._n = 0
        self._next_us = now

    def add(self, x: float, y: float, z: float, t_sample: int) -> None:
        """One calibrated sample (gauss) of the selected magnetometer."""
        self._x += x
        self._y += y
        self._z += z
        self._ts += t_sample
        self._n += 1

    def publish_if_due(self, now: int, mag: SensorInstance) -> None:
        """Publish the interval's mean if it has samples and is over (``mag``: selected)."""
        n = self._n
        if not n or now < self._next_us:
            return
        m = self._msg
        m.timestamp = now
        m.timestamp_sample = self._ts // n
        m.device_id = mag.device_id
        v = m.magnetometer_ga
        v[0], v[1], v[2] = self._x / n, self._y / n, self._z / n
        m.calibration_count = mag.cal.slot + 1
        self._pub.publish(m)
        self.reset()
        self._next_us = max(self._next_us + self.interval_us, now - self.interval_us)

    def reset(self) -> None:
        """Drop the samples so far (after a publication, or another magnetometer selected)."""
        self._x = self._y = self._z = 0.0
        self._ts = self._n = 0
