"""The contracts between the layers, as typing protocols: what one side may use of the other.

The board packages meet at a few duck-typed seams; these protocols write each seam down, so
mypy checks both sides and a reader sees what a seam carries without reading its one
implementation:

* :class:`BoardHardware`: what a firmware :class:`firmware.system.System` sees of its board,
  ``system.hw`` (the buses, the pins, the ADC, the spec); driver modules build their drivers
  from it and a :class:`board.specs.DevicePlace`. :class:`fmu.board.FmuV2Board` is one.
* :class:`BoardHandle`: a board as the orchestrator drives it, quantum by quantum, in this
  process (:class:`board.endpoint.LocalHandle`) or in its own (``hil.boardproc.ProcessHandle``,
  ``OffsetHandle`` after a reboot).
* The port adapters :meth:`board.board.Board.expose_uart` and friends take: :class:`UartPort`,
  :class:`OutputPin`, :class:`InputPin`, :class:`PwmOutput`.

The world's side of the wires (the JSBSim world's ports and the hub that shares the role with
the RC transmitter and the ground station) is ``hil.devices.HostDevice``.

Protocols are erased at run time: nothing here is checked with ``isinstance`` and nothing on a
hot path costs more for them (mypyc compiles a protocol-typed argument as a plain object). The
compiled modules import this one under ``TYPE_CHECKING`` only.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from board.adc import Adc
    from board.gpio import Gpio, Pin
    from board.i2c import I2cBus
    from board.spi import SpiHandle
    from board.specs import BoardSpecData
    from board.uart import LineBreak, Uart, UartConfig, UartLink

__all__ = ["BoardHandle", "BoardHardware", "InputPin", "OutputPin", "PwmOutput", "Record",
           "UartPort"]

#: one record on a wire: (port, time stamp in ns, payload)
Record = tuple[str, int, Any]


class BoardHardware(Protocol):
    """The hardware a firmware system sees (``system.hw``): what drivers are built from.

    Read-only: firmware takes handles from it and never rewires the board. Facilities only
    some boards have (the FMU's PWM ``timers``, ``can``/``can_ctrl``, the network port's
    ``udp_handlers``) stay outside this protocol; the modules that need one ask for it with
    ``getattr`` and say so when it is missing.
    """

    @property
    def spec(self) -> BoardSpecData:
        """The board's spec: where every device sits (``spec.place(name)``)."""
        ...

    @property
    def i2c(self) -> Mapping[str, I2cBus]:
        """I2C controllers by bus name (``"I2C1"``); ``.device(addr)`` is a driver's handle."""
        ...

    @property
    def uarts(self) -> Mapping[str, Uart]:
        """USARTs by peripheral name (``"USART2"``)."""
        ...

    @property
    def gpio(self) -> Gpio:
        """The pins (``gpio.pin("PD15")``): data-ready lines, switches, LEDs."""
        ...

    @property
    def adc(self) -> Adc:
        ...

    def spi_handle(self, device: str) -> SpiHandle:
        """The SPI handle (chip select, mode, clock) of the spec's device ``device``."""
        ...

    def uart_by_device(self, device: str) -> Uart | None:
        """The UART behind a NuttX device name (``/dev/ttyS3``), or None."""
        ...


class BoardHandle(Protocol):
    """A board as the orchestrator drives it: advance a quantum, call a control hook."""

    name: str
    #: the board's ports: (name, kind, direction)
    ports: list[tuple[str, str, str]]
    #: False once the board has died or been closed (the orchestrator's ``kill`` sets it on a
    #: handle that cannot kill a process)
    alive: bool

    def post_advance(self, start_ns: int, until_ns: int, inputs: list[Record]) -> None:
        """Hand the board the quantum ``(start_ns, until_ns]`` and the records due in it."""
        ...

    def wait_advance(self) -> tuple[list[Record], int | None]:
        """The quantum's outputs and the board's next event time (None: nothing due);
        raises ``BoardDied`` if the board did not survive it."""
        ...

    def is_alive(self) -> bool:
        ...

    def call(self, method: str, *args: Any) -> Any:
        """A control hook of the board (``ctl_<method>``), between quanta."""
        ...

    def close(self, timeout_s: float = ...) -> None:
        ...


class UartPort(Protocol):
    """A UART as a port adapter sees it: one transmitter to attach, a receiver to feed."""

    def attach(self, link: UartLink | None) -> None:
        ...

    def receive(self, t_start_ns: int, tx_config: UartConfig,
                data: bytes | LineBreak) -> None:
        ...


class OutputPin(Protocol):
    """A pin whose level changes leave the board (``listener(pin, t_ns, level)``)."""

    def on_change(self, listener: Callable[[Pin, int, int], None]) -> None:
        ...


class InputPin(Protocol):
    """A pin driven from outside the board (a level, or released to its pull)."""

    def set(self, level: int, t_ns: int | None = None) -> None:
        ...

    def release(self, t_ns: int | None = None) -> None:
        ...


class PwmOutput(Protocol):
    """A timer channel's PWM output (``listener(t_ns, high_ns, period_ns)`` on a change)."""

    def on_pwm(self, listener: Callable[[int, int, int], None]) -> None:
        ...
