"""Fixed-wing attitude controller (``fw_att_control``)."""

from firmware.modules.fw_att_control.fw_att_control import PARAMS, FwAttControlModule

__all__ = ["PARAMS", "FwAttControlModule"]
