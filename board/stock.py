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


class LinkDemoFmu(Board):
    """Stand-in FMU for the demo: reads truth, sends a 68-byte frame to the IO every 2.5 ms."""

    def __init__(self, name: str = "fmu", seed: int = 0) -> None:
        super().__init__(name, seed)
        self.uart = Uart(self.kernel, "USART6", UartConfig(baud=1_500_000))
        self.expose_uart("io_link", self.uart)
        self.expose_input("truth", self._truth)
        self.truth_samples = 0
        self.last_truth: tuple = ()
        self.frames_sent = 0
        self.replies = 0
        self.kernel.call_every(2_500_000, self._send)

    def _truth(self, t_ns: int, record: Any) -> None:
        self.truth_samples += 1
        self.last_truth = record

    def _send(self) -> None:
        self.replies += len(self.uart.read()) // 4
        seq = self.frames_sent & 0xFF
        self.uart.write(bytes([0x40 | 32, seq, 54, 0]) + bytes(64))
        self.frames_sent += 1

    def ctl_stats(self) -> dict[str, Any]:
        return {"truth_samples": self.truth_samples, "frames_sent": self.frames_sent,
                "replies": self.replies, "last_truth": self.last_truth}


class LinkDemoIo(Board):
    """Stand-in IO for the demo: answers every frame (on IDLE) and drives four PWM outputs
    at 1000 us (motors stopped)."""

    def __init__(self, name: str = "io", seed: int = 0) -> None:
        super().__init__(name, seed)
        self.uart = Uart(self.kernel, "USART2", UartConfig(baud=1_500_000))
        self.expose_uart("fmu_link", self.uart)
        self.uart.on_idle(self._idle)
        self.frames = 0
        emits = [self.expose_output(f"pwm{i}", "pwm") for i in range(1, 5)]
        for emit in emits:
            self.kernel.call_at(0, emit, 0, (1_000_000, 2_500_000))

    def _idle(self, t_ns: int) -> None:
        frame = self.uart.read()
        if frame:
            self.frames += 1
            self.uart.write(bytes([0x00, frame[1], 54, 0]))

    def ctl_stats(self) -> dict[str, Any]:
        return {"frames_answered": self.frames, "bytes_received": self.uart.rx_bytes}
