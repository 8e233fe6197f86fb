"""battery_status: the power module's battery estimate from the FMU ADC (PX4's module)."""

from firmware.modules.battery.battery import PARAMS, BatteryStatusModule

__all__ = ["PARAMS", "BatteryStatusModule"]
