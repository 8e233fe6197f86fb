"""PX4's ``VehicleAirData``: the selected barometer averaged into ``vehicle_air_data``.

Part of the ``sensors`` work item, which feeds it the selected barometer's samples; every
1/SENS_BARO_RATE their mean pressure (less the calibration's offset) and temperature go out with
the ISA altitude referenced to SENS_BARO_QNH and the air density.
"""

from __future__ import annotations

from typing import Any, Final

from firmware.modules.sensors.voter import SensorInstance
from firmware.platform.uorb import Publication

__all__ = ["VehicleAirData", "isa_altitude_m"]

_T0_K: Final = 288.15
_LAPSE_K_M: Final = 0.0065
_ISA_EXP: Final = 0.190263          # R L / (g M) of the ISA troposphere
_R_AIR: Final = 287.05              # J/(kg K)
_KELVIN: Final = 273.15


def isa_altitude_m(pressure_pa: float, qnh_pa: float = 101325.0) -> float:
    """Altitude of a static pressure in the ISA troposphere, referenced to ``qnh_pa``."""
    return _T0_K / _LAPSE_K_M * (1.0 - (pressure_pa / qnh_pa) ** _ISA_EXP)


class VehicleAirData:
    """Mean of the selected barometer over one SENS_BARO_RATE interval."""

    def __init__(self, pub: Publication, msg: Any, now: int) -> None:
        self._pub = pub
        self._msg = msg
        self.qnh_pa = 101325.0
        self.interval_us = 50_000
        self._p = self._temp = 0.0
        self._ts = self._n = 0
        self._next_us = now

    def add(self, msg: Any, offset_pa: float) -> None:
        """One sample of the selected barometer, its calibrated offset removed."""
        self._p += msg.pressure - offset_pa
        self._temp += msg.temperature
        self._ts += msg.timestamp_sample
        self._n += 1

    def publish_if_due(self, now: int, baro: SensorInstance) -> None:
        """Publish the interval's mean if it has samples and is over (``baro``: selected)."""
        n = self._n
        if not n or now < self._next_us:
            return
        p = self._p / n
        temp = self._temp / n
        m = self._msg
        m.timestamp = now
        m.timestamp_sample = self._ts // n
        m.baro_device_id = baro.device_id
        m.baro_alt_meter = isa_altitude_m(p, self.qnh_pa)
        m.baro_temp_celcius = temp
        m.baro_pressure_pa = p
        m.rho = p / (_R_AIR * (temp + _KELVIN))
        m.calibration_count = baro.cal.slot + 1
        self._pub.publish(m)
        self.reset()
        self._next_us = max(self._next_us + self.interval_us, now - self.interval_us)

    def reset(self) -> None:
        """Drop the samples so far (after a publication, or another barometer selected)."""
        self._p = self._temp = 0.0
        self._ts = self._n = 0
