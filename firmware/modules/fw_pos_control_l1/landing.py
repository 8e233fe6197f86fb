"""Landing geometry of fw_pos_control_l1: the glide slope, the flare and the throttle limit.

The approach follows the line from the previous waypoint through the touchdown point (L1), at
``FW_AIRSPD_MIN * FW_LND_AIRSPD_SC``; an aircraft that starts its landing too close to the point
(or past it) first flies to the start of the final at its altitude (:class:`Approach`). The
glide slope rises from the touchdown point at ``FW_LND_ANG`` (aimed short of the point by what
the flare adds, :func:`slope_aim_shift_m`); until the aircraft meets it, it holds the altitude
it had when the landing began, then it follows it. Below ``FW_LND_FLALT`` above the touchdown
point the flare starts and is never left (PX4's "no return"): height demand below the ground
with an exponential approach whose time constant makes the sink rate at the flare's start
continuous and leaves ~0.3 m/s at touchdown, the pitch between ``FW_LND_FL_PMIN`` and
``FW_LND_FL_PMAX``, the throttle at ``FW_THR_MIN`` and the speed left to bleed off (speed weight
0). From ``FW_LND_TLALT`` (or the flare altitude when it is -1) the throttle is limited to
``FW_THR_LND_MAX``.
"""

from __future__ import annotations

import math
from typing import Final

__all__ = ["APP_JOIN", "APP_ON_SLOPE", "APP_REPOSITION", "FLARE_BELOW_GROUND_M", "Approach",
           "flare_time_constant", "slope_aim_shift_m", "slope_altitude"]

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


APP_REPOSITION: Final = 0
APP_JOIN: Final = 1
APP_ON_SLOPE: Final = 2


class Approach:
    """Where the aircraft is in its approach, and what to fly toward.

    A landing can start anywhere: abeam the runway, past the touchdown point, or far out on
    the line. The slope needs a straight final of ``slope_len_m`` (from the entry altitude down
    to the touchdown point) before the point; so:

    * REPOSITION: too close to (or past) the touchdown point along the approach direction:
      fly to the start of that final at the entry altitude;
    * JOIN: far enough out: fly the approach line at the entry altitude until on it (within
      ``join_xtrack_m`` and heading along it);
    * ON_SLOPE (latched): descend on the glide slope (the module's flare follows).

    ``update`` returns the phase; :attr:`line_a`/:attr:`line_b` are the L1 line to fly (A == B
    means straight to B).
    """

    def __init__(self) -> None:
        self.phase = APP_REPOSITION
        self.started = False
        self.line_a = (0.0, 0.0)
        self.line_b = (0.0, 0.0)

    def reset(self) -> None:
        self.started = False
        self.phase = APP_REPOSITION

    def update(self, pos_ne: tuple[float, float], vel_ne: tuple[float, float],
               target_ne: tuple[float, float], dir_ne: tuple[float, float],
               slope_len_m: float, capture_m: float, join_xtrack_m: float = 15.0) -> int:
        un, ue = dir_ne
        tn, te = target_ne
        final = (tn - un * slope_len_m, te - ue * slope_len_m)
        dist = (tn - pos_ne[0]) * un + (te - pos_ne[1]) * ue        # along track, > 0 before
        xtrack = (pos_ne[0] - tn) * ue - (pos_ne[1] - te) * un
        if not self.started:
            self.started = True
            self.phase = APP_JOIN if dist >= 0.9 * slope_len_m else APP_REPOSITION
        if self.phase == APP_REPOSITION:
            if math.hypot(final[0] - pos_ne[0], final[1] - pos_ne[1]) < capture_m:
                self.phase = APP_JOIN
        elif self.phase == APP_JOIN:
            vn, ve = vel_ne
            v = math.hypot(vn, ve)
            aligned = v > 1.0 and (vn * un + ve * ue) / v > 0.9
            if dist < 0.5 * slope_len_m:
                self.phase = APP_REPOSITION           # overshot the final's start: go round
            elif abs(xtrack) < join_xtrack_m and aligned:
                self.phase = APP_ON_SLOPE
        if self.phase == APP_REPOSITION:
            self.line_a = self.line_b = final
        else:
            far = max(slope_len_m, dist) + 200.0
            self.line_a = (tn - un * far, te - ue * far)
            self.line_b = target_ne
        return self.phase
