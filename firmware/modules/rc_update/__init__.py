"""rc_update: RC calibration, function mapping, manual control and switches (PX4's module)."""

from firmware.modules.rc_update.rc_update import (
    RcUpdateModule,
    mode_slot,
    scale_channel,
    switch_position,
)

__all__ = ["RcUpdateModule", "mode_slot", "scale_channel", "switch_position"]
