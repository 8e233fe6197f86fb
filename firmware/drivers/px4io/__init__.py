"""px4io: the FMU driver of the PX4IO coprocessor, E14 (protocol 4, mixer on the IO).

``link`` is the transaction layer (UART, 10 ms timeout, 3 attempts), ``driver`` the task
(init, 400 Hz controls, 50 Hz status/RC poll, arming, reboot recovery), ``config`` the tables
it writes, ``module`` the shell command.
"""

from firmware.drivers.px4io.module import Px4ioModule

__all__ = ["Px4ioModule"]
