"""uavcan: the FMU's UAVCAN v0 (DroneCAN) node on CAN1, as far as bus health goes.

``node`` holds the NodeStatus codec and the module (``uavcan start|stop|status``).
"""

from firmware.drivers.uavcan.node import PARAMS, UavcanModule

__all__ = ["PARAMS", "UavcanModule"]
