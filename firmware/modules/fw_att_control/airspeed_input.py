"""The airspeed both fixed-wing modules fly on: the ``airspeed`` topic while it is fresh and
plausible, else none (the controllers then assume ``FW_AIRSPD_TRIM``, as PX4 does).

A stuck or blocked pitot is the airspeed module's to detect (its ``confidence``); here only
what every consumer must check: the topic exists in this build, is recent (1 s, PX4's
timeout), finite, and not declared invalid. ``FW_ARSP_MODE`` 1 ignores the sensor altogether.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Final

if TYPE_CHECKING:
    from firmware.platform.module import ModuleBase
    from firmware.platform.uorb import Subscription

__all__ = ["AirspeedInput"]

#: an airspeed older than this is not used (PX4: 1 s)
TIMEOUT_US: Final = 1_000_000


class AirspeedInput:
    """Reads ``airspeed`` for a module; :meth:`update` refreshes :attr:`valid`,
    :attr:`indicated_m_s` and :attr:`true_m_s`."""

    def __init__(self, module: ModuleBase) -> None:
        self.module = module
        orb = module.platform.orb
        # the airspeed topic comes with the airspeed sensor's build; without it, no airspeed
        self.sub: Subscription | None = (module.subscribe("airspeed")
                                         if "airspeed" in orb.registry.topics else None)
        self.valid = False
        self.indicated_m_s = math.nan
        self.true_m_s = math.nan
        self.last_us = 0
        self.use = True

    def update(self, now_us: int) -> bool:
        sub = self.sub
        if sub is not None:
            m = sub.update()
            if m is not None:
                ias = float(m.indicated_airspeed_m_s)
                tas = float(m.true_airspeed_m_s)
                conf = float(getattr(m, "confidence", 1.0))
                if math.isfinite(ias) and math.isfinite(tas) and conf > 0.0 and ias >= 0.0:
                    self.indicated_m_s, self.true_m_s = ias, tas
                    self.last_us = int(m.timestamp)
                else:
                    self.last_us = 0
        self.valid = (self.use and self.last_us > 0
                      and now_us - self.last_us < TIMEOUT_US)
        return self.valid
