"""Multicopter position controller (``mc_pos_control``): flight tasks, cascade, hover thrust."""

from firmware.modules.mc_pos_control.mc_pos_control import PARAMS, McPosControlModule

__all__ = ["PARAMS", "McPosControlModule"]
