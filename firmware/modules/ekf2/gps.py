"""GPS quality gate before use, and the local projection around the origin.

PX4 does not trust a receiver the moment it reports a 3D fix: the solution must meet the
EKF2_REQ_* thresholds continuously for EKF2_REQ_GPS_H seconds first (a fresh fix wanders by
metres while the receiver settles). :class:`GpsChecks` keeps that state and PX4's
``gps_check_fail_flags`` bits for estimator_status.

:class:`LocalProjection` maps WGS-84 latitude/longitude to north/east metres around the origin
(an azimuthal equidistant projection on a sphere of the WGS-84 mean radius, the projection PX4
uses for its local frame) and back.
"""

from __future__ import annotations

import math
from typing import Any, Final

__all__ = ["EARTH_RADIUS_M", "GPS_CHECK_FAIL_BITS", "GpsChecks", "LocalProjection"]

EARTH_RADIUS_M: Final = 6371000.0

#: estimator_status.gps_check_fail_flags bits (PX4 numbering)
GPS_FAIL_FIX: Final = 0
GPS_FAIL_NSATS: Final = 1
GPS_FAIL_PDOP: Final = 2
GPS_FAIL_HACC: Final = 3
GPS_FAIL_VACC: Final = 4
GPS_FAIL_SACC: Final = 5
GPS_CHECK_FAIL_BITS: Final = {GPS_FAIL_FIX: "fix", GPS_FAIL_NSATS: "nsats", GPS_FAIL_PDOP: "pdop",
                       GPS_FAIL_HACC: "hacc", GPS_FAIL_VACC: "vacc", GPS_FAIL_SACC: "sacc"}
#: EKF2_GPS_CHECK mask bits (PX4 numbering): which of the checks are enforced
MASK_NSATS: Final = 1
MASK_PDOP: Final = 2
MASK_HACC: Final = 4
MASK_VACC: Final = 8
MASK_SACC: Final = 16


class GpsChecks:
    """Quality of the receiver's solutions over time."""

    def __init__(self) -> None:
        self.fail_flags = 0
        self.pass_since_us = -1
        self.last_fail_us = -1

    def update(self, gps: Any, now_us: int, mask: int, req_eph: float, req_epv: float,
               req_sacc: float, req_nsats: int, req_pdop: float) -> int:
        """Check one solution; returns the fail flags (0 = good)."""
        f = 0
        if gps.fix_type < 3:
            f |= 1 << GPS_FAIL_FIX
        if mask & MASK_NSATS and gps.satellites_used < req_nsats:
            f |= 1 << GPS_FAIL_NSATS
        if mask & MASK_PDOP and gps.hdop > req_pdop:
            f |= 1 << GPS_FAIL_PDOP
        if mask & MASK_HACC and gps.eph > req_eph:
            f |= 1 << GPS_FAIL_HACC
        if mask & MASK_VACC and gps.epv > req_epv:
            f |= 1 << GPS_FAIL_VACC
        if mask & MASK_SACC and (not gps.vel_ned_valid or gps.s_variance_m_s > req_sacc):
            f |= 1 << GPS_FAIL_SACC
        self.fail_flags = f
        if f:
            self.pass_since_us = -1
            self.last_fail_us = now_us
        elif self.pass_since_us < 0:
            self.pass_since_us = now_us
        return f

    def passed_for_us(self, now_us: int) -> int:
        return now_us - self.pass_since_us if self.pass_since_us >= 0 else -1


class LocalProjection:
    """North/east metres around a reference latitude/longitude (degrees)."""

    __slots__ = ("_clat0", "_slat0", "lat0", "lon0", "valid")

    def __init__(self) -> None:
        self.lat0 = self.lon0 = 0.0
        self._slat0 = 0.0
        self._clat0 = 1.0
        self.valid = False

    def init(self, lat_deg: float, lon_deg: float) -> None:
        self.lat0, self.lon0 = lat_deg, lon_deg
        r = math.radians(lat_deg)
        self._slat0, self._clat0 = math.sin(r), math.cos(r)
        self.valid = True

    def project(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        lat = math.radians(lat_deg)
        dlon = math.radians(lon_deg - self.lon0)
        sl, cl = math.sin(lat), math.cos(lat)
        cdl = math.cos(dlon)
        c = self._slat0 * sl + self._clat0 * cl * cdl
        c = max(-1.0, min(1.0, c))
        arg = math.acos(c)
        k = arg / math.sin(arg) if arg > 1e-12 else 1.0
        x = k * (self._clat0 * sl - self._slat0 * cl * cdl) * EARTH_RADIUS_M
        y = k * cl * math.sin(dlon) * EARTH_RADIUS_M
        return x, y

    def reproject(self, x: float, y: float) -> tuple[float, float]:
        xr, yr = x / EARTH_RADIUS_M, y / EARTH_RADIUS_M
        c = math.sqrt(xr * xr + yr * yr)
        if c < 1e-15:
            return self.lat0, self.lon0
        sc, cc = math.sin(c), math.cos(c)
        lat = math.asin(cc * self._slat0 + xr * sc * self._clat0 / c)
        lon = math.radians(self.lon0) + math.atan2(
            yr * sc, c * self._clat0 * cc - xr * self._slat0 * sc)
        return math.degrees(lat), math.degrees(lon)
