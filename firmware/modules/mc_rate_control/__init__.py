"""Multicopter rate controller (``mc_rate_control``)."""

from firmware.modules.mc_rate_control.mc_rate_control import PARAMS, McRateControlModule

__all__ = ["PARAMS", "McRateControlModule"]
