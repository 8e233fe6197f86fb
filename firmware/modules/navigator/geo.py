"""Small-distance geodesy for waypoints: distances, bearings and offsets on a spherical Earth.

The navigator compares positions tens to thousands of metres apart; a sphere of PX4's radius
(CONSTANTS_RADIUS_OF_EARTH) is accurate to well under a metre there, and the same formulas on
both sides (navigator and tests) keep "reached" decisions consistent.
"""

from __future__ import annotations

import math
from typing import Final

__all__ = ["EARTH_RADIUS_M", "bearing_rad", "distance_m", "offset_deg"]

EARTH_RADIUS_M: Final = 6371000.0
_D2R: Final = math.pi / 180.0


def distance_m(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Great-circle distance between two points in degrees (haversine)."""
    p1, p2 = lat1 * _D2R, lat2 * _D2R
    dlat, dlon = p2 - p1, (lon2 - lon1) * _D2R
    a = math.sin(dlat / 2) ** 2 + math.cos(p1) * math.cos(p2) * math.sin(dlon / 2) ** 2
    return 2.0 * EARTH_RADIUS_M * math.atan2(math.sqrt(a), math.sqrt(max(0.0, 1.0 - a)))


def bearing_rad(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Initial bearing from point 1 to point 2, -pi..pi, 0 = north, clockwise positive."""
    p1, p2 = lat1 * _D2R, lat2 * _D2R
    dlon = (lon2 - lon1) * _D2R
    y = math.sin(dlon) * math.cos(p2)
    x = math.cos(p1) * math.sin(p2) - math.sin(p1) * math.cos(p2) * math.cos(dlon)
    return math.atan2(y, x)


def offset_deg(lat: float, lon: float, north_m: float, east_m: float) -> tuple[float, float]:
    """The point ``north_m`` north and ``east_m`` east of (lat, lon) (flat-Earth, small)."""
    dlat = north_m / EARTH_RADIUS_M / _D2R
    dlon = east_m / (EARTH_RADIUS_M * math.cos(lat * _D2R)) / _D2R
    return lat + dlat, lon + dlon
