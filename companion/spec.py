"""The companion computer as data: its serial ports and the modules its firmware may start.

A Raspberry Pi 4 class computer (Broadcom BCM2711, 4x Cortex-A72 at 1.5 GHz) running Linux:

* ``/dev/ttyUSB0``: an FTDI USB-serial cable (FT232R, 3.3 V) plugged into the FMU's TELEM2
  connector (USART3, ``/dev/ttyS2``), port ``telem2``. The uORB bridge sets both ends to
  921600 baud (the FT232R divides 3 MHz by 3.25; the STM32's USART3 at 42 MHz by 2.875, both
  exact to well under 1 %).
* ``/dev/ttyS0``: the Pi's mini UART on GPIO14/15, the Linux serial console (115200 8N1) where
  the companion's nsh runs, port ``console``.

What a Linux computer does not have is not declared: no SPI/I2C sensors, no FRAM (parameters
live in a file on its disk, :mod:`companion.disk`), no IO coprocessor, no PWM.
"""

from __future__ import annotations

from typing import Final

from board.specs import BoardSpecData, UartSpec
from firmware.platform.module import STACK_MODULES

__all__ = ["COMPANION_RPI4", "COMPANION_MODULES", "CONSOLE_UART", "TELEM_UART",
           "TELEM_DEVICE"]

#: the device file of the FTDI cable to the FMU's TELEM2 (what ``uorb_bridge start -d`` names)
TELEM_DEVICE: Final = "/dev/ttyUSB0"
TELEM_UART: Final = "ttyUSB0"
CONSOLE_UART: Final = "ttyS0"

COMPANION_RPI4: Final = BoardSpecData(
    name="companion_rpi4",
    mcu="BCM2711",
    sysclk_hz=1_500_000_000,
    uarts=(
        UartSpec(TELEM_UART, TELEM_DEVICE, "telem2", 921_600, port="telem2",
                 about="FTDI FT232R USB-serial cable to the FMU's TELEM2 (USART3)"),
        UartSpec(CONSOLE_UART, "/dev/ttyS0", "console", 115_200, port="console",
                 about="mini UART on GPIO14/15: the Linux serial console (nsh)"),
    ),
)

#: Modules the companion's firmware may start, by shell name. The flight stack's entries are
#: taken from the FMU's table (:data:`firmware.platform.module.STACK_MODULES`), so a module is
#: the same class on both sides; a name not (yet) in that table falls back to its expected
#: place, and starting a module that does not exist prints a clear error and the script goes
#: on. No drivers: the companion has no sensors, FRAM or IO.
_WANTED: Final[dict[str, str]] = {
    "uorb_bridge": "firmware.modules.uorb_bridge:UorbBridgeModule",
    "ros_bridge": "firmware.modules.ros_bridge:RosBridgeModule",
    "mc_att_control": "firmware.modules.mc_att_control:McAttControlModule",
    "mc_att_control_so3": "firmware.modules.mc_att_control_so3:McAttControlSo3Module",
    "mc_att_select": "firmware.modules.mc_att_select:McAttSelectModule",
    "mc_rate_control": "firmware.modules.mc_rate_control:McRateControlModule",
}
COMPANION_MODULES: Final[dict[str, str]] = {
    name: STACK_MODULES.get(name, target) for name, target in _WANTED.items()}
