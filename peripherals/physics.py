"""Physical inputs of a board's sensors: what the world says the chip is experiencing.

Sensor models never see the world directly; they read an :class:`Environment`, updated by the
board from the truth records the orchestrator routes to it (or set by a test fixture that holds
the board still or spins it). Values are SI at the model boundary: specific force in m/s^2 and
rates in rad/s in the board's body frame (FRD), field in gauss, pressure in Pa (static, and the
pitot's differential pressure), temperature in degC, position in degrees and metres, velocity
NED in m/s.

Between two updates the value is held (zero-order hold): the world steps at 1 kHz and the
sensors' own filters and data rates are modelled by the chips.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Final
from common.units import G0_M_S2
from common.quaternion import Vec3

__all__ = ["Environment"]



@dataclass
class Environment:
    t_ns: int = 0
    accel_m_s2: Vec3 = (0.0, 0.0, -G0_M_S2)     # specific force, body FRD (level and still: -g on z)
    gyro_rad_s: Vec3 = (0.0, 0.0, 0.0)     # body rates, FRD
    mag_gauss: Vec3 = (0.21, 0.01, 0.43)   # earth field in body axes
    pressure_pa: float = 101_325.0
    temperature_c: float = 25.0            # air temperature (the chips add self-heating)
    diff_pressure_pa: float = 0.0          # pitot minus static (dynamic pressure): airspeed sensors
    board_temperature_c: float = 35.0      # the FMU's temperature, what the sensors' dies see
    lat_deg: float = 47.397742
    lon_deg: float = 8.545594
    alt_m: float = 488.0
    vel_ned_m_s: Vec3 = (0.0, 0.0, 0.0)
    gps_available: bool = True             # sky view: False indoors / under a jammer
    extra: dict = field(default_factory=dict)

    def update_from_truth(self, t_ns: int, truth: dict) -> None:
        """Copy the fields of a world truth record (a mapping of field name to value)."""
        self.set_truth(t_ns, truth["accel_body_m_s2"], truth["gyro_rad_s"],
                       truth["mag_body_gauss"], truth["pressure_pa"], truth["temperature_c"],
                       truth["lat_deg"], truth["lon_deg"], truth["alt_m"], truth["vel_ned_m_s"])

    def set_truth(self, t_ns: int, accel_m_s2: Vec3, gyro_rad_s: Vec3, mag_gauss: Vec3,
                  pressure_pa: float, temperature_c: float, lat_deg: float, lon_deg: float,
                  alt_m: float, vel_ned_m_s: Vec3) -> None:
        """The same from the values themselves (the board's 1 kHz path: no mapping built)."""
        self.t_ns = t_ns
        self.accel_m_s2 = accel_m_s2
        self.gyro_rad_s = gyro_rad_s
        self.mag_gauss = mag_gauss
        self.pressure_pa = pressure_pa
        self.temperature_c = temperature_c
        self.lat_deg = lat_deg
        self.lon_deg = lon_deg
        self.alt_m = alt_m
        self.vel_ned_m_s = vel_ned_m_s
