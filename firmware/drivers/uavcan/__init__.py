"""uavcan: the FMU's DroneCAN (UAVCAN v0) node on CAN1, PX4's ``uavcan`` module.

``node`` holds the module (``uavcan start|stop|status``), ``params`` its parameters,
``stack`` the node's transfers and services, ``allocator`` the dynamic node-ID allocation
server, ``bridges`` the CAN GNSS and compass publishers. The DroneCAN transport shared with
the node models is :mod:`firmware.lib.uavcan`.
"""

from firmware.drivers.uavcan.node import PARAMS, UavcanModule

__all__ = ["PARAMS", "UavcanModule"]
