"""International Standard Atmosphere (ISA, ICAO Doc 7488), troposphere and lower stratosphere.

The world reads pressure and temperature from JSBSim's standard atmosphere (so the baro and the
aerodynamics see one air); these functions are the reference for tests and for places that need
the atmosphere without an FDM. Altitudes are geometric metres above mean sea level; the formula
uses geopotential altitude (the difference is 0.04 m at 500 m).
"""

from __future__ import annotations

import math
from common.units import G0_M_S2

R_AIR_J_KG_K = 287.05287  # specific gas constant of dry air
P0_PA = 101325.0  # sea-level pressure
T0_K = 288.15  # sea-level temperature
LAPSE_K_M = -0.0065  # troposphere lapse rate (0 .. 11 km geopotential)
EARTH_RADIUS_M = 6356766.0  # radius used for the geopotential altitude (US 1976 / ISA)
H_TROPOPAUSE_M = 11000.0
T_TROPOPAUSE_K = T0_K + LAPSE_K_M * H_TROPOPAUSE_M  # 216.65 K
P_TROPOPAUSE_PA = P0_PA * (T_TROPOPAUSE_K / T0_K) ** (-G0_M_S2 / (LAPSE_K_M * R_AIR_J_KG_K))
KELVIN_0C = 273.15

__all__ = [
    "geopotential_m",
    "isa_temperature_k",
    "isa_pressure_pa",
    "isa_density_kg_m3",
    "KELVIN_0C",
]


def geopotential_m(alt_m: float) -> float:
    """Geopotential altitude for a geometric altitude (m)."""
    return EARTH_RADIUS_M * alt_m / (EARTH_RADIUS_M + alt_m)


def isa_temperature_k(alt_m: float) -> float:
    """ISA static temperature (K) at geometric altitude alt_m (valid up to 20 km)."""
    h = geopotential_m(alt_m)
    if h <= H_TROPOPAUSE_M:
        return T0_K + LAPSE_K_M * h
    return T_TROPOPAUSE_K


def isa_pressure_pa(alt_m: float) -> float:
    """ISA static pressure (Pa) at geometric altitude alt_m (valid up to 20 km)."""
    h = geopotential_m(alt_m)
    if h <= H_TROPOPAUSE_M:
        t = T0_K + LAPSE_K_M * h
        return P0_PA * (t / T0_K) ** (-G0_M_S2 / (LAPSE_K_M * R_AIR_J_KG_K))
    return P_TROPOPAUSE_PA * math.exp(
        -G0_M_S2 * (h - H_TROPOPAUSE_M) / (R_AIR_J_KG_K * T_TROPOPAUSE_K)
    )


def isa_density_kg_m3(alt_m: float) -> float:
    """ISA air density (kg/m^3) at geometric altitude alt_m."""
    return isa_pressure_pa(alt_m) / (R_AIR_J_KG_K * isa_temperature_k(alt_m))
