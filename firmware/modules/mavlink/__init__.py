"""MAVLink for the emulated FMU: links over the board's UARTs or its UDP network port.

See :mod:`firmware.modules.mavlink.module` for the shell command and docs/mavlink.md for the
protocols, the board contract for UDP and the host-side bridge and ground-station client.
"""

from firmware.modules.mavlink.module import MavlinkModule

__all__ = ["MavlinkModule"]
