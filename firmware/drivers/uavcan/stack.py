"""The FMU's DroneCAN node proper (what libuavcan's Node and PX4's UavcanNode do above the CAN
driver): transfers in and out, NodeStatus, GetNodeInfo both ways, the node table with
offline detection, the allocation server and the sensor bridges.

Imported when ``uavcan start`` runs, never at boot (the ``dronecan`` package's DSDL tables take
a few hundred milliseconds to load), so a board with UAVCAN disabled pays nothing.

Node discovery is PX4's: a node is known from its first NodeStatus; the FMU then asks it for
its GetNodeInfo (again every second until it answers, five times at most, and again after a
restart, seen as its uptime going back). A node is online while its NodeStatus arrives within 3 s (the spec's
offline timeout); going offline and coming back are reported in dmesg.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Final

import can

from firmware.drivers.uavcan.allocator import Allocator
from firmware.drivers.uavcan.bridges import GnssBridge, MagBridge
from firmware.drivers.uavcan.esc_output import EscOutput
from firmware.lib.uavcan.ids import PRIORITY_DEFAULT
from firmware.lib.uavcan.transfer import Reassembler, RxTransfer, TransferIds, encode, types
from firmware.lib.uavcan.txqueue import TxQueue
from firmware.platform import Platform

__all__ = ["DronecanStack", "NodeEntry", "FMU_NODE_NAME", "OFFLINE_TIMEOUT_US"]

NODE_STATUS_DTID: Final = 341
GET_NODE_INFO_DTID: Final = 1
ALLOCATION_DTID: Final = 1
FIX2_DTID: Final = 1063
AUXILIARY_DTID: Final = 1061
MAG2_DTID: Final = 1002
RAW_COMMAND_DTID: Final = 1030
ESC_STATUS_DTID: Final = 1034
#: RawCommand goes out ahead of the housekeeping (libuavcan's "fast" priority band)
PRIORITY_ESC: Final = 8
OFFLINE_TIMEOUT_US: Final = 3_000_000
NODE_STATUS_PERIOD_US: Final = 1_000_000
NODE_INFO_RETRY_US: Final = 1_000_000
#: GetNodeInfo requests to a node that never answers (a replayed recording, a bare adapter)
NODE_INFO_TRIES: Final = 5
#: what the FMU's GetNodeInfo says of itself (PX4 names its node after the board)
FMU_NODE_NAME: Final = "org.pixhawk.fmuv2"
FMU_SW_VERSION: Final = (1, 14)
FMU_HW_VERSION: Final = (2, 4)


class NodeEntry:
    """What the FMU knows of one node on the bus."""

    __slots__ = ("node_id", "last_us", "uptime_s", "health", "mode", "online", "name",
                 "sw_version", "info_asked_us", "info_tries", "status_count")

    def __init__(self, node_id: int) -> None:
        self.node_id = node_id
        self.last_us = 0
        self.uptime_s = 0
        self.health = 0
        self.mode = 0
        self.online = True
        self.name = ""
        self.sw_version = (0, 0)
        self.info_asked_us: int | None = None
        self.info_tries = 0
        self.status_count = 0


class DronecanStack:
    """Transfers over ``ctrl`` for node ``node_id``; ``dna`` runs the allocation server."""

    def __init__(self, platform: Platform, ctrl: Any, node_id: int, dna: bool,
                 sub_gps: bool, sub_mag: bool, unique_id: bytes,
                 gps_first_instance: Callable[[], int] = lambda: 0) -> None:
        self.platform = platform
        self.ctrl = ctrl
        self.node_id = node_id
        self.unique_id = unique_id
        self.txq = TxQueue(ctrl)
        self.rxa = Reassembler(node_id)
        self.tids = TransferIds()
        self.nodes: dict[int, NodeEntry] = {}
        self.allocator = Allocator(node_id, self._occupied) if dna else None
        self.gnss = GnssBridge(platform, gps_first_instance) if sub_gps else None
        self.esc: EscOutput | None = None
        self.mag = MagBridge(platform) if sub_mag else None
        self.node_status_rx = 0
        self.node_info_answered = 0
        self._next_status_us = 0

    def _occupied(self) -> set[int]:
        return set(self.nodes)

    # -- out -------------------------------------------------------------------------------

    def send(self, obj: Any, dtid: int, now_us: int, deadline_us: int,
             priority: int = PRIORITY_DEFAULT, dest: int | None = None,
             transfer_id: int | None = None) -> bool:
        if transfer_id is None:
            transfer_id = self.tids.next(dtid, dest is not None, dest or 0)
        frames = encode(obj, self.node_id, transfer_id, priority, dest)
        return self.txq.push(frames, deadline_us * 1000, now_us * 1000)

    def tick(self, now_us: int) -> None:
        """Once per driver cycle: expire late transfers, NodeStatus at 1 Hz, offline nodes,
        pending GetNodeInfo requests."""
        self.txq.expire(now_us * 1000)
        if now_us >= self._next_status_us:
            self._next_status_us = now_us + NODE_STATUS_PERIOD_US
            st = types().uavcan.protocol.NodeStatus(
                uptime_sec=(now_us // 1_000_000) & 0xFFFFFFFF, health=0, mode=0, sub_mode=0,
                vendor_specific_status_code=0)
            self.send(st, NODE_STATUS_DTID, now_us, now_us + NODE_STATUS_PERIOD_US)
        for n in self.nodes.values():
            if n.online and now_us - n.last_us > OFFLINE_TIMEOUT_US:
                n.online = False
                self.platform.warn("uavcan", f"node {n.node_id} ({n.name or 'unknown'}) offline: "
                                             f"no NodeStatus for {OFFLINE_TIMEOUT_US // 1000} ms")
            if n.online and not n.name and n.info_tries < NODE_INFO_TRIES and (
                    n.info_asked_us is None or now_us - n.info_asked_us >= NODE_INFO_RETRY_US):
                n.info_asked_us = now_us
                n.info_tries += 1
                req = types().uavcan.protocol.GetNodeInfo.Request()
                self.send(req, GET_NODE_INFO_DTID, now_us, now_us + NODE_INFO_RETRY_US,
                          dest=n.node_id)

    # -- in --------------------------------------------------------------------------------

    def receive(self, msg: can.Message, now_us: int) -> None:
        tr = self.rxa.push(msg, now_us * 1000)
        if tr is not None:
            self._dispatch(tr, now_us)

    def _dispatch(self, tr: RxTransfer, now_us: int) -> None:
        p = tr.payload
        dtid = tr.data_type_id
        if tr.service:
            if dtid == GET_NODE_INFO_DTID and tr.request:
                self._answer_node_info(tr, now_us)
            elif dtid == GET_NODE_INFO_DTID:
                n = self.nodes.get(tr.source)
                if n is not None:
                    n.name = bytes(p.name).decode("utf-8", "replace")
                    n.sw_version = (int(p.software_version.major),
                                    int(p.software_version.minor))
                    self.platform.info("uavcan", f"node {n.node_id}: {n.name} "
                                                 f"sw {n.sw_version[0]}.{n.sw_version[1]}")
            return
        if dtid == NODE_STATUS_DTID and tr.source != self.node_id:
            self._on_node_status(tr.source, p, now_us)
        elif dtid == ALLOCATION_DTID and tr.source == 0 and self.allocator is not None:
            self._on_allocation_request(p, now_us)
        elif dtid == FIX2_DTID and self.gnss is not None:
            self.gnss.on_fix2(tr.source, p, now_us)
        elif dtid == AUXILIARY_DTID and self.gnss is not None:
            self.gnss.on_auxiliary(tr.source, p)
        elif dtid == MAG2_DTID and self.mag is not None:
            self.mag.on_mag2(tr.source, p, now_us)
        elif dtid == ESC_STATUS_DTID and self.esc is not None:
            self.esc.on_status(tr.source, p, now_us)

    def send_esc_command(self, raw: list[int], now_us: int) -> bool:
        """One RawCommand; a command not out within 5 ms is stale and dropped."""
        m = types().uavcan.equipment.esc.RawCommand(cmd=raw)
        return self.send(m, RAW_COMMAND_DTID, now_us, now_us + 5_000, priority=PRIORITY_ESC)

    def _on_node_status(self, src: int, p: Any, now_us: int) -> None:
        self.node_status_rx += 1
        n = self.nodes.get(src)
        uptime = int(p.uptime_sec)
        if n is None:
            n = self.nodes[src] = NodeEntry(src)
            self.platform.info("uavcan", f"node {src} found")
        elif not n.online:
            n.online = True
            self.platform.info("uavcan", f"node {src} ({n.name or 'unknown'}) back online")
        if uptime < n.uptime_s:  # restarted: ask again who it is
            n.name = ""
            n.info_asked_us = None
            n.info_tries = 0
        n.last_us = now_us
        n.uptime_s = uptime
        n.health = int(p.health)
        n.mode = int(p.mode)
        n.status_count += 1

    def _answer_node_info(self, tr: RxTransfer, now_us: int) -> None:
        t = types().uavcan.protocol
        r = t.GetNodeInfo.Response()
        r.status = t.NodeStatus(uptime_sec=(now_us // 1_000_000) & 0xFFFFFFFF, health=0, mode=0,
                                sub_mode=0, vendor_specific_status_code=0)
        r.software_version.major, r.software_version.minor = FMU_SW_VERSION
        r.hardware_version.major, r.hardware_version.minor = FMU_HW_VERSION
        r.hardware_version.unique_id = list(self.unique_id)
        r.name = FMU_NODE_NAME
        self.node_info_answered += 1
        self.send(r, GET_NODE_INFO_DTID, now_us, now_us + 1_000_000, priority=tr.priority,
                  dest=tr.source, transfer_id=tr.transfer_id)

    def _on_allocation_request(self, p: Any, now_us: int) -> None:
        assert self.allocator is not None
        ans = self.allocator.handle(bool(p.first_part_of_unique_id), bytes(p.unique_id),
                                    int(p.node_id), now_us)
        if ans is None:
            return
        node_id, uid = ans
        a = types().uavcan.protocol.dynamic_node_id.Allocation(
            node_id=node_id, first_part_of_unique_id=False, unique_id=list(uid))
        if node_id:
            self.platform.info("uavcan", f"allocated node ID {node_id} to {uid.hex()}")
        self.send(a, ALLOCATION_DTID, now_us, now_us + 500_000)

    def nodes_online(self) -> list[int]:
        return sorted(n.node_id for n in self.nodes.values() if n.online)
