"""The FMU's DroneCAN node on CAN1 (PX4's ``uavcan`` module): NodeStatus, GetNodeInfo, node
discovery and offline detection, the dynamic node-ID allocation server, CAN GNSS and compass
onto ``sensor_gps`` / ``sensor_mag``, and the controller's error state.

Started by the ROMFS rcS only when ``UAVCAN_ENABLE`` > 0 (PX4's default 0: no CAN traffic, no
cost). At start the driver takes CAN1's bxCAN out of initialisation mode with automatic bus-off
management (ABOM, as libuavcan's STM32 driver sets it), so after a bus-off the hardware
rejoins the bus by itself once it has seen 128 x 11 recessive bits.

Interrupts, as the NuttX/libuavcan driver uses them: RX FIFO pending (frames copied to a
software queue), TX request complete (the transmit queue loads the next frame), error status
(ERRIE with BOFIE and EPVIE: bus-off and error-passive entries counted with their time). The
node loop runs every 10 ms on ``wq:uavcan``: it hands the queued frames to the DroneCAN stack
(:mod:`firmware.drivers.uavcan.stack`: transfers, services, the node table), expires transfers
whose deadline passed (counted in ``tx_timeouts``: a NodeStatus still queued when the next is
due), reads ESR (state, TEC, REC; BOFF clear after a bus-off counts a recovery) and publishes
``can_interface_status`` at 10 Hz and at once on a state change.

Encoding and decoding are the ``dronecan`` package's (through :mod:`firmware.lib.uavcan`);
the stack is imported only when the driver starts.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import can

from firmware.drivers.uavcan.params import PARAMS
from firmware.platform.module import ModuleError, WorkItemModule

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["NODE_STATUS_DTID", "OFFLINE_TIMEOUT_US", "PARAMS", "UavcanModule",
           "node_status_frame", "parse_node_status"]

NODE_STATUS_DTID = 341
OFFLINE_TIMEOUT_US = 3_000_000
PUBLISH_PERIOD_US = 100_000
_STATES = {"error_active": 0, "error_passive": 1, "bus_off": 2}


def node_status_frame(node_id: int, uptime_s: int, transfer_id: int, health: int = 0,
                      mode: int = 0) -> can.Message:
    """A NodeStatus single-frame transfer from ``node_id`` (the ``dronecan`` package's
    encoding)."""
    from firmware.lib.uavcan.transfer import encode, types

    st = types().uavcan.protocol.NodeStatus(uptime_sec=uptime_s & 0xFFFFFFFF, health=health & 3,
                                            mode=mode & 7, sub_mode=0,
                                            vendor_specific_status_code=0)
    return encode(st, node_id, transfer_id)[0]


def parse_node_status(msg: can.Message) -> tuple[int, int, int] | None:
    """(source node, uptime s, health) of a single-frame NodeStatus message, else None."""
    from firmware.lib.uavcan.transfer import decode_single

    tr = decode_single(msg)
    if tr is None or tr.service or tr.data_type_id != NODE_STATUS_DTID or tr.source == 0:
        return None
    return tr.source, int(tr.payload.uptime_sec), int(tr.payload.health)


class UavcanModule(WorkItemModule):
    """``uavcan start``: the FMU's DroneCAN node on CAN1."""

    NAME = "uavcan"
    DESCRIPTION = ("DroneCAN node on CAN1: NodeStatus, GetNodeInfo, node-ID allocation, CAN "
                   "GNSS and compass, bus health (can_interface_status)")
    WQ = "wq:uavcan"
    INTERVAL_US = 10_000
    CPU_COST_NS = 20_000
    PARAMS = PARAMS

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.ctrl: Any = None
        self.stack: Any = None

    def _start(self) -> None:
        hw: Any = getattr(self.system, "hw", None)
        buses = getattr(hw, "can", None) if hw is not None else None
        if not buses or "CAN1" not in buses:
            raise ModuleError("no CAN1 on this board")
        bitrate = int(self.param("UAVCAN_BITRATE"))
        wire = int(buses["CAN1"].bitrate)
        if bitrate != wire:
            why = (f"UAVCAN_BITRATE {bitrate}: the emulated CAN1 and its nodes run at {wire} "
                   f"bit/s only; the controller would see only errors")
            self.error(why)  # in dmesg as PX4_ERR, as well as on the console
            raise ModuleError(why)
        from firmware.drivers.uavcan.stack import DronecanStack

        self.ctrl = ctrl = hw.can_ctrl["CAN1"]
        self.node_id = int(self.param("UAVCAN_NODE_ID"))
        mode = int(self.param("UAVCAN_ENABLE"))
        # the STM32's 96-bit unique device ID, padded: fixed per board here
        uid = bytes(range(0x30, 0x3C)) + bytes(4)
        self.stack = DronecanStack(self.platform, ctrl, self.node_id, dna=mode >= 2,
                                   sub_gps=bool(self.param("UAVCAN_SUB_GPS")),
                                   sub_mag=bool(self.param("UAVCAN_SUB_MAG")), unique_id=uid,
                                   gps_first_instance=self._gps_first_instance)
        self._rxq: deque[can.Message] = deque()
        self.bus_off_count = 0
        self.error_passive_count = 0
        self.recoveries = 0
        self.last_bus_off_us = 0
        self.frames_tx = 0
        self.frames_rx = 0
        self._in_bus_off = False
        self._last_pub_us = -PUBLISH_PERIOD_US
        self._last_state = -1
        self._controls_sub: Any = None
        self._armed_sub: Any = None
        self._armed = False
        self._esc_pub: Any = None
        self._esc_msg: Any = None
        self._next_esc_status_us = 0
        self._esc_status_period_us = 0
        self._cmd_interval_us = 0
        self._last_cmd_us = -(1 << 62)
        if mode >= 3:  # ESCs on CAN: RawCommand from the FMU's own mixer (esc_output.py)
            from firmware.drivers.uavcan.esc_output import (COMMAND_INTERVAL_US,
                                                            ESC_STATUS_PERIOD_US, EscOutput)

            self.stack.esc = EscOutput(int(self.param("UAVCAN_EC_MIN")),
                                       int(self.param("UAVCAN_EC_MAX")))
            assert self.work_item is not None
            self._controls_sub = self.subscribe_callback(
                self.work_item, "actuator_controls_0", interval_us=COMMAND_INTERVAL_US)
            self._armed_sub = self.subscribe("actuator_armed")
            self._esc_pub = self.advertise("esc_status")
            self._esc_msg = self.platform.orb.new("esc_status")
            self._esc_status_period_us = ESC_STATUS_PERIOD_US
            self._cmd_interval_us = COMMAND_INTERVAL_US
        self._pub = self.advertise("can_interface_status")
        self._msg = self.platform.orb.new("can_interface_status")
        ctrl.on_receive(self._rx_isr)
        ctrl.on_tx_complete(self._tx_isr)
        ctrl.on_error(self._err_isr)
        ctrl.enable()
        self.info(f"node {self.node_id} on CAN1 at {ctrl.bus.bitrate // 1000} kbit/s"
                  + (", node-ID allocation server" if mode >= 2 else ""))

    def _gps_first_instance(self) -> int:
        # the serial gps driver publishes on instance 0 once it has found its receiver (it
        # claims that instance at its first fix): then a CAN GNSS takes the next one
        gps: Any = self.system.modules.get("gps")
        drv = getattr(gps, "driver", None)
        return 1 if drv is not None and getattr(drv, "configured", False) else 0

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
        if ok:
            self.frames_tx += 1
        self.stack.txq.tx_done(msg, ok)

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
        stack = self.stack
        q = self._rxq
        while q:
            self.frames_rx += 1
            stack.receive(q.popleft(), now)
        stack.tick(now)
        if self._controls_sub is not None:
            self._esc_output(now)
            if now >= self._next_esc_status_us:
                self._publish_esc_status(now)
        state = _STATES[self.ctrl.state]
        if self._in_bus_off and state != 2:
            self._in_bus_off = False
            self.recoveries += 1
        if state != self._last_state or now - self._last_pub_us >= PUBLISH_PERIOD_US:
            self._publish(now, state)

    def _esc_output(self, now: int) -> None:
        a = self._armed_sub.update()
        if a is not None:
            self._armed = bool(a.armed) and not a.lockdown and not a.manual_lockdown
        # at most every COMMAND_INTERVAL_US (PX4's 200 Hz), also when the item runs for other
        # reasons (received frames, timers); the cadence kept as SubscriptionInterval keeps it
        iv = self._cmd_interval_us
        if now - self._last_cmd_us < iv:
            return  # the update stays unread for the next turn
        c = self._controls_sub.update()
        if c is None:
            return
        nxt = self._last_cmd_us + iv
        self._last_cmd_us = nxt if now - iv < nxt <= now else now
        esc = self.stack.esc
        raw = esc.command(c.control, self._armed)
        if raw and self.stack.send_esc_command(raw, now):
            esc.commands_tx += 1
            esc.last_raw = raw

    def _publish_esc_status(self, now: int) -> None:
        """``esc_status`` at 10 Hz once an ESC has reported (a board without CAN ESCs on the
        bus publishes nothing, so its log has no esc_status data)."""
        self._next_esc_status_us = now + self._esc_status_period_us
        esc = self.stack.esc
        if esc is None or not esc.reports:
            return
        esc.fill_status(self._esc_msg, now)
        self._esc_pub.publish(self._esc_msg)

    def custom_command(self, args: list[str]) -> int:
        """``uavcan mixer FILE`` (what ``mixer load /dev/uavcan/esc FILE`` calls): the CAN ESC
        output's mixer, with UAVCAN_ENABLE 3."""
        if args and args[0] == "mixer" and len(args) == 2:
            esc = self.stack.esc if self.stack is not None else None
            if esc is None:
                self.print("uavcan: no CAN ESC output (UAVCAN_ENABLE is not 3)")
                return 1
            try:
                text = self.system.resolve_path(args[1]).read_text(encoding="latin-1")
                n = esc.load_mixer(text, args[1])
            except (OSError, ValueError) as exc:
                self.print(f"uavcan: mixer {args[1]}: {exc}")
                return 1
            self.info(f"ESC mixer {args[1]}: {n} outputs")
            return 0
        return super().custom_command(args)

    def nodes_online(self, now_us: int) -> list[int]:
        return list(self.stack.nodes_online()) if self.stack is not None else []

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
        m.tx_timeouts = self.stack.txq.tx_timeouts
        m.node_status_rx = self.stack.node_status_rx
        m.nodes_online = len(self.stack.nodes_online())
        self._pub.publish(m)
        self._last_pub_us = now
        self._last_state = state

    def status_lines(self) -> list[str]:
        if self.ctrl is None or self.stack is None:
            return []
        c = self.ctrl
        s = self.stack
        now = self.platform.time_us()
        rx = s.rxa
        errs = ", ".join(f"{k} {v}" for k, v in rx.errors.items() if v) or "none"
        lines = [f"CAN1: {c.state.replace('_', '-')}, TEC {min(c.tec, 255)} REC {c.rec}, "
                 f"bus-off {self.bus_off_count} (recovered {self.recoveries}), "
                 f"error-passive {self.error_passive_count}",
                 f"frames tx {self.frames_tx} rx {self.frames_rx}, transfers tx "
                 f"{s.txq.transfers_tx} rx {rx.transfers}, tx timeouts {s.txq.tx_timeouts}, "
                 f"node ID {self.node_id}",
                 f"dropped transfers: {errs}"]
        if s.allocator is not None:
            a = s.allocator
            lines.append(f"node-ID allocation server: {a.allocations} allocations, "
                         f"table {dict(sorted((v, k.hex()) for k, v in a.table.items()))}")
        for n in sorted(s.nodes.values(), key=lambda e: e.node_id):
            on = "online" if n.online else "offline"
            name = n.name or "?"
            lines.append(f"node {n.node_id}: {on}, {name} sw {n.sw_version[0]}."
                         f"{n.sw_version[1]}, uptime {n.uptime_s} s, health {n.health}, "
                         f"last NodeStatus {(now - n.last_us) / 1e6:.1f} s ago")
        if s.esc is not None:
            e = s.esc
            lines.append(f"ESC output: mixer {e.mixer_path or 'none'}, {e.commands_tx} "
                         f"RawCommands, last {e.last_raw}")
            for idx, r in sorted(e.reports.items()):
                lines.append(f"esc {idx}: node {r.node_id}, {r.rpm} rpm, {r.voltage_v:.1f} V, "
                             f"{r.current_a:.1f} A, {r.temperature_c:.0f} C, {r.power_pct} %, "
                             f"errors {r.error_count}, status {r.count}, "
                             f"{(now - r.last_us) / 1e6:.1f} s ago")
        if s.gnss is not None or s.mag is not None:
            lines.append(f"sensors: GNSS fixes {s.gnss.fixes if s.gnss else '-'}, "
                         f"mag samples {s.mag.samples if s.mag else '-'}")
        return lines
