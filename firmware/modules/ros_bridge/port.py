"""The companion board's "ros" port: uORB messages in and out of the board as plain records.

On a real companion computer the ROS side is another process on the same Linux machine (a ROS 1
node speaking TCPROS); here it is the host edge (``hil/ros/``), outside the lockstep. Between the
two only plain data crosses, as over every other port: a record ``(topic, instance, payload)``
whose payload is the uORB message's packed bytes (``msg.pack()``, the layout
``firmware/msg/*.msg`` defines, the same bytes the uorb_bridge frames carry). The board owns a
:class:`RosPort`; the ``ros_bridge`` module (firmware, deterministic) decides what goes out and
validates what comes in.

:func:`expose_ros_port` is the board's one line: a value port ``"ros"`` in both directions,
whose inputs are queued here (bounded: beyond :data:`INBOX_MAX` the oldest are dropped and
counted, as a full socket buffer would) and wake whoever listens.
"""

from __future__ import annotations

from collections import deque
from typing import TYPE_CHECKING, Any, Callable, Final

if TYPE_CHECKING:
    from board.board import Board

__all__ = ["INBOX_MAX", "PORT_NAME", "RosPort", "expose_ros_port"]

#: the port's name on the companion board (and on the host edge's side of the wire)
PORT_NAME: Final = "ros"
#: records held for the module between two of its runs (a run drains them all)
INBOX_MAX: Final = 512


class RosPort:
    """A board's ROS value port: an inbox of raw records and the emitter of outgoing ones."""

    def __init__(self, emit: Callable[[int, Any], None] | None = None) -> None:
        self._emit = emit
        self.inbox: deque[tuple[int, Any]] = deque()
        #: called (no arguments) when a record arrives: the module's work item scheduler
        self.listener: Callable[[], None] | None = None
        self.records_in = 0
        self.records_out = 0
        self.overflow = 0

    def deliver(self, t_ns: int, payload: Any) -> None:
        """A record from the wire (the board's input handler): queued as is, validated by the
        module that reads it."""
        self.records_in += 1
        if len(self.inbox) >= INBOX_MAX:
            self.inbox.popleft()
            self.overflow += 1
        self.inbox.append((t_ns, payload))
        cb = self.listener
        if cb is not None:
            cb()

    def send(self, t_ns: int, topic: str, instance: int, payload: bytes) -> None:
        """Put ``(topic, instance, payload)`` on the wire at ``t_ns`` (dropped when the port is
        not wired to anything, as bytes to a closed socket)."""
        emit = self._emit
        if emit is None:
            return
        self.records_out += 1
        emit(t_ns, (topic, instance, payload))

    def take(self) -> list[tuple[int, Any]]:
        """Every queued record, oldest first; the inbox is empty afterwards."""
        out = list(self.inbox)
        self.inbox.clear()
        return out


def expose_ros_port(board: Board, name: str = PORT_NAME) -> RosPort:
    """Expose ``name`` on ``board`` as a value port in both directions and return its
    :class:`RosPort` (the board keeps it as ``ros_port``, where ``ros_bridge`` finds it)."""
    board._add_port(name, "value", "inout")
    port = RosPort(lambda t_ns, payload: board.emit(name, t_ns, payload))
    board._inputs[name] = port.deliver
    return port
