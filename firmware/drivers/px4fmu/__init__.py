"""The FMU's own PWM outputs (``fmu``): AUX1..AUX6 on a Pixhawk 1."""

from firmware.drivers.px4fmu.module import PARAMS, FmuModule

__all__ = ["PARAMS", "FmuModule"]
