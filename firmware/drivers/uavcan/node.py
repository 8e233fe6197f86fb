"""The FMU's UAVCAN node on CAN1: NodeStatus out at 1 Hz, other nodes' NodeStatus counted, the
controller's error state reported (PX4's ``uavcan`` module, reduced to bus health).

Started by the ROMFS rcS only when ``UAVCAN_ENABLE`` > 0 (PX4's default 0: no CAN traffic, no
cost). At start the driver takes CAN1's bxCAN out of initialisation mode with automatic bus-off
management (ABOM, as libuavcan's STM32 driver sets it), so after a bus-off the hardware
rejoins the bus by itself once it has seen 128 x 11 recessive bits.

Interrupts, as the NuttX/libuavcan driver uses them: RX FIFO pending (frames copied to a
software queue), TX request complete (frames sent), error status (ERRIE with BOFIE and EPVIE:
bus-off and error-passive entries counted with their time). The node loop runs every 10 ms on
``wq:uavcan``: it drains the queue, decodes ``uavcan.protocol.NodeStatus`` (data type 341) from
other nodes, sends its own NodeStatus once a second (a frame still in its mailbox when the next
is due passed its deadline: it is aborted and counted in ``tx_timeouts``), reads ESR (state,
TEC, REC; BOFF clear after a bus-off counts a recovery) and publishes
``can_interface_status`` at 10 Hz and at once on a state change. A node is online while its
NodeStatus arrived within the last 3 s (UAVCAN's offline timeout).
"""

from __future__ import annotations

import struct
from collections import deque
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import can

from firmware.platform.module import ModuleError, WorkItemModule
from firmware.platform.params import ParamDef

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["NODE_STATUS_DTID", "OFFLINE_TIMEOUT_US", "PARAMS", "UavcanModule",
           "node_status_frame", "parse_node_status"]

NODE_STATUS_DTID = 341
OFFLINE_TIMEOUT_US = 3_000_000
NODE_STATUS_PERIOD_US = 1_000_000
PUBLISH_PERIOD_US = 100_000
_PRIORITY = 16            # libuavcan's default transfer priority
_STATES = {"error_active": 0, "error_passive": 1, "bus_off": 2}
_G = "UAVCAN"

PARAMS: tuple[ParamDef, ...] = (
    ParamDef("UAVCAN_ENABLE", "INT32", 0, min=0, max=3, group=_G, reboot_required=True,
             short="UAVCAN mode",
             long="0: the uavcan driver is not started (no CAN traffic). Any other value starts "
                  "it from the startup script on CAN1.",
             values={0: "Disabled", 1: "Sensors Manual Config", 2: "Sensors Automatic Config",
                     3: "Sensors and Actuators (ESCs) Automatic Config"}),
    ParamDef("UAVCAN_NODE_ID", "INT32", 1, min=1, max=125, group=_G, reboot_required=True,
             short="UAVCAN Node ID", long="Read once at startup."),
)


def node_status_frame(node_id: int, uptime_s: int, transfer_id: int, health: int = 0,
                      mode: int = 0) -> can.Message:
    """A NodeStatus single-frame transfer: 29-bit ID (priority, data type, source node), 7
    payload bytes (uptime, health/mode/sub-mode, vendor code; little-endian), tail byte."""
    payload = struct.pack("<IBH", uptime_s & 0xFFFFFFFF, (health & 3) << 6 | (mode & 7) << 3, 0)
    return can.Message(arbitration_id=(_PRIORITY << 24) | (NODE_STATUS_DTID << 8) | node_id,
                       is_extended_id=True,
                       data=payload + bytes((0xC0 | (transfer_id & 0x1F),)))


def parse_node_status(msg: can.Message) -> tuple[int, int, int] | None:
    """(source node, uptime s, health) of a single-frame NodeStatus message, else None."""
    aid = msg.arbitration_id
    data = msg.data
    if (msg.is_extended_id and (aid >> 8) & 0xFFFF == NODE_STATUS_DTID and not aid & 0x80
            and len(data) == 8 and data[7] & 0xC0 == 0xC0):
        return aid & 0x7F, int.from_bytes(data[0:4], "little"), data[4] >> 6
    return None


