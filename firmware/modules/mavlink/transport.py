"""Where a MAVLink instance's bytes go: a board UART, or a UDP port carried by the board.

The firmware never opens a socket. A UART instance reads and writes the emulated USART (its
bytes then take their real wire time at the configured baud rate). A UDP instance exchanges
whole datagrams with the board's network "value" ports (``udp_in``/``udp_out``); the host side
(:mod:`hil.mavlink_bridge`, :mod:`hil.gcs`) owns the real sockets, as PX4 SITL's network stack
is the host's.

The board contract for UDP (see docs/mavlink.md) is two attributes of the board object that the
System carries as ``system.hw``:

* ``udp_handlers: dict[int, Callable[[int, int, bytes], None]]`` - the board calls
  ``handler(t_ns, remote_port, data)`` for a datagram addressed to that FMU port;
* ``udp_out(t_ns, (fmu_port, remote_port, data))`` - emits a datagram on ``udp_out``.
"""

from __future__ import annotations

from collections import deque
from typing import Any, Final

from mypy_extensions import mypyc_attr

__all__ = ["Transport", "TransportError", "UartTransport", "UdpTransport"]

#: what PX4's serial driver buffers for transmission; a message that does not fit is dropped
UART_TX_BUFFER: Final = 1024
#: datagrams queued for the receiver between two runs before new ones are dropped (the
#: socket buffer of the network stack)
UDP_RX_QUEUE: Final = 64


@mypyc_attr(native_class=False)
class TransportError(ValueError):
    """The device or port named on the command line does not exist on this board."""


class Transport:
    """A byte pipe with back-pressure: ``read`` at most n bytes, ``room`` before ``write``."""

    kind = "generic"
    #: telemetry_status.type
    link_type = 0

    def read(self, max_bytes: int) -> bytes:
        raise NotImplementedError

    def room(self) -> int:
        """Bytes that can be written now without being dropped."""
        raise NotImplementedError

    def write(self, data: bytes) -> None:
        raise NotImplementedError

    def close(self) -> None:
        """Release the device (the instance stops)."""

    def describe(self) -> str:
        return self.kind


class UartTransport(Transport):
    """A USART of the board at a given baud rate (8N1), PX4's ``-d /dev/ttySn -b BAUD``."""

    kind = "serial"
    link_type = 1

    def __init__(self, uart: Any, device: str, baud: int) -> None:
        from board.uart import UartConfig

        self.uart = uart
        self.device = device
        self.baud = baud
        uart.config = UartConfig(baud=baud)
        self.rx_overruns_at_start = uart.overruns

    def read(self, max_bytes: int) -> bytes:
        return self.uart.read(max_bytes)

    def room(self) -> int:
        return UART_TX_BUFFER - self.uart.tx_pending

    def write(self, data: bytes) -> None:
        self.uart.write(data)

    @property
    def rx_lost(self) -> int:
        """Bytes lost to receive-buffer overruns (a flood faster than the instance reads)."""
        return self.uart.overruns - self.rx_overruns_at_start

    def describe(self) -> str:
        return f"serial {self.device} @ {self.baud} baud"


class UdpTransport(Transport):
    """A UDP port of the FMU's network: ``-u LOCAL -o REMOTE``.

    PX4 answers the peer that last talked to it; here the host bridge does the addressing, and
    the remote port travels with each datagram so the bridge knows where to send before any
    client has spoken.
    """

    kind = "udp"
    link_type = 2

    def __init__(self, hw: Any, kernel: Any, local_port: int, remote_port: int) -> None:
        handlers = getattr(hw, "udp_handlers", None)
        emit = getattr(hw, "udp_out", None)
        if handlers is None or emit is None:
            raise TransportError("this board has no UDP network ports (udp_in/udp_out)")
        if local_port in handlers:
            raise TransportError(f"UDP port {local_port} already in use")
        self.hw = hw
        self.kernel = kernel
        self.local_port = local_port
        self.remote_port = remote_port
        self._emit = emit
        self._rx: deque[bytes] = deque()
        self._partial = b""
        self.rx_datagrams = 0
        self.rx_lost = 0
        handlers[local_port] = self._on_datagram

    def _on_datagram(self, t_ns: int, remote_port: int, data: bytes) -> None:
        self.rx_datagrams += 1
        if len(self._rx) >= UDP_RX_QUEUE:
            self.rx_lost += 1
            return
        if remote_port:
            self.remote_port = remote_port
        self._rx.append(bytes(data))

    def read(self, max_bytes: int) -> bytes:
        out = bytearray(self._partial)
        self._partial = b""
        while self._rx and len(out) < max_bytes:
            out += self._rx.popleft()
        if len(out) > max_bytes:
            self._partial = bytes(out[max_bytes:])
            del out[max_bytes:]
        return bytes(out)

    def room(self) -> int:
        return 1 << 30

    def write(self, data: bytes) -> None:
        k = self.kernel
        self._emit(k.now_ns + k.busy_ns, (self.local_port, self.remote_port, bytes(data)))

    def close(self) -> None:
        handlers = getattr(self.hw, "udp_handlers", {})
        if handlers.get(self.local_port) == self._on_datagram:
            del handlers[self.local_port]

    def describe(self) -> str:
        return f"udp local port {self.local_port}, remote port {self.remote_port}"
