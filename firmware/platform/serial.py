"""Serial ports as device files: what a task gets from ``open("/dev/ttyS2")`` on NuttX.

A :class:`SerialPort` wraps one board USART (:class:`board.uart.Uart`) the way NuttX's serial
driver does: ``read``/``write`` with a bounded transmit buffer, ``set_baud`` (termios), and
``poll()`` readiness, so a task can wait on serial ports and uORB topics together in one
``task.poll([sub, port], timeout_ms)`` (:mod:`firmware.platform.task`). That is the point of
PX4's design: a topic handle behaves as a file, and a file behaves as a topic handle.

When a port becomes readable. The STM32F4's USARTs on PX4 receive by DMA into a small
circular ring; the driver learns about bytes from the ring's half- and full-transfer interrupts
and from the IDLE-line interrupt, never per byte. So here a waiting poller is woken

* when the RX line goes idle after a burst (one character time after its last byte:
  :meth:`board.uart.Uart.on_idle`), or
* when half of the :data:`RX_DMA_RING_BYTES`-byte ring has filled (every
  :data:`RX_DMA_HALF_BYTES` bytes of a long stream: :meth:`board.uart.Uart.on_rx_dma`),

whichever comes first. A stream at 921600 baud (92 160 bytes/s) thus costs at most one kernel
event per 32 bytes (2 880 a second, 347 us apart) plus one per burst, whatever reads it, and
a poller sees new bytes at most 32 byte times late while the line is busy. 64 bytes is the
order of NuttX's ``CONFIG_STM32_SERIAL_RXDMA_BUFFER_SIZE`` on PX4's F4 boards.

A port's readiness is ``in_waiting > 0`` (``updated()``), so poll() returns at once when bytes
are already waiting, as POLLIN does.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable, Final
from weakref import WeakKeyDictionary

from board.uart import Uart, UartConfig
from firmware.platform.module import ModuleError

if TYPE_CHECKING:
    from firmware.platform import Platform

__all__ = ["RX_DMA_HALF_BYTES", "RX_DMA_RING_BYTES", "SERIAL_TX_BUFFER", "PortNode",
           "SerialError", "SerialPort", "open_serial"]

#: bytes of the RX DMA ring; a poller wakes when half of it has filled
RX_DMA_RING_BYTES: Final = 64
RX_DMA_HALF_BYTES: Final = RX_DMA_RING_BYTES // 2
#: NuttX's serial TX buffer (PX4's mavlink sizes its messages against the same figure): bytes
#: beyond it are refused by ``write`` and counted in ``tx_dropped``
SERIAL_TX_BUFFER: Final = 1024

#: open ports per platform, by UART, so one USART has one owner of its interrupts
_OPEN: WeakKeyDictionary[Any, dict[int, SerialPort]] = WeakKeyDictionary()


class SerialError(ModuleError):
    """Bad use of a serial device: no such device, already open, closed, bad baud rate."""


class PortNode:
    """A port's poll list: the same shape as a uORB topic node's (``callbacks``), so that
    :class:`~firmware.platform.task.PollWaiter` registers on a port as on a topic."""

    __slots__ = ("callbacks",)

    def __init__(self) -> None:
        self.callbacks: list[Callable[[], None]] = []


class SerialPort:
    """A device file over a board UART (8N1 at ``baud``).

    ``read``/``write``/``in_waiting`` as pyserial names them; ``updated()`` is poll()'s
    readiness; ``rx_lost`` counts bytes the UART dropped because the port was read too late.
    """

    def __init__(self, platform: Platform, uart: Uart, device: str, baud: int) -> None:
        self.platform = platform
        self.uart = uart
        self.device = device
        self.node = PortNode()
        self.tx_dropped = 0
        self.wakes = 0
        self.closed = False
        ports = _OPEN.setdefault(platform, {})
        other = ports.get(id(uart))
        if other is not None:
            raise SerialError(f"{device}: already open (as {other.device})")
        self.baud = 0
        self.set_baud(baud)
        ports[id(uart)] = self
        self._rx_overruns_at_open = uart.overruns
        uart.on_idle(self._on_rx_event)
        uart.on_rx_dma(RX_DMA_HALF_BYTES, self._on_rx_event)

    # -- file operations ---------------------------------------------------------------------

    def _check_open(self, what: str) -> None:
        if self.closed:
            raise SerialError(f"{self.device}: {what} on a closed port")

    def read(self, max_bytes: int = -1) -> bytes:
        """Bytes arrived by now, oldest first, at most ``max_bytes`` (all if < 0)."""
        self._check_open("read")
        return self.uart.read(max_bytes)

    def write(self, data: bytes | bytearray | memoryview) -> int:
        """Queue ``data`` for sending; returns the bytes accepted. What does not fit in the
        TX buffer (:meth:`room`) is dropped and counted in ``tx_dropped``, as a non-blocking
        write to a full NuttX serial buffer."""
        self._check_open("write")
        n = len(data)
        room = self.room()
        if n > room:
            self.tx_dropped += n - room
            data = bytes(data[:room])
        return self.uart.write(data) if room > 0 else 0

    def room(self) -> int:
        """Bytes that can be written now without being dropped."""
        self._check_open("room")
        return max(0, SERIAL_TX_BUFFER - self.uart.tx_pending)

    @property
    def in_waiting(self) -> int:
        self._check_open("in_waiting")
        return self.uart.in_waiting

    def set_baud(self, baud: int) -> None:
        """Reprogram the USART (8N1) for bytes written or received from now on."""
        self._check_open("set_baud")
        if type(baud) is not int or baud <= 0:
            raise SerialError(f"{self.device}: bad baud rate {baud!r}")
        self.uart.config = UartConfig(baud=baud)
        self.baud = baud

    @property
    def rx_lost(self) -> int:
        """Bytes lost to receive-buffer overruns since the port was opened."""
        return self.uart.overruns - self._rx_overruns_at_open

    def updated(self) -> bool:
        """Readable: bytes are waiting (poll()'s POLLIN). False once closed: a poller that
        was waiting when the port closed wakes for its other items or its timeout."""
        return not self.closed and self.uart.in_waiting > 0

    def close(self) -> None:
        """Release the UART's interrupts; later use of the port raises :class:`SerialError`.
        A poller still waiting on the port keeps waiting for its other items or timeout."""
        if self.closed:
            return
        self.closed = True
        self.uart.on_idle(None)
        self.uart.on_rx_dma(0, None)
        ports = _OPEN.get(self.platform)
        if ports is not None and ports.get(id(self.uart)) is self:
            del ports[id(self.uart)]

    # -- interrupts ----------------------------------------------------------------------------

    def _on_rx_event(self, t_ns: int) -> None:
        """IDLE or DMA half/full transfer: wake the pollers if bytes are waiting."""
        cbs = self.node.callbacks
        if cbs and self.uart.in_waiting > 0:
            self.wakes += 1
            for cb in cbs:
                cb()

    def __repr__(self) -> str:
        state = "closed" if self.closed else f"{self.baud} baud"
        return f"<SerialPort {self.device} {state}>"


#: UART roles the board's own firmware holds: opening one would take a console's or a link's
#: bytes from its owner (binary frames on nsh's console lock the shell out)
RESERVED_ROLES: dict[str, str] = {"console": "nsh console", "io_link": "link to the IO"}


def open_serial(system: Any, device: str, baud: int) -> SerialPort:
    """Open ``device`` (``/dev/ttyS2``) of the system's board at ``baud``: the UART comes from
    ``system.hw.uart_by_device``; a board without it raises :class:`SerialError`."""
    hw = getattr(system, "hw", None)
    uart = hw.uart_by_device(device) if hw is not None else None
    if uart is None:
        raise SerialError(f"no serial device {device} on this board")
    spec = getattr(system, "board", None)
    for u in getattr(spec, "uarts", ()):
        if u.device == device and u.role in RESERVED_ROLES:
            raise SerialError(f"{device} is the board's {RESERVED_ROLES[u.role]}, not free "
                              "for a serial module")
    return SerialPort(system.platform, uart, device, baud)
