"""Local tangent-plane projection around a reference point (azimuthal equidistant, sphere).

The same projection the estimator uses to turn GPS latitude/longitude into local x (north) and
y (east), so a position setpoint in lat/lon lands at the same local point as the estimate.
Spherical Earth of radius 6371 km, as PX4's map projection (the error against WGS-84 is well
below a GPS's noise over a flight's few kilometres).
"""

from __future__ import annotations

import math
from typing import Final

__all__ = ["EARTH_RADIUS_M", "MapProjection"]

EARTH_RADIUS_M: Final = 6371000.0


class MapProjection:
    """Projection around (ref_lat, ref_lon) in degrees: lat/lon <-> local north/east (m)."""

    def __init__(self, ref_lat_deg: float, ref_lon_deg: float) -> None:
        self.ref_lat = ref_lat_deg
        self.ref_lon = ref_lon_deg
        lat0 = math.radians(ref_lat_deg)
        self._lon0 = math.radians(ref_lon_deg)
        self._sin0 = math.sin(lat0)
        self._cos0 = math.cos(lat0)

    def project(self, lat_deg: float, lon_deg: float) -> tuple[float, float]:
        lat = math.radians(lat_deg)
        dlon = math.radians(lon_deg) - self._lon0
        s, c = math.sin(lat), math.cos(lat)
        cdl = math.cos(dlon)
        arg = self._sin0 * s + self._cos0 * c * cdl
        arg = -1.0 if arg < -1.0 else (min(arg, 1.0))
        cang = math.acos(arg)
        k = cang / math.sin(cang) if abs(cang) > 1e-12 else 1.0
        x = k * (self._cos0 * s - self._sin0 * c * cdl) * EARTH_RADIUS_M
        y = k * c * math.sin(dlon) * EARTH_RADIUS_M
        return x, y

    def reproject(self, x_m: float, y_m: float) -> tuple[float, float]:
        """Local (north, east) back to latitude/longitude in degrees."""
        xr, yr = x_m / EARTH_RADIUS_M, y_m / EARTH_RADIUS_M
        c = math.hypot(xr, yr)
        if c < 1e-15:
            return self.ref_lat, self.ref_lon
        sc, cc = math.sin(c), math.cos(c)
        lat = math.asin(cc * self._sin0 + xr * sc * self._cos0 / c)
        lon = self._lon0 + math.atan2(yr * sc, c * self._cos0 * cc - xr * self._sin0 * sc)
        return math.degrees(lat), math.degrees(lon)
