"""navigator: takeoff, hold, mission, return and land setpoints (PX4's module)."""

from firmware.modules.navigator.navigator import NavigatorModule
from firmware.modules.navigator.params import PARAMS

__all__ = ["PARAMS", "NavigatorModule"]
