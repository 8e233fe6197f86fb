"""PX4's ``VehicleIMU`` as this FMU uses it: gyro and accelerometer integrated into
``sensor_combined``.

Part of the ``sensors`` work item. The selected gyro's samples are integrated (rectangular: a
sample is the mean rate over its interval, the interval measured by
:class:`~firmware.modules.sensors.vehicle_angular_velocity.VehicleAngularVelocity`); the
selected accelerometer's likewise, by its own sample times. Every 1/IMU_INTEG_RATE (4 ms) the
work item closes an interval at the gyro sample that completes it, feeds the accelerometer
samples up to that time and calls :meth:`publish`: the averages of the interval go out as
``sensor_combined`` (the 2014 stack's estimator input; PX4 later split it into vehicle_imu),
whatever rate the work item wakes at.
"""

from __future__ import annotations

from typing import Any

from firmware.platform.uorb import Publication
from common.units import G0_M_S2

__all__ = ["VehicleIMU"]


class VehicleIMU:
    """Integrators of the selected gyro and accelerometer between two ``sensor_combined``."""

    def __init__(self, pub: Publication, msg: Any) -> None:
        self._pub = pub
        self._msg = msg
        self.integ_us = 4000
        self._gix = self._giy = self._giz = 0.0
        self.gyro_dt_us = 0
        self.gyro_t = 0
        self._accel_seen = False
        self._accel_t = -1
        self._aix = self._aiy = self._aiz = 0.0
        self._ai_dt = 0
        self._ai_t = 0
        self._ai_clip = 0
        #: the last interval's mean specific force, m/s^2 (held while no accel sample comes)
        self.ax = self.ay = 0.0
        self.az = -G0_M_S2

    def integrate_gyro(self, x: float, y: float, z: float, dt: int, t: int) -> None:
        self._gix += x * dt
        self._giy += y * dt
        self._giz += z * dt
        self.gyro_dt_us += dt
        self.gyro_t = t

    def due(self, gyro_dt_avg_us: float) -> bool:
        """The interval is complete (within half a gyro sample)."""
        return self.gyro_dt_us >= self.integ_us - (gyro_dt_avg_us * 0.5)

    def accel_selected(self) -> None:
        """Another accelerometer was selected: its interval is measured afresh."""
        self._accel_t = -1

    def integrate_accel(self, x: float, y: float, z: float, msg: Any) -> None:
        """One calibrated sample of the selected accelerometer (``msg`` for time and clipping)."""
        t = msg.timestamp_sample
        dt = t - self._accel_t
        self._accel_t = t
        if not 0 < dt < 20_000:
            dt = 1000 * max(1, msg.samples) if self._ai_dt == 0 else 0
            if dt == 0:
                return
        self._aix += x * dt
        self._aiy += y * dt
        self._aiz += z * dt
        self._ai_dt += dt
        self._ai_t = t
        c = msg.clip_counter
        if c[0] or c[1] or c[2]:
            self._ai_clip |= (1 if c[0] else 0) | (2 if c[1] else 0) | (4 if c[2] else 0)

    def publish(self, gyro_device_id: int, accel_device_id: int) -> bool:
        """Close the interval into ``sensor_combined``; False (nothing published) before the
        first accelerometer sample: a made-up specific force would mislead the estimator's
        alignment. The caller then calls :meth:`reset`."""
        gdt = self.gyro_dt_us
        inv = 1.0 / gdt
        m = self._msg
        g = m.gyro_rad
        g[0], g[1], g[2] = self._gix * inv, self._giy * inv, self._giz * inv
        m.gyro_integral_dt = gdt
        adt = self._ai_dt
        if not adt and not self._accel_seen:
            return False
        if adt:
            self._accel_seen = True
            ainv = 1.0 / adt
            self.ax, self.ay, self.az = self._aix * ainv, self._aiy * ainv, self._aiz * ainv
            m.accelerometer_timestamp_relative = self._ai_t - self.gyro_t
        else:  # no new accel sample in this interval: hold the last one
            m.accelerometer_timestamp_relative = m.RELATIVE_TIMESTAMP_INVALID
        m.timestamp = self.gyro_t
        a = m.accelerometer_m_s2
        a[0], a[1], a[2] = self.ax, self.ay, self.az
        m.accelerometer_integral_dt = adt if adt else gdt
        m.accelerometer_clipping = self._ai_clip
        m.gyro_device_id = gyro_device_id
        m.accel_device_id = accel_device_id
        self._pub.publish(m)
        return True

    def reset(self) -> None:
        """Start the next interval."""
        self._gix = self._giy = self._giz = 0.0
        self.gyro_dt_us = 0
        self._aix = self._aiy = self._aiz = 0.0
        self._ai_dt = 0
        self._ai_clip = 0
