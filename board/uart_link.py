"""Links: what sits between a UART's TX pin and another UART's RX pin.

A link is any object with ``transmit(t_start_ns, config, data)``; it is the only thing between
two boards. In one process :func:`connect` and :class:`UartWire` deliver straight to the peer's
``Uart.receive``; a process boundary records bursts (as :class:`RecordingLink` does) and
replays them on the other side, up to one lockstep quantum late.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

from board.uart_line import LineBreak, UartConfig

if TYPE_CHECKING:
    from board.uart import Uart

__all__ = ["DirectLink", "RecordingLink", "UartLink", "UartWire", "connect"]


class UartLink(Protocol):
    """What a transmitter needs from a wire: take one burst."""

    def transmit(self, t_start_ns: int, config: UartConfig, data: bytes | LineBreak) -> None:
        ...


class DirectLink:
    """One-way in-process wire: hands bursts straight to the receiving :class:`Uart`."""

    __slots__ = ("rx",)

    def __init__(self, rx: Uart) -> None:
        self.rx = rx

    def transmit(self, t_start_ns: int, config: UartConfig, data: bytes | LineBreak) -> None:
        self.rx.receive(t_start_ns, config, data)


class RecordingLink:
    """Keeps bursts instead of delivering them: a tap for tests and the shape of what a
    process boundary ships (``(t_start_ns, config, data)`` tuples)."""

    def __init__(self) -> None:
        self.bursts: list[tuple[int, UartConfig, bytes | LineBreak]] = []

    def transmit(self, t_start_ns: int, config: UartConfig, data: bytes | LineBreak) -> None:
        self.bursts.append((t_start_ns, config, data))

    def take(self) -> list[tuple[int, UartConfig, bytes | LineBreak]]:
        """Return and forget the recorded bursts."""
        out, self.bursts = self.bursts, []
        return out


def connect(tx_uart: Uart, rx_uart: Uart) -> DirectLink:
    """Wire ``tx_uart``'s TX pin to ``rx_uart``'s RX pin (one direction)."""
    link = DirectLink(rx_uart)
    tx_uart.attach(link)
    return link


class UartWire:
    """Full-duplex in-process cable: a.TX -> b.RX and b.TX -> a.RX."""

    def __init__(self, a: Uart, b: Uart) -> None:
        self.a = a
        self.b = b
        connect(a, b)
        connect(b, a)

    def disconnect(self) -> None:
        """Unplug both directions (bytes written afterwards go nowhere)."""
        self.a.attach(None)
        self.b.attach(None)
