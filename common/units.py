"""Physical constants and unit factors, SI unless the name says otherwise."""

from __future__ import annotations

from typing import Final

__all__ = ["G0_M_S2", "M_PER_DEG_LAT"]

#: standard gravity (CGPM 1901), PX4's CONSTANTS_ONE_G
G0_M_S2: Final = 9.80665
#: metres per degree of latitude at mid latitudes (the flat-earth projection of missions and
#: accuracy checks around home; PX4's map projection is exact, these checks need metres only)
M_PER_DEG_LAT: Final = 111_132.954
