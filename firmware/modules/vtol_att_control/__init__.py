"""Standard VTOL attitude control (``vtol_att_control``): transitions and the control mix."""

from firmware.modules.vtol_att_control.module import PARAMS, VtolAttControlModule

__all__ = ["PARAMS", "VtolAttControlModule"]
