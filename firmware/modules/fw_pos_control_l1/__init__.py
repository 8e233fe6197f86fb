"""Fixed-wing position controller (``fw_pos_control_l1``): L1 guidance and TECS."""

from firmware.modules.fw_pos_control_l1.fw_pos_control_l1 import PARAMS, FwPosControlL1Module

__all__ = ["PARAMS", "FwPosControlL1Module"]
