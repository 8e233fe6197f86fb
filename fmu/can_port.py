"""The host's CAN adapter on an emulated bus: outside tools join the bus as one node.

A python-can tool (``can.logger``, a ``dronecan`` node, a real bus bound with ``hil fly
--can``) lives outside the board process, so its frames cross the lockstep boundary as records
on a ``can`` port, like UART bytes do. On the board side this is one
:class:`~board.can.CanController` (a USB-CAN adapter plugged into the connector): it takes part
in arbitration, ACKs every frame and counts errors as any node does, so what the firmware sees
is exactly a bus with one more node. It starts in initialisation mode (off the bus, no ACKs)
and joins only while a tool is attached (``<port>_host`` record ``True``), so an emulator with
nobody attached behaves as a board with nothing plugged in.

Records (plain data, see :mod:`board.board`):

* ``<port>`` out: ``(arbitration_id, is_extended, is_remote, data, tag)`` at the frame's end
  of EOF. ``tag`` 0: a frame another node sent; ``tag`` > 0: the host's own frame with that
  tag went out (its transmit confirmation, which the host side uses to hand the frame to the
  other attached tools at its wire time).
* ``<port>`` in: the same tuple, a frame to send (tag > 0 chosen by the host side).
* ``<port>_host`` in: ``True`` when a tool attaches, ``False`` when the last one leaves.

Frames are sent in the order they arrive (one mailbox at a time, as SocketCAN and slcan
adapters do), queued up to ``TX_QUEUE_MAX``; beyond that, and for a tuple that is not a classic
CAN frame, the record is counted (``dropped``, ``rejected``) and dropped.
"""

from __future__ import annotations

from collections import deque
from typing import TYPE_CHECKING, Any

import can

from board.can import CanBus, CanController, check_frame

if TYPE_CHECKING:
    from board.board import Board

__all__ = ["CanHostPort", "TX_QUEUE_MAX"]

#: Frames waiting to be sent; a tool sending faster than the bus carries loses the excess.
TX_QUEUE_MAX = 1024


class CanHostPort:
    """A CAN adapter node on ``bus`` whose frames come from and go to the ``port`` records."""

    def __init__(self, board: Board, bus: CanBus, port: str) -> None:
        self.board = board
        self.bus = bus
        self.port = port
        # depth 64: the ISR below drains it at once, so it never overruns in practice
        self.ctrl = CanController(bus, f"{board.name}.{bus.name}.host", rx_fifo_depth=64,
                                  auto_recovery=True, enabled=False)
        self.ctrl.on_receive(self._rx)
        self.ctrl.on_tx_complete(self._tx_done)
        self._queue: deque[tuple[can.Message, int]] = deque()
        self._in_mailbox: can.Message | None = None
        self._tag = 0
        #: Frames from the host that were not classic CAN frames, and ones beyond the queue.
        self.rejected = 0
        self.dropped = 0
        self.sent = 0
        self.received = 0
        board._add_port(port, "can", "inout")
        board._inputs[port] = self._from_host
        board.expose_input(f"{port}_host", self._attach)

    # -- records from the host -------------------------------------------------------------------

    def _attach(self, t_ns: int, attached: Any) -> None:
        if attached:
            self.ctrl.enable()
            self._pump()
        else:
            self.ctrl.abort()
            self.ctrl.disable()
            self._queue.clear()
            self._in_mailbox = None

    def _from_host(self, t_ns: int, payload: Any) -> None:
        try:
            aid, ext, rtr, data, tag = payload
            if rtr:
                msg = can.Message(arbitration_id=int(aid), is_extended_id=bool(ext),
                                  is_remote_frame=True, dlc=len(data))
            else:
                msg = can.Message(arbitration_id=int(aid), is_extended_id=bool(ext),
                                  data=bytes(data))
            check_frame(msg, f"{self.port} from host")
            tag = int(tag)
        except (TypeError, ValueError):
            self.rejected += 1
            return
        if len(self._queue) >= TX_QUEUE_MAX:
            self.dropped += 1
            return
        self._queue.append((msg, tag))
        self._pump()

    def _pump(self) -> None:
        if self._in_mailbox is not None or not self._queue or not self.ctrl.enabled:
            return
        msg, tag = self._queue.popleft()
        if self.ctrl.send(msg):
            self._in_mailbox = msg
            self._tag = tag

    # -- interrupts of the adapter's controller -------------------------------------------------

    def _rx(self, t_ns: int) -> None:
        ctrl = self.ctrl
        while (m := ctrl.recv()) is not None:
            self.received += 1
            # a remote frame carries its DLC as that many zero bytes
            data = bytes(m.dlc) if m.is_remote_frame else bytes(m.data)
            self.board.emit(self.port, t_ns,
                            (m.arbitration_id, m.is_extended_id, m.is_remote_frame, data, 0))

    def _tx_done(self, t_ns: int, msg: can.Message, ok: bool) -> None:
        if msg is not self._in_mailbox:
            return
        self._in_mailbox = None
        if ok:
            self.sent += 1
            data = bytes(msg.dlc) if msg.is_remote_frame else bytes(msg.data)
            self.board.emit(self.port, t_ns, (msg.arbitration_id, msg.is_extended_id,
                                              msg.is_remote_frame, data, self._tag))
        self._pump()

    def stats(self) -> dict[str, Any]:
        c = self.ctrl
        return {"attached": c.enabled, "state": c.state, "tec": c.tec, "rec": c.rec,
                "sent": self.sent, "received": self.received, "queued": len(self._queue),
                "rejected": self.rejected, "dropped": self.dropped}
