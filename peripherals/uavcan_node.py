"""A plain DroneCAN node on the FMU's CAN bus (NodeStatus, GetNodeInfo, dynamic node ID).

Kept under its old name for the board's ``uavcan_nodes=(125,)``: the node itself is
:class:`peripherals.dronecan.node.DronecanNode`, whose NodeStatus and GetNodeInfo come from
the ``dronecan`` package's DSDL types instead of the hand-written encoding this module held.
"""

from __future__ import annotations

from peripherals.dronecan.node import (
    HEALTH_OK,
    MODE_OPERATIONAL,
    NODE_STATUS_DTID,
    DronecanNode,
)

__all__ = ["HEALTH_OK", "MODE_OPERATIONAL", "NODE_STATUS_DTID", "UavcanNode"]


class UavcanNode(DronecanNode):
    """A node that only announces itself (a GNSS receiver or ESC seen by its NodeStatus)."""
