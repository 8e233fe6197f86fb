"""Multicopter attitude controller, geometric SO(3) law (``mc_att_control_so3``)."""

from firmware.modules.mc_att_control_so3.mc_att_control_so3 import PARAMS, McAttControlSo3Module

__all__ = ["PARAMS", "McAttControlSo3Module"]
