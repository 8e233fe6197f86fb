"""PX4's ``VehicleAngularVelocity``: the selected gyro, filtered, for the rate controller.

Part of the ``sensors`` work item (firmware/modules/sensors/module.py), which hands it every
calibrated sample of the selected gyro in order:

* the sample interval is measured (a running average; a change of more than 5 % retunes the
  filters, as PX4 does when a gyro's rate changes or another gyro is selected);
* the estimator's gyro bias is removed, then the IMU_GYRO_CUTOFF 2nd-order low-pass and the
  IMU_DGYRO_CUTOFF-filtered derivative (``xyz_derivative``, the D term's input in PX4) run at
  the full raw rate;
* ``vehicle_angular_velocity`` is published from the last sample of a run, at most every
  IMU_GYRO_RATEMAX interval less half a sample, and the work item is woken after the number of
  samples closest to that interval (PX4's rule, see :meth:`set_publish_rate`).
"""

from __future__ import annotations

import math
from typing import Any

from firmware.modules.sensors.filters import LowPass2p3
from firmware.platform.uorb import Publication, SubscriptionCallback

__all__ = ["VehicleAngularVelocity"]


class VehicleAngularVelocity:
    """Rate estimate of the selected gyro; ``update`` per sample, ``publish_if_due`` per run."""

    def __init__(self, pub: Publication, msg: Any, callback: SubscriptionCallback) -> None:
        self._pub = pub
        self._msg = msg
        #: the selected gyro's callback subscription (its required updates are ours to set)
        self.callback = callback
        self._lpf = LowPass2p3(1000.0, 40.0)
        self._gyro_t = -1
        self.dt_avg_us = 1000.0
        self._rate_unknown = True
        self._filter_primed = False
        self._last_pub_us = 0           # timestamp_sample of the last publication
        self.interval_us = 0            # its minimum interval (from IMU_GYRO_RATEMAX)
        self._bx = self._by = self._bz = 0.0
        self._fx = self._fy = self._fz = 0.0
        self._dx = self._dy = self._dz = 0.0
        self.cutoff_hz = 0.0
        self._dcutoff_hz = 0.0
        self.ratemax_hz = 0.0

    def set_params(self, cutoff_hz: float, dcutoff_hz: float, ratemax_hz: float) -> None:
        self.cutoff_hz = cutoff_hz
        self._dcutoff_hz = dcutoff_hz
        self.ratemax_hz = ratemax_hz
        self.set_gyro_rate(self.dt_avg_us)

    def set_gyro_rate(self, dt_us: float) -> None:
        """Filter coefficients for a gyro sample interval (start, rate change, failover)."""
        self._lpf.set_cutoff(1e6 / dt_us, self.cutoff_hz)
        self._filter_primed = False
        dt_s = dt_us * 1e-6
        k = self._dcutoff_hz
        self._d_alpha = 1.0 if k <= 0.0 else dt_s / (dt_s + 1.0 / (6.283185307179586 * k))
        self.set_publish_rate(dt_us)

    def set_publish_rate(self, dt_us: float) -> None:
        """PX4's rule for IMU_GYRO_RATEMAX: wake after the number of samples closest to the
        configured interval, publish no closer than that interval less half a sample."""
        rmax = self.ratemax_hz
        if rmax <= 0.0:
            samples, interval = 1, 0
        else:
            configured = 1e6 / rmax
            samples = math.floor(configured / dt_us + 0.5)  # roundf: halves round up
            interval = min(10_000, max(125, math.floor(configured - dt_us / 2.0 + 0.5)))
        self.interval_us = interval
        self.callback.set_required_updates(samples)

    def select(self, callback: SubscriptionCallback) -> None:
        """Another gyro was selected: its rate is measured afresh and the bias (the old
        gyro's) dropped. The caller moved the work item's callback to ``callback``."""
        self.callback = callback
        self._last_pub_us = 0
        self.set_publish_rate(self.dt_avg_us)
        self._gyro_t = -1
        self._rate_unknown = True  # measured from the new gyro's first two samples
        self._bx = self._by = self._bz = 0.0

    def set_bias(self, x: float, y: float, z: float) -> None:
        """The estimator's bias of the selected gyro, rad/s (zero: none known for it)."""
        self._bx, self._by, self._bz = x, y, z

    def update(self, x: float, y: float, z: float, t: int) -> int:
        """Filter and differentiate one calibrated sample taken at ``t`` us; returns the
        sample's interval in us (measured, or the average after a gap)."""
        dt = t - self._gyro_t
        self._gyro_t = t
        avg = self.dt_avg_us
        if 0 < dt < 20_000:
            if self._rate_unknown:
                avg = float(dt)
                self._rate_unknown = False
            avg += 0.02 * (dt - avg)
            self.dt_avg_us = avg
            if abs(self._lpf.sample_hz * avg - 1e6) > 0.05e6:  # rate changed by > 5 %
                self.set_gyro_rate(avg)
        else:
            dt = int(avg)
        x -= self._bx
        y -= self._by
        z -= self._bz
        lpf = self._lpf
        if not self._filter_primed:
            lpf.reset(x, y, z)
            self._fx, self._fy, self._fz = x, y, z
            self._filter_primed = True
        fx, fy, fz = lpf.apply(x, y, z)
        a = self._d_alpha
        inv = 1e6 / dt
        self._dx += a * ((fx - self._fx) * inv - self._dx)
        self._dy += a * ((fy - self._fy) * inv - self._dy)
        self._dz += a * ((fz - self._fz) * inv - self._dz)
        self._fx, self._fy, self._fz = fx, fy, fz
        return dt

    def publish_if_due(self, now: int, t: int) -> None:
        """Publish the state after the run's last sample (at ``t``) if the interval allows."""
        iv = self.interval_us
        last = self._last_pub_us
        if t >= last + iv:
            m = self._msg
            m.timestamp = now
            m.timestamp_sample = t
            xyz = m.xyz
            xyz[0], xyz[1], xyz[2] = self._fx, self._fy, self._fz
            d = m.xyz_derivative
            d[0], d[1], d[2] = self._dx, self._dy, self._dz
            self._pub.publish(m)
            nxt = last + iv
            # PX4: constrain(last + interval, t - interval, t), so no drift and no burst
            self._last_pub_us = min(t, max(nxt, t - iv))
