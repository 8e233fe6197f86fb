"""The FMU's dynamic node-ID allocation server (``uavcan.protocol.dynamic_node_id.Allocation``,
PX4's ``UAVCAN_ENABLE`` >= 2), the centralised allocator of the DroneCAN specification.

A node with no ID sends anonymous requests carrying its 16-byte unique ID in up to three parts
(6 + 6 + 4 bytes). The server answers each part with the unique ID received so far (node ID 0);
a follow-up later than 500 ms after the previous part (``FOLLOWUP_TIMEOUT_MS``), or a
continuation with no first part, starts over. When all 16 bytes are in, it answers with a node
ID: the one this unique ID had before (the allocation table), else the requested ID if free,
else the first free ID searching up from it and then down (with no request: from 125 down, as
libuavcan's allocator does). IDs are free unless taken by the FMU itself, by an allocation, or
by a node heard on the bus.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Final

__all__ = ["Allocator"]

FOLLOWUP_TIMEOUT_US: Final = 500_000
UID_LEN: Final = 16
MAX_NODE_ID: Final = 125


class Allocator:
    """Server state: ``handle(first, uid_part, requested_id, now_us)`` returns the answer to
    send, ``(node_id, uid so far)``, or None to stay quiet."""

    def __init__(self, own_id: int, occupied: Callable[[], set[int]]) -> None:
        self.own_id = own_id
        self._occupied = occupied
        self.table: dict[bytes, int] = {}
        self._uid = b""
        self._requested = 0
        self._last_us = 0
        self.requests = 0
        self.allocations = 0
        self.restarts = 0

    def handle(self, first: bool, part: bytes, requested_id: int,
               now_us: int) -> tuple[int, bytes] | None:
        self.requests += 1
        if first:
            if not part or len(part) > 6:
                return None
            self._uid = part
            self._requested = requested_id
        else:
            if not self._uid or now_us - self._last_us > FOLLOWUP_TIMEOUT_US:
                self._uid = b""
                self.restarts += 1
                return None
            self._uid = (self._uid + part)[:UID_LEN]
        self._last_us = now_us
        if len(self._uid) < UID_LEN:
            return 0, self._uid
        uid = self._uid
        self._uid = b""
        node_id = self.table.get(uid)
        if node_id is None:
            node_id = self._free_id(self._requested)
            if node_id is None:
                return None  # the network is full: no answer, the node keeps asking
            self.table[uid] = node_id
        self.allocations += 1
        return node_id, uid

    def _free_id(self, preferred: int) -> int | None:
        taken = self._occupied() | set(self.table.values()) | {self.own_id}
        start = preferred if 1 <= preferred <= MAX_NODE_ID else MAX_NODE_ID
        for n in range(start, MAX_NODE_ID + 1):
            if n not in taken:
                return n
        for n in range(start - 1, 0, -1):
            if n not in taken:
                return n
        return None
