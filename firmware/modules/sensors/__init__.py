"""The sensors module: calibration, voting and the vehicle-level sensor topics."""

from firmware.modules.sensors.module import SensorsModule, isa_altitude_m
from firmware.modules.sensors.params import PARAMS

__all__ = ["PARAMS", "SensorsModule", "isa_altitude_m"]
