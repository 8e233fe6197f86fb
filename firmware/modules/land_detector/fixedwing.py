"""Fixed-wing land detection (``land_detector start fixedwing``), PX4's crude but robust rule.

A plane on the ground is slow and still; in the air it never is (it stalls below its minimum
airspeed). So it is landed while, filtered, its airspeed is below ``LNDFW_AIRSPD_MAX``, its
groundspeed below ``LNDFW_VEL_XY_MAX`` (0.7 of it when there is no valid airspeed, to make up
for the missing check), its vertical speed below ``LNDFW_VEL_Z_MAX`` and its horizontal
specific force below ``LNDFW_XYACC_MAX`` (a hand launch or a catapult shows as a jolt before
any speed builds up). Landed needs ``LNDFW_TRIG_TIME`` of that; takeoff is seen at once. Without
a local position for a second it reports landed, as PX4 does.

The filters are PX4's first-order ones at the detector's 50 Hz: they smooth GPS and airspeed
noise, and the horizontal acceleration one leaks so that a sensor bias cannot build up.
There is no ground contact or maybe-landed stage on a plane: both follow ``landed``.
"""

from __future__ import annotations

import math
from typing import Any, Final

from firmware.platform.params import ParamDef

__all__ = ["FW_PARAMS", "FixedwingDetector"]

_G: Final = "Land Detector"
#: a topic older than this counts as lost (PX4: 1 s)
STALE_US: Final = 1_000_000


def _p(name: str, default: float, lo: float, hi: float, short: str, unit: str,
       decimals: int = 1) -> ParamDef:
    return ParamDef(name, "FLOAT", default, min=lo, max=hi, unit=unit, group=_G, short=short,
                    decimals=decimals)


FW_PARAMS: Final[tuple[ParamDef, ...]] = (
    _p("LNDFW_VEL_XY_MAX", 5.0, 0.5, 10.0, "Fixed-wing max horizontal velocity", "m/s"),
    _p("LNDFW_VEL_Z_MAX", 3.0, 0.1, 20.0, "Fixed-wing max climb rate", "m/s"),
    _p("LNDFW_XYACC_MAX", 8.0, 2.0, 15.0, "Fixed-wing max horizontal acceleration", "m/s^2"),
    _p("LNDFW_AIRSPD_MAX", 6.0, 2.0, 20.0, "Fixed-wing max airspeed", "m/s"),
    _p("LNDFW_TRIG_TIME", 2.0, 0.1, 10.0, "Fixed-wing land detection trigger time", "s"),
)


class FixedwingDetector:
    """The filtered quantities and the landed condition; the module owns the hysteresis."""

    __slots__ = ("accel_max", "airspeed_filt", "airspeed_max", "airspeed_valid", "vel_xy_filt",
                 "vel_xy_max", "vel_z_filt", "vel_z_max", "xy_accel_filt")

    def __init__(self) -> None:
        self.vel_xy_filt = 0.0
        self.vel_z_filt = 0.0
        self.airspeed_filt = 0.0
        self.xy_accel_filt = 0.0
        self.airspeed_valid = False
        self.vel_xy_max = 5.0
        self.vel_z_max = 3.0
        self.accel_max = 8.0
        self.airspeed_max = 6.0

    def load(self, p: Any) -> None:
        """Thresholds from the parameters (``p(name)`` reads one)."""
        self.vel_xy_max = float(p("LNDFW_VEL_XY_MAX"))
        self.vel_z_max = float(p("LNDFW_VEL_Z_MAX"))
        self.accel_max = float(p("LNDFW_XYACC_MAX"))
        self.airspeed_max = float(p("LNDFW_AIRSPD_MAX"))

    def reset(self) -> None:
        """Disarmed: the filters start again from rest."""
        self.vel_xy_filt = self.vel_z_filt = self.airspeed_filt = self.xy_accel_filt = 0.0

    def landed(self, lp: Any, lp_age_us: int, airspeed: Any, airspeed_age_us: int,
               accel: Any) -> bool:
        """One 50 Hz step: update the filters, return whether the plane looks landed."""
        if lp is None or lp_age_us > STALE_US:
            return True
        tas = float(airspeed.true_airspeed_m_s) if airspeed is not None else math.nan
        self.airspeed_valid = math.isfinite(tas) and airspeed_age_us <= STALE_US
        if self.airspeed_valid:
            self.airspeed_filt = 0.95 * self.airspeed_filt + 0.05 * tas
        else:
            self.airspeed_filt = 0.0
        v_xy = math.hypot(lp.vx, lp.vy)
        if math.isfinite(v_xy):
            self.vel_xy_filt = 0.97 * self.vel_xy_filt + 0.03 * v_xy
        if math.isfinite(lp.vz):
            self.vel_z_filt = 0.99 * self.vel_z_filt + 0.01 * abs(float(lp.vz))
        if accel is not None:
            a_xy = math.hypot(accel.xyz[0], accel.xyz[1])
            if math.isfinite(a_xy):
                self.xy_accel_filt = self.xy_accel_filt * 0.8 + a_xy * 0.18
        vel_xy_max = self.vel_xy_max if self.airspeed_valid else 0.7 * self.vel_xy_max
        return (self.airspeed_filt < self.airspeed_max and self.vel_xy_filt < vel_xy_max
                and self.vel_z_filt < self.vel_z_max and self.xy_accel_filt < self.accel_max)

    def status_line(self) -> str:
        return (f"fixedwing: groundspeed {self.vel_xy_filt:.1f} m/s, climb {self.vel_z_filt:.1f}"
                f" m/s, airspeed {self.airspeed_filt:.1f} m/s"
                f"{'' if self.airspeed_valid else ' (invalid)'}, horizontal accel "
                f"{self.xy_accel_filt:.1f} m/s^2")
