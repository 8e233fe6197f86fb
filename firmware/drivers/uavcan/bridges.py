"""Sensor bridges of the uavcan driver: CAN GNSS and compass nodes onto the topics the serial
GPS and the I2C compass use, so the sensors module and EKF2 take them as they are.

* ``uavcan.equipment.gnss.Fix2`` -> ``sensor_gps`` (PX4's ``UavcanGnssBridge``): position from
  1e-8 degrees and millimetres, velocity, fix type from the status, eph/epv from the position
  covariance (sqrt of north + east, sqrt of down), the speed accuracy from the velocity
  variances, UTC from ``gnss_timestamp`` when its time standard is UTC; HDOP/VDOP and the
  visible satellites from ``Auxiliary``. One ``sensor_gps`` instance per node, taken at its
  first Fix2 with a fix (2D or 3D; before that nothing is published): the first free one from
  ``first_instance()`` up. The driver passes 1 when the serial ``gps`` driver has found a
  receiver (it claims its fixed instance 0 at its first fix, and a receiver is configured
  within about a second while a GNSS's first fix takes longer), else 0: with no serial GPS
  the CAN one is instance 0, the one EKF2 reads.
* ``uavcan.equipment.ahrs.MagneticFieldStrength2`` -> ``sensor_mag`` (gauss, the node's frame),
  marked external, one instance per (node, sensor_id).

Device IDs are PX4's for CAN devices: bus type UAVCAN, bus 0 (CAN1), address the node ID,
device type ``DRV_GPS_DEVTYPE_UAVCAN`` (0x85) / ``DRV_MAG_DEVTYPE_UAVCAN`` (0x88).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Final

from firmware.drivers.device import BUS_TYPE_UAVCAN, DeviceId
from firmware.platform import Platform
from firmware.platform.uorb import ORB_MULTI_MAX_INSTANCES

__all__ = ["GnssBridge", "MagBridge", "DRV_GPS_DEVTYPE_UAVCAN", "DRV_MAG_DEVTYPE_UAVCAN"]

DRV_GPS_DEVTYPE_UAVCAN: Final = 0x85
DRV_MAG_DEVTYPE_UAVCAN: Final = 0x88
GNSS_TIME_STANDARD_UTC: Final = 2


class GnssBridge:
    """Fix2 and Auxiliary of every GNSS node -> one ``sensor_gps`` instance per node."""

    def __init__(self, platform: Platform, first_instance: Callable[[], int]) -> None:
        self.platform = platform
        self._first_instance = first_instance
        self._pubs: dict[int, Any] = {}
        self._msgs: dict[int, Any] = {}
        self.fixes = 0
        self.dropped = 0

    def _advertise(self, node_id: int) -> Any:
        """A free ``sensor_gps`` instance from the first the serial GPS leaves, else None: the
        node's fixes are dropped, said once (PX4's bridges run out of channels the same way)."""
        orb = self.platform.orb
        for i in range(self._first_instance(), ORB_MULTI_MAX_INSTANCES):
            if not orb.exists("sensor_gps", i):
                return orb.advertise("sensor_gps", i)
        self.platform.warn("uavcan", f"GNSS node {node_id}: no sensor_gps instance left, "
                                     "its fixes are dropped")
        return None

    def on_fix2(self, node_id: int, f: Any, now_us: int) -> None:
        orb = self.platform.orb
        if node_id not in self._pubs and int(f.status) < 2:
            return  # no instance claimed before the node's first fix (see the module doc)
        msg = self._msgs.get(node_id)
        if msg is None:
            msg = self._msgs[node_id] = orb.new("sensor_gps")
            msg.hdop = msg.vdop = 99.99
            msg.heading = msg.heading_offset = math.nan
        msg.timestamp = now_us
        msg.timestamp_sample = now_us
        msg.device_id = DeviceId(BUS_TYPE_UAVCAN, 0, node_id, DRV_GPS_DEVTYPE_UAVCAN).value
        lat = int(f.latitude_deg_1e8)
        lon = int(f.longitude_deg_1e8)
        msg.latitude_deg = lat * 1e-8
        msg.longitude_deg = lon * 1e-8
        msg.lat = lat // 10
        msg.lon = lon // 10
        msg.alt = int(f.height_msl_mm)
        msg.alt_ellipsoid = int(f.height_ellipsoid_mm)
        msg.altitude_msl_m = msg.alt * 1e-3
        msg.altitude_ellipsoid_m = msg.alt_ellipsoid * 1e-3
        status = int(f.status)
        msg.fix_type = status if status >= 2 else 0
        msg.satellites_used = int(f.sats_used)
        cov = [float(c) for c in f.covariance]
        if len(cov) >= 6:
            msg.eph = math.sqrt(max(0.0, cov[0] + cov[1]))
            msg.epv = math.sqrt(max(0.0, cov[2]))
            msg.s_variance_m_s = math.sqrt(max(0.0, (cov[3] + cov[4] + cov[5]) / 3.0))
        else:
            msg.eph = msg.epv = 10.0 if msg.fix_type >= 2 else 1000.0
            msg.s_variance_m_s = 1.0
        vn, ve, vd = (float(v) for v in f.ned_velocity)
        msg.vel_n_m_s, msg.vel_e_m_s, msg.vel_d_m_s = vn, ve, vd
        msg.vel_m_s = math.hypot(vn, ve)
        msg.cog_rad = math.atan2(ve, vn)
        msg.c_variance_rad = math.radians(180.0) if msg.vel_m_s < 0.5 else \
            min(math.pi, msg.s_variance_m_s / msg.vel_m_s)
        msg.vel_ned_valid = msg.fix_type >= 2
        utc_us = int(f.gnss_timestamp.usec)
        std = int(f.gnss_time_standard)
        msg.time_utc_usec = utc_us if std == GNSS_TIME_STANDARD_UTC and utc_us else 0
        msg.timestamp_time_relative = 0
        if node_id not in self._pubs:
            self._pubs[node_id] = self._advertise(node_id)
        pub = self._pubs[node_id]
        if pub is None:
            self.dropped += 1
            return
        pub.publish(msg)
        self.fixes += 1

    def on_auxiliary(self, node_id: int, a: Any) -> None:
        msg = self._msgs.get(node_id)
        if msg is not None:  # goes out with the next fix, as PX4's bridge does
            msg.hdop = float(a.hdop)
            msg.vdop = float(a.vdop)


class MagBridge:
    """MagneticFieldStrength2 -> ``sensor_mag`` (one instance per node and sensor ID)."""

    def __init__(self, platform: Platform) -> None:
        self.platform = platform
        self._pubs: dict[tuple[int, int], Any] = {}
        self._msg = platform.orb.new("sensor_mag")
        self.samples = 0
        self.dropped = 0

    def on_mag2(self, node_id: int, m: Any, now_us: int) -> None:
        key = (node_id, int(m.sensor_id))
        field = [float(v) for v in m.magnetic_field_ga]
        if len(field) != 3 or not all(math.isfinite(v) for v in field):
            return
        msg = self._msg
        msg.timestamp = now_us
        msg.timestamp_sample = now_us
        msg.device_id = DeviceId(BUS_TYPE_UAVCAN, 0, node_id, DRV_MAG_DEVTYPE_UAVCAN).value
        msg.x, msg.y, msg.z = field
        msg.temperature = math.nan
        msg.error_count = 0
        msg.is_external = True
        if key not in self._pubs:
            try:
                self._pubs[key] = self.platform.orb.advertise_multi("sensor_mag")
            except RuntimeError:  # all instances in use: PX4's bridge is out of channels
                self._pubs[key] = None
                self.platform.warn("uavcan", f"compass node {node_id} sensor {key[1]}: no "
                                             "sensor_mag instance left, its fields are dropped")
        pub = self._pubs[key]
        if pub is None:
            self.dropped += 1
            return
        pub.publish(msg)
        self.samples += 1
