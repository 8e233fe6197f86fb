"""Multicopter attitude controller (``mc_att_control``)."""

from firmware.modules.mc_att_control.mc_att_control import PARAMS, McAttControlModule

__all__ = ["PARAMS", "McAttControlModule"]
