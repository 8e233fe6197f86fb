"""A DroneCAN transmit queue in front of a bxCAN controller's three mailboxes.

libuavcan keeps outgoing frames in a software queue with a deadline per transfer and feeds the
controller's mailboxes from it. Here one frame is in the mailboxes at a time: the frames of a
multi-frame transfer share one CAN ID, and bxCAN sends equal IDs in no defined order, so
keeping one in flight is what keeps their order (the cost, an interrupt's latency between
frames, is small beside a frame's 100+ bits). A transfer whose deadline passes before it is
out is dropped (``tx_timeouts``): the frame still in its mailbox is aborted, as libuavcan's
driver does, so a node alone on the bus (nobody ACKs) or on a faulty one holds at most one
transfer pending.
"""

from __future__ import annotations

from collections import deque
from typing import Any, Final

import can

__all__ = ["TxQueue"]

#: Transfers waiting at most; more are refused and counted (``tx_dropped``).
MAX_QUEUED: Final = 64


class _Tx:
    __slots__ = ("frames", "deadline_ns", "index")

    def __init__(self, frames: list[can.Message], deadline_ns: int) -> None:
        self.frames = frames
        self.deadline_ns = deadline_ns
        self.index = 0


class TxQueue:
    """Transfers queued for ``ctrl`` (a :class:`board.can.CanController`). The owner routes
    the controller's TX-complete interrupt to :meth:`tx_done`."""

    def __init__(self, ctrl: Any) -> None:
        self.ctrl = ctrl
        self._q: deque[_Tx] = deque()
        self._in_flight: can.Message | None = None
        self.transfers_tx = 0
        self.frames_tx = 0
        self.tx_timeouts = 0
        self.tx_dropped = 0

    def __len__(self) -> int:
        return len(self._q)

    def push(self, frames: list[can.Message], deadline_ns: int, now_ns: int) -> bool:
        """Queue one transfer's frames; False (counted) when the queue is full."""
        self.expire(now_ns)
        if len(self._q) >= MAX_QUEUED:
            self.tx_dropped += 1
            return False
        self._q.append(_Tx(frames, deadline_ns))
        self._pump()
        return True

    def expire(self, now_ns: int) -> None:
        """Drop the transfers whose deadline has passed (the one on its way is aborted)."""
        q = self._q
        while q and q[0].deadline_ns <= now_ns:
            q.popleft()
            self.tx_timeouts += 1
            if self._in_flight is not None:
                self.ctrl.abort()
                self._in_flight = None
        kept = [t for t in q if t.deadline_ns > now_ns]
        if len(kept) != len(q):
            self.tx_timeouts += len(q) - len(kept)
            self._q = deque(kept)
        self._pump()

    def tx_done(self, msg: can.Message, ok: bool) -> None:
        """The controller finished ``msg`` (ok: ACKed). A frame that failed without automatic
        retransmission ends its transfer."""
        if msg is not self._in_flight:
            return  # an aborted frame that was already on the wire
        self._in_flight = None
        q = self._q
        if q:
            head = q[0]
            if ok:
                self.frames_tx += 1
                head.index += 1
                if head.index >= len(head.frames):
                    q.popleft()
                    self.transfers_tx += 1
            else:
                q.popleft()
        self._pump()

    def clear(self) -> None:
        self._q.clear()
        if self._in_flight is not None:
            self.ctrl.abort()
            self._in_flight = None

    def _pump(self) -> None:
        if self._in_flight is not None or not self._q:
            return
        head = self._q[0]
        msg = head.frames[head.index]
        if self.ctrl.send(msg):
            self._in_flight = msg
