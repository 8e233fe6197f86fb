"""Earth magnetic field at a location, in NED, in gauss.

Two sources, in this order:

1. A small table of sites with declination, inclination and total intensity taken from the
   World Magnetic Model (epoch ~2020) and rounded. A location within ``TABLE_RADIUS_DEG`` of a
   site uses that site's field. PX4's default home (Zurich, 47.397742 N, 8.545594 E) is there:
   declination +2.6 deg (east), inclination 63.4 deg (down), 0.482 gauss, i.e.
   (N, E, D) = (0.2156, 0.0098, 0.4310) gauss.
2. Elsewhere, the centred tilted dipole of IGRF-13 (2020, degree 1 only). It is crude: it gets
   the intensity within ~20 % and the inclination within a few degrees at mid latitudes, but
   declination can be off by 10-20 deg (-14 deg instead of +2.6 deg at Zurich). Pass an explicit
   field to World (``mag_field_ned_gauss``) when a scenario needs a particular place.

The field is evaluated once per world (flights span kilometres, across which the real field
changes by well under a degree).
"""

from __future__ import annotations

import math

__all__ = ["field_from_angles", "dipole_field_ned_gauss", "earth_field_ned_gauss", "SITES"]

# name: (lat_deg, lon_deg, declination_deg, inclination_deg, intensity_gauss)
SITES: dict[str, tuple[float, float, float, float, float]] = {
    "px4_home_zurich": (47.397742, 8.545594, 2.6, 63.4, 0.482),
}
TABLE_RADIUS_DEG = 1.5

# IGRF-13 degree-1 Gauss coefficients for 2020.0 (nT) and the reference radius (m).
_G10_NT = -29404.8
_G11_NT = -1450.9
_H11_NT = 4652.5
_A_M = 6371200.0


def field_from_angles(
    declination_deg: float, inclination_deg: float, intensity_gauss: float
) -> tuple[float, float, float]:
    """NED field vector (gauss) from declination (east +), inclination (down +) and intensity."""
    d = math.radians(declination_deg)
    i = math.radians(inclination_deg)
    h = intensity_gauss * math.cos(i)
    return (h * math.cos(d), h * math.sin(d), intensity_gauss * math.sin(i))


def dipole_field_ned_gauss(
    lat_deg: float, lon_deg: float, alt_m: float = 0.0
) -> tuple[float, float, float]:
    """Field of the IGRF-2020 centred tilted dipole (spherical Earth), NED gauss."""
    theta = math.radians(90.0 - lat_deg)  # colatitude
    phi = math.radians(lon_deg)
    k = (_A_M / (_A_M + alt_m)) ** 3
    ct, st = math.cos(theta), math.sin(theta)
    g = _G11_NT * math.cos(phi) + _H11_NT * math.sin(phi)
    b_r = 2.0 * k * (_G10_NT * ct + g * st)
    b_theta = -k * (-_G10_NT * st + g * ct)
    b_phi = -k * (-_G11_NT * math.sin(phi) + _H11_NT * math.cos(phi))
    nt_to_gauss = 1e-5
    return (-b_theta * nt_to_gauss, b_phi * nt_to_gauss, -b_r * nt_to_gauss)


def earth_field_ned_gauss(
    lat_deg: float, lon_deg: float, alt_m: float = 0.0
) -> tuple[float, float, float]:
    """Field at a location: the nearest table site if close enough, else the dipole."""
    for lat0, lon0, dec, inc, f in SITES.values():
        if abs(lat_deg - lat0) <= TABLE_RADIUS_DEG and abs(lon_deg - lon0) <= TABLE_RADIUS_DEG:
            return field_from_angles(dec, inc, f)
    return dipole_field_ned_gauss(lat_deg, lon_deg, alt_m)