class UavcanModule(WorkItemModule):
    """``uavcan start``: the FMU's UAVCAN node on CAN1."""

    NAME = "uavcan"
    DESCRIPTION = "UAVCAN node on CAN1: NodeStatus, bus health (can_interface_status)"
    WQ = "wq:uavcan"
    INTERVAL_US = 10_000
    CPU_COST_NS = 20_000
    PARAMS = PARAMS

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.ctrl: Any = None

    def _start(self) -> None:
        hw = getattr(self.system, "hw", None)
        buses = getattr(hw, "can", None) if hw is not None else None
        if not buses or "CAN1" not in buses:
            raise ModuleError("no CAN1 on this board")
        self.ctrl = ctrl = hw.can_ctrl["CAN1"]
        self.node_id = int(self.param("UAVCAN_NODE_ID"))
        self._rxq: deque[can.Message] = deque()
        self.bus_off_count = 0
        self.error_passive_count = 0
        self.recoveries = 0
        self.last_bus_off_us = 0
        self.frames_tx = 0
        self.frames_rx = 0
        self.tx_timeouts = 0
        self.node_status_rx = 0
        self.nodes: dict[int, tuple[int, int, int]] = {}  # id -> (last us, uptime, health)
        self._in_bus_off = False
        self._pending: can.Message | None = None
        self._tid = 0
        self._next_status_us = 0
        self._last_pub_us = -PUBLISH_PERIOD_US
        self._last_state = -1
        self._pub = self.advertise("can_interface_status")
        self._msg = self.platform.orb.new("can_interface_status")
        ctrl.on_receive(self._rx_isr)
        ctrl.on_tx_complete(self._tx_isr)
        ctrl.on_error(self._err_isr)
        ctrl.enable()
        self.info(f"node {self.node_id} on CAN1 at {ctrl.bus.bitrate // 1000} kbit/s")

    def _stop(self) -> None:
        ctrl = self.ctrl
        if ctrl is not None:
            ctrl.abort()
            ctrl.disable()
            ctrl.on_receive(None)
            ctrl.on_tx_complete(None)
            ctrl.on_error(None)

    # -- interrupts --------------------------------------------------------------------------

    def _rx_isr(self, t_ns: int) -> None:
        ctrl = self.ctrl
        while (m := ctrl.recv()) is not None:
            self._rxq.append(m)

    def _tx_isr(self, t_ns: int, msg: can.Message, ok: bool) -> None:
        if msg is self._pending:
            self._pending = None
        if ok:
            self.frames_tx += 1

    def _err_isr(self, t_ns: int, state: str) -> None:
        if state == "bus_off":
            self.bus_off_count += 1
            self.last_bus_off_us = t_ns // 1000
            self._in_bus_off = True
        elif state == "error_passive":
            self.error_passive_count += 1

    # -- the node loop -----------------------------------------------------------------------

    def run(self) -> None:
        now = self.platform.time_us()
        ctrl = self.ctrl
        q = self._rxq
        while q:
            m = q.popleft()
            self.frames_rx += 1
            st = parse_node_status(m)
            if st is not None and st[0] != self.node_id:
                self.nodes[st[0]] = (now, st[1], st[2])
                self.node_status_rx += 1
        if now >= self._next_status_us:
            self._next_status_us = now + NODE_STATUS_PERIOD_US
            if self._pending is not None:  # deadline passed without leaving the mailbox
                ctrl.abort()
                self._pending = None
                self.tx_timeouts += 1
            msg = node_status_frame(self.node_id, now // 1_000_000, self._tid)
            self._tid = (self._tid + 1) & 0x1F
            if ctrl.send(msg):
                self._pending = msg
        state = _STATES[ctrl.state]
        if self._in_bus_off and state != 2:
            self._in_bus_off = False
            self.recoveries += 1
        if state != self._last_state or now - self._last_pub_us >= PUBLISH_PERIOD_US:
            self._publish(now, state)

    def nodes_online(self, now_us: int) -> list[int]:
        return sorted(n for n, (t, _u, _h) in self.nodes.items()
                      if now_us - t <= OFFLINE_TIMEOUT_US)

    def _publish(self, now: int, state: int) -> None:
        ctrl = self.ctrl
        m = self._msg
        m.timestamp = now
        m.interface = 0
        m.state = state
        m.tec = min(ctrl.tec, 255)
        m.rec = min(ctrl.rec, 255)
        m.bus_off_count = self.bus_off_count
        m.error_passive_count = self.error_passive_count
        m.recoveries = self.recoveries
        m.last_bus_off = self.last_bus_off_us
        m.frames_tx = self.frames_tx
        m.frames_rx = self.frames_rx
        m.tx_timeouts = self.tx_timeouts
        m.node_status_rx = self.node_status_rx
        m.nodes_online = len(self.nodes_online(now))
        self._pub.publish(m)
        self._last_pub_us = now
        self._last_state = state

    def status_lines(self) -> list[str]:
        if self.ctrl is None:
            return []
        c = self.ctrl
        now = self.platform.time_us()
        lines = [f"CAN1: {c.state.replace('_', '-')}, TEC {min(c.tec, 255)} REC {c.rec}, "
                 f"bus-off {self.bus_off_count} (recovered {self.recoveries}), "
                 f"error-passive {self.error_passive_count}",
                 f"frames tx {self.frames_tx} rx {self.frames_rx}, NodeStatus tx timeouts "
                 f"{self.tx_timeouts}, node ID {self.node_id}"]
        for n, (t, up, health) in sorted(self.nodes.items()):
            on = "online" if now - t <= OFFLINE_TIMEOUT_US else "offline"
            lines.append(f"node {n}: {on}, uptime {up} s, health {health}, "
                         f"last NodeStatus {(now - t) / 1e6:.1f} s ago")
        return lines
