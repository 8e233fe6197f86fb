"""A DroneCAN (UAVCAN v0) node on a CAN bus: an MCU of its own running libcanard-like firmware.

What the rest of the bus sees of it is what every DroneCAN node does:

* ``uavcan.protocol.NodeStatus`` once a second (``period_ns``) from its node ID;
* an answer to ``uavcan.protocol.GetNodeInfo`` (name, software and hardware version with its
  16-byte unique ID);
* with no configured ID (``node_id=0``), the client side of dynamic node-ID allocation
  (``uavcan.protocol.dynamic_node_id.Allocation``, the spec's three-stage exchange): anonymous
  requests every 600-1000 ms carrying the first 6 bytes of its unique ID; when an allocator
  answers with a matching prefix, the next part after a 0-400 ms delay; when the answer holds
  the whole unique ID and a node ID, it takes that ID. The random periods and delays come from
  the node's seeded generator.

Its controller is a bxCAN-like :class:`~board.can.CanController` with automatic bus-off
recovery, as libuavcan's STM32 driver configures it (ABOM), behind a transmit queue with
deadlines (:class:`firmware.lib.uavcan.txqueue.TxQueue`: a NodeStatus still queued when the
next is due is dropped and counted in ``tx_timeouts``). Encoding, decoding and transfer
reassembly are the shared DroneCAN library's (:mod:`firmware.lib.uavcan`, built on the
``dronecan`` package); malformed transfers are counted and dropped.

``set_silent(True)`` is a node that stops talking (a hung MCU, a cut CAN stub): its controller
leaves the bus (no frames, no ACKs) until ``set_silent(False)``.

Subclasses (GNSS, magnetometer) override :meth:`_on_ready` (start publishing once the node
has an ID) and :meth:`_on_transfer` (transfers the base does not handle).
"""

from __future__ import annotations

import hashlib
from typing import Any, ClassVar, Final

import numpy as np

from board.can import CanBus, CanController
from board.kernel import PRIO_HW, Kernel
from firmware.lib.uavcan.ids import PRIORITY_DEFAULT, PRIORITY_LOWEST
from firmware.lib.uavcan.transfer import Reassembler, RxTransfer, TransferIds, encode, types
from firmware.lib.uavcan.txqueue import TxQueue

__all__ = ["DronecanNode", "HEALTH_OK", "HEALTH_WARNING", "MODE_OPERATIONAL", "NODE_STATUS_DTID",
           "unique_id_for"]

NODE_STATUS_DTID: Final = 341
GET_NODE_INFO_DTID: Final = 1
ALLOCATION_DTID: Final = 1
HEALTH_OK: Final = 0
HEALTH_WARNING: Final = 1
MODE_OPERATIONAL: Final = 0
MODE_INITIALIZATION: Final = 1
NS_PER_MS: Final = 1_000_000
#: the spec's request period and follow-up delay bounds for allocation clients
MIN_REQUEST_PERIOD_MS: Final = 600
MAX_REQUEST_PERIOD_MS: Final = 1000
MAX_FOLLOWUP_DELAY_MS: Final = 400
UID_PART: Final = 6  # unique-ID bytes an anonymous single-frame request can carry


def unique_id_for(name: str, seed: int = 0) -> bytes:
    """A node's 16-byte unique ID (the MCU's serial number on real hardware), fixed by its
    name and the board seed."""
    return hashlib.sha256(f"{seed}:{name}".encode()).digest()[:16]


