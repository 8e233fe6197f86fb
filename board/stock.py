"""Small boards for tests, benchmarks and the demo: an empty chip and a UART probe.

They are real boards (kernel, ports, endpoint), so everything that runs them in lockstep is
exercised exactly as with the FMU and the IO.
"""

from __future__ import annotations

from typing import Any

from board.board import Board
from board.uart import Uart, UartConfig


class EmptyBoard(Board):
    """A chip with nothing on it but an optional heartbeat timer (measures lockstep cost)."""

    def __init__(self, name: str = "empty", seed: int = 0, tick_us: int = 0) -> None:
        super().__init__(name, seed)
        self.ticks = 0
        if tick_us:
            self.kernel.call_every(tick_us * 1000, self._tick)

    def _tick(self) -> None:
        self.ticks += 1

    def ctl_ticks(self) -> int:
        return self.ticks


class UartProbeBoard(Board):
    """One UART exposed as port ``uart``: writes scheduled bytes, records what arrives.

    ``sends`` is a list of ``(t_ns, data)`` to write; arrivals are recorded per byte as
    ``(t_ns, byte)`` through the RX interrupt, so a test sees exact arrival times.
    """

    def __init__(self, name: str = "probe", seed: int = 0, baud: int = 1_500_000,
                 sends: list[tuple[int, bytes]] | None = None, parity: str = "N",
                 stop_bits: int = 1, invert: bool = False, pwm_port: bool = False) -> None:
        super().__init__(name, seed)
        cfg = UartConfig(baud=baud, data_bits=8, parity=parity, stop_bits=stop_bits,
                         invert=invert)
        self.uart = Uart(self.kernel, f"{name}.uart", cfg)
        self.expose_uart("uart", self.uart)
        self.received: list[tuple[int, int]] = []
        self.uart.on_rx(lambda t_ns, byte, flags: self.received.append((t_ns, byte)))
        for t_ns, data in sends or []:
            self.kernel.call_at(t_ns, self.uart.write, bytes(data))
        self._out: Any = None

    def ctl_received(self) -> list[tuple[int, int]]:
        return self.received

    def ctl_write(self, data: bytes) -> int:
        return self.uart.write(data)

