"""Landing geometry of fw_pos_control_l1: the glide slope, the flare and the throttle limit.

The approach follows the line from the previous waypoint through the touchdown point (L1), at
``FW_AIRSPD_MIN * FW_LND_AIRSPD_SC``. The glide slope rises from the touchdown point at
``FW_LND_ANG`` (aimed short of the point by what the flare adds, :func:`slope_aim_shift_m`);
until the aircraft meets it, it holds the altitude it had when the landing
began, then it follows it. Below ``FW_LND_FLALT`` above the touchdown point the flare starts and
is never left (PX4's "no return"): height demand below the ground with an exponential approach
whose time constant makes the sink rate at the flare's start continuous and leaves ~0.3 m/s at
touchdown, the pitch between ``FW_LND_FL_PMIN`` and ``FW_LND_FL_PMAX``, the throttle at
``FW_THR_MIN`` and the speed left to bleed off (speed weight 0). From ``FW_LND_TLALT`` (or the
flare altitude when it is -1) the throttle is limited to ``FW_THR_LND_MAX``.
"""

from __future__ import annotations

import math
from typing import Final

__all__ = ["FLARE_BELOW_GROUND_M", "flare_time_constant", "slope_aim_shift_m", "slope_altitude"]

#: the flare aims this far below the touchdown point so that it reaches the ground
FLARE_BELOW_GROUND_M: Final = 1.0


def slope_altitude(land_alt_m: float, dist_to_touchdown_m: float, slope_rad: float,
                   entry_alt_m: float) -> float:
    """The approach altitude: on the glide slope, never above the altitude at the start."""
    on_slope = land_alt_m + max(dist_to_touchdown_m, 0.0) * math.tan(slope_rad)
    return min(on_slope, max(entry_alt_m, land_alt_m))


def flare_time_constant(flare_alt_m: float, sink_m_s: float) -> float:
    """The flare's exponential time constant: at its start the demanded sink rate equals the
    approach's (height above the aim point over the time constant)."""
    return (flare_alt_m + FLARE_BELOW_GROUND_M) / max(sink_m_s, 0.3)


def slope_aim_shift_m(flare_alt_m: float, slope_rad: float, airspeed_m_s: float) -> float:
    """How far before the touchdown point the glide slope must aim so that the wheels touch
    at it (PX4 does this with its virtual flare height, FW_LND_HVIRT): the exponential flare
    covers ``V tc ln((h_f + b) / b)`` where the straight slope would cover ``h_f / tan``."""
    t = math.tan(slope_rad)
    if t <= 0.0 or flare_alt_m <= 0.0:
        return 0.0
    sink = airspeed_m_s * t
    tc = flare_time_constant(flare_alt_m, sink)
    flare_len = airspeed_m_s * tc * math.log((flare_alt_m + FLARE_BELOW_GROUND_M)
                                             / FLARE_BELOW_GROUND_M)
    return max(flare_len - flare_alt_m / t, 0.0)