class DronecanNode:
    """A node plugged into ``bus``: NodeStatus every ``period_ns`` from ``first_ns``;
    ``node_id`` 0 asks an allocator for one first."""

    #: message data types the node's firmware subscribes to (its acceptance filter)
    ACCEPT: ClassVar[frozenset[int]] = frozenset({NODE_STATUS_DTID, ALLOCATION_DTID})
    #: what GetNodeInfo reports (the product's reverse-domain name, versions)
    HW_NAME = "org.hil.node"
    SW_VERSION = (1, 0)
    HW_VERSION = (1, 0)

    def __init__(self, kernel: Kernel, bus: CanBus, node_id: int = 125,
                 name: str = "uavcan_node", period_ns: int = 1_000_000_000,
                 first_ns: int | None = None, rng: np.random.Generator | None = None,
                 seed: int = 0) -> None:
        if type(node_id) is not int or not 0 <= node_id <= 125:
            raise ValueError(f"DroneCAN node {name}: node ID must be 1..125 (0: dynamic), "
                             f"got {node_id!r}")
        self.kernel = kernel
        self.name = name
        self.node_id = node_id
        self.configured_id = node_id
        self.period_ns = period_ns
        self.unique_id = unique_id_for(name, seed)
        self.rng = rng if rng is not None else np.random.default_rng(
            int.from_bytes(self.unique_id[:8], "little"))
        self.ctrl = CanController(bus, name, auto_recovery=True)
        self.ctrl.on_receive(self._rx)
        self.ctrl.on_tx_complete(self._tx_done)
        self.txq = TxQueue(self.ctrl)
        self.rxa = Reassembler(node_id, self.ACCEPT)
        self.tids = TransferIds()
        self.silent = False
        #: NodeStatus.health this node reports (a subclass raises it while it has a problem)
        self.health = HEALTH_OK
        #: NodeStatus frames of other nodes received, per source node ID: (count, t_ns, uptime)
        self.heard: dict[int, tuple[int, int, int]] = {}
        self.node_status_rx = 0
        self.node_status_tx = 0
        self.node_info_requests = 0
        self.allocated_at_ns: int | None = None
        self._dna_event: Any = None
        self._dna_stage = 0
        self._timer = kernel.call_every(period_ns, self._status_tick, priority=PRIO_HW,
                                        first_ns=first_ns)
        if node_id == 0:
            self._schedule_request(kernel.now_ns)
        else:
            kernel.call_at(kernel.now_ns, self._ready, priority=PRIO_HW)

    # -- sending ---------------------------------------------------------------------------

    def send(self, obj: Any, dtid: int, deadline_ns: int, priority: int = PRIORITY_DEFAULT,
             dest: int | None = None, transfer_id: int | None = None) -> bool:
        """Queue one transfer of ``obj`` from this node (anonymous while it has no ID)."""
        if self.silent:
            return False
        if transfer_id is None:
            transfer_id = self.tids.next(dtid, dest is not None, dest or 0)
        frames = encode(obj, self.node_id, transfer_id, priority, dest)
        return self.txq.push(frames, deadline_ns, self.kernel.now_ns)

    def _status_tick(self) -> None:
        now = self.kernel.now_ns
        self.txq.expire(now)
        if self.silent or self.node_id == 0:
            return
        mode = MODE_OPERATIONAL if self.allocated_at_ns is not None else MODE_INITIALIZATION
        st = types().uavcan.protocol.NodeStatus(uptime_sec=self._uptime_s(), health=self.health,
                                                mode=mode, sub_mode=0,
                                                vendor_specific_status_code=0)
        self.send(st, NODE_STATUS_DTID, now + self.period_ns)

    def _uptime_s(self) -> int:
        return (self.kernel.now_ns // 1_000_000_000) & 0xFFFFFFFF

    def _tx_done(self, t_ns: int, msg: Any, ok: bool) -> None:
        before = self.txq.transfers_tx
        self.txq.tx_done(msg, ok)
        if self.txq.transfers_tx != before and msg.arbitration_id >> 8 & 0xFFFF == \
                NODE_STATUS_DTID and not msg.arbitration_id & 0x80:
            self.node_status_tx += 1

    # -- receiving -------------------------------------------------------------------------

    def _rx(self, t_ns: int) -> None:
        while (msg := self.ctrl.recv()) is not None:
            tr = self.rxa.push(msg, t_ns)
            if tr is not None and not self.silent:
                self._dispatch(tr)

    def _dispatch(self, tr: RxTransfer) -> None:
        p = tr.payload
        if not tr.service and tr.data_type_id == NODE_STATUS_DTID:
            count = self.heard.get(tr.source, (0, 0, 0))[0]
            self.heard[tr.source] = (count + 1, tr.t_ns, int(p.uptime_sec))
            self.node_status_rx += 1
        elif tr.service and tr.request and tr.data_type_id == GET_NODE_INFO_DTID:
            self._answer_node_info(tr)
        elif not tr.service and tr.data_type_id == ALLOCATION_DTID and tr.source != 0:
            self._on_allocation(tr)
        else:
            self._on_transfer(tr)

    def _answer_node_info(self, tr: RxTransfer) -> None:
        self.node_info_requests += 1
        t = types().uavcan.protocol
        r = t.GetNodeInfo.Response()
        r.status = t.NodeStatus(uptime_sec=self._uptime_s(), health=self.health,
                                mode=MODE_OPERATIONAL, sub_mode=0, vendor_specific_status_code=0)
        r.software_version.major, r.software_version.minor = self.SW_VERSION
        r.hardware_version.major, r.hardware_version.minor = self.HW_VERSION
        r.hardware_version.unique_id = list(self.unique_id)
        r.name = self.HW_NAME
        # a service response goes back with the request's transfer ID and priority
        self.send(r, GET_NODE_INFO_DTID, self.kernel.now_ns + 1_000_000_000,
                  priority=tr.priority, dest=tr.source, transfer_id=tr.transfer_id)

    # -- dynamic node-ID allocation (client) -------------------------------------------------

    def _schedule_request(self, now_ns: int) -> None:
        delay_ms = int(self.rng.integers(MIN_REQUEST_PERIOD_MS, MAX_REQUEST_PERIOD_MS + 1))
        self.kernel.cancel(self._dna_event)
        self._dna_event = self.kernel.call_at(now_ns + delay_ms * NS_PER_MS, self._request,
                                              priority=PRIO_HW)

    def _request(self) -> None:
        """First stage (or a restart): the first 6 bytes of the unique ID."""
        self._dna_event = None
        if self.node_id != 0:
            return
        self._dna_stage = 0
        self._send_allocation(True, self.unique_id[:UID_PART])
        self._schedule_request(self.kernel.now_ns)

    def _followup(self, part: bytes) -> None:
        self._dna_event = None
        if self.node_id != 0:
            return
        self._send_allocation(False, part)
        self._schedule_request(self.kernel.now_ns)

    def _send_allocation(self, first: bool, part: bytes) -> None:
        a = types().uavcan.protocol.dynamic_node_id.Allocation(
            node_id=self.configured_id, first_part_of_unique_id=first, unique_id=list(part))
        # anonymous transfers use the lowest priority; the deadline is the request period
        self.send(a, ALLOCATION_DTID, self.kernel.now_ns + MIN_REQUEST_PERIOD_MS * NS_PER_MS,
                  priority=PRIORITY_LOWEST)

    def _on_allocation(self, tr: RxTransfer) -> None:
        if self.node_id != 0:
            return
        got = bytes(tr.payload.unique_id)
        if not got or self.unique_id[:len(got)] != got:
            # the allocator is serving another node: drop any follow-up and start over later
            # (the spec's rule, so that two nodes' parts never interleave)
            self._dna_stage = 0
            self._schedule_request(self.kernel.now_ns)
            return
        new_id = int(tr.payload.node_id)
        if len(got) == len(self.unique_id) and new_id != 0:
            self.kernel.cancel(self._dna_event)
            self._dna_event = None
            self.node_id = new_id
            self.rxa.node_id = new_id
            self.kernel.call_at(self.kernel.now_ns, self._ready, priority=PRIO_HW)
            return
        self._dna_stage = len(got)
        delay_ms = int(self.rng.integers(0, MAX_FOLLOWUP_DELAY_MS + 1))
        self.kernel.cancel(self._dna_event)
        self._dna_event = self.kernel.call_at(
            self.kernel.now_ns + delay_ms * NS_PER_MS, self._followup,
            self.unique_id[len(got):len(got) + UID_PART], priority=PRIO_HW)

    def _ready(self) -> None:
        if self.allocated_at_ns is None:
            self.allocated_at_ns = self.kernel.now_ns
            self._on_ready()

    # -- for subclasses and faults ---------------------------------------------------------

    def _on_ready(self) -> None:
        """The node has its ID: start the application's publications."""

    def _on_transfer(self, tr: RxTransfer) -> None:
        """A transfer the base node does not handle (ESC commands, parameters, ...)."""

    def set_silent(self, silent: bool = True) -> None:
        """The node stops talking (off the bus: no frames, no ACKs) or comes back."""
        self.silent = bool(silent)
        if self.silent:
            self.txq.clear()
            self.ctrl.disable()
        else:
            self.ctrl.enable()

    def stats(self) -> dict[str, Any]:
        c = self.ctrl
        return {"state": c.state, "tec": c.tec, "rec": c.rec, "bus_off_count": c.bus_off_count,
                "node_id": self.node_id, "silent": self.silent, "name": self.HW_NAME,
                "node_status_tx": self.node_status_tx, "node_status_rx": self.node_status_rx,
                "tx_timeouts": self.txq.tx_timeouts, "transfers_tx": self.txq.transfers_tx,
                "node_info_requests": self.node_info_requests,
                "rx_errors": dict(self.rxa.errors),
                "heard": {k: v[0] for k, v in self.heard.items()}}
