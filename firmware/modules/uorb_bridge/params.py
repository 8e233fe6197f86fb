"""The uORB bridge's parameters: which serial port the startup script starts it on, and the
port's speed (PX4's UXRCE_DDS_CFG and SER_TEL2_BAUD conventions)."""

from __future__ import annotations

from typing import Final

from firmware.platform.params import ParamDef

__all__ = ["PARAMS", "CFG_DISABLED", "CFG_TELEM1", "CFG_TELEM2"]

CFG_DISABLED: Final = 0
CFG_TELEM1: Final = 101
CFG_TELEM2: Final = 102

_BAUDS: Final = {57600: "57600 8N1", 115200: "115200 8N1", 230400: "230400 8N1",
                 460800: "460800 8N1", 921600: "921600 8N1", 1500000: "1500000 8N1"}

PARAMS: Final[tuple[ParamDef, ...]] = (
    ParamDef("UORB_BRG_CFG", "INT32", CFG_DISABLED, min=0, max=102, group="uORB bridge",
             short="Serial configuration for the uORB bridge to a companion computer",
             long="The port the startup script starts uorb_bridge on (-r fmu), with the "
                  "topic list /etc/bridge/topics.yaml. 102 TELEM 2 (/dev/ttyS2 at "
                  "SER_TEL2_BAUD) is the companion computer's port; 0 starts no bridge. "
                  "101 (TELEM 1) is reserved: the startup script runs MAVLink there. The "
                  "values follow PX4's UXRCE_DDS_CFG.",
             values={CFG_DISABLED: "Disabled", CFG_TELEM1: "TELEM 1 (reserved)",
                     CFG_TELEM2: "TELEM 2"},
             reboot_required=True),
    ParamDef("SER_TEL2_BAUD", "INT32", 921600, min=0, max=3000000, group="Serial",
             short="Baudrate for the TELEM 2 serial port",
             long="The speed of /dev/ttyS2 (USART3) for the service that uses it (uorb_bridge "
                  "with UORB_BRG_CFG 102). 921600 is what companion computers run at and "
                  "PX4's default for TELEM 2.",
             values=_BAUDS, reboot_required=True),
)
