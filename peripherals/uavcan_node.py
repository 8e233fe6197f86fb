"""A UAVCAN v0 (DroneCAN) node on the FMU's CAN bus: a GNSS receiver or ESC with its own MCU.

What the FMU sees of it is what every UAVCAN node does: a ``uavcan.protocol.NodeStatus``
broadcast once per second (``period_ns``) from its node ID, and ACKs for every frame on the
bus. Its controller is a bxCAN-like :class:`~board.can.CanController` with automatic bus-off
recovery, as libuavcan's STM32 driver configures it (ABOM). A NodeStatus still in its mailbox
when the next one is due is aborted (its transfer deadline passed) and counted in
``tx_timeouts``; so a node alone on the bus, or on a faulty one, keeps at most one frame
pending.

NodeStatus (data type ID 341, 7 bytes): ``uptime_sec`` (uint32), ``health`` (2 bits) ``mode``
(3 bits) ``sub_mode`` (3 bits) in one byte, ``vendor_specific_status_code`` (uint16), all
little-endian, sent as a single-frame transfer (tail byte: start, end, toggle 0, transfer ID).
CAN ID (29 bits): priority (5 bits), data type ID (16), service-not-message 0 (1), source node
ID (7). This model decodes the NodeStatus of other nodes (the FMU's) to count them.
"""

from __future__ import annotations

import struct
from typing import Any, Final

import can

from board.can import CanBus, CanController
from board.kernel import PRIO_HW, Kernel

__all__ = ["NODE_STATUS_DTID", "UavcanNode", "decode_node_status", "encode_node_status"]

NODE_STATUS_DTID: Final = 341
#: libuavcan's default transfer priority (0 highest .. 31 lowest)
PRIORITY_DEFAULT: Final = 16
HEALTH_OK: Final = 0
MODE_OPERATIONAL: Final = 0


def encode_node_status(node_id: int, uptime_s: int, transfer_id: int, health: int = HEALTH_OK,
                       mode: int = MODE_OPERATIONAL, vendor: int = 0) -> can.Message:
    """One NodeStatus single-frame transfer from ``node_id``."""
    can_id = (PRIORITY_DEFAULT << 24) | (NODE_STATUS_DTID << 8) | (node_id & 0x7F)
    payload = struct.pack("<IBH", uptime_s & 0xFFFFFFFF, (health & 3) << 6 | (mode & 7) << 3,
                          vendor & 0xFFFF)
    tail = 0xC0 | (transfer_id & 0x1F)
    return can.Message(arbitration_id=can_id, is_extended_id=True, data=payload + bytes((tail,)))


def decode_node_status(msg: can.Message) -> tuple[int, int, int, int] | None:
    """(source node ID, uptime s, health, mode) of a NodeStatus frame, or None."""
    aid = msg.arbitration_id
    if (not msg.is_extended_id or (aid >> 8) & 0xFFFF != NODE_STATUS_DTID or aid & 0x80
            or len(msg.data) != 8 or msg.data[7] & 0xC0 != 0xC0):
        return None
    uptime, hm, _vendor = struct.unpack("<IBH", bytes(msg.data[:7]))
    return aid & 0x7F, uptime, hm >> 6, (hm >> 3) & 7


class UavcanNode:
    """A UAVCAN node plugged into ``bus``: NodeStatus every ``period_ns`` from ``first_ns``."""

    def __init__(self, kernel: Kernel, bus: CanBus, node_id: int = 125,
                 name: str = "uavcan_node", period_ns: int = 1_000_000_000,
                 first_ns: int | None = None) -> None:
        if type(node_id) is not int or not 1 <= node_id <= 125:
            raise ValueError(f"UAVCAN node {name}: node ID must be 1..125, got {node_id!r}")
        self.kernel = kernel
        self.name = name
        self.node_id = node_id
        self.ctrl = CanController(bus, name, auto_recovery=True)
        self.ctrl.on_receive(self._rx)
        self._tid = 0
        self._pending: can.Message | None = None
        #: NodeStatus frames of other nodes received, per source node ID: (count, t_ns, uptime)
        self.heard: dict[int, tuple[int, int, int]] = {}
        self.node_status_rx = 0
        self.node_status_tx = 0
        self.tx_timeouts = 0
        self.ctrl.on_tx_complete(self._tx_done)
        self._timer = kernel.call_every(period_ns, self._publish, priority=PRIO_HW,
                                        first_ns=first_ns)

    def _publish(self) -> None:
        if self._pending is not None:  # still not out: its deadline has passed
            self.ctrl.abort()
            self._pending = None
            self.tx_timeouts += 1
        uptime = self.kernel.now_ns // 1_000_000_000
        msg = encode_node_status(self.node_id, uptime, self._tid)
        self._tid = (self._tid + 1) & 0x1F
        if self.ctrl.send(msg):
            self._pending = msg

    def _tx_done(self, t_ns: int, msg: can.Message, ok: bool) -> None:
        if msg is self._pending:
            self._pending = None
        if ok:
            self.node_status_tx += 1

    def _rx(self, t_ns: int) -> None:
        while (msg := self.ctrl.recv()) is not None:
            st = decode_node_status(msg)
            if st is None:
                continue
            src, uptime, _h, _m = st
            count = self.heard.get(src, (0, 0, 0))[0]
            self.heard[src] = (count + 1, t_ns, uptime)
            self.node_status_rx += 1

    def stats(self) -> dict[str, Any]:
        c = self.ctrl
        return {"state": c.state, "tec": c.tec, "rec": c.rec, "bus_off_count": c.bus_off_count,
                "node_status_tx": self.node_status_tx, "node_status_rx": self.node_status_rx,
                "tx_timeouts": self.tx_timeouts,
                "heard": {k: v[0] for k, v in self.heard.items()}}
