"""The IO end of the FMU link: USART2 with RX DMA framed by the IDLE interrupt (§1.5, §1.6).

What the real IO does: RX DMA is armed for the 68-byte packet buffer; the USART IDLE
interrupt (one character of mark after the last byte) ends a request; the length is checked
against the header, the packet processed *in the interrupt* and the reply started by TX DMA.
A UART error (overrun, noise, framing - a received break included) makes the IO send a line
break so the FMU aborts, and the next IDLE discards whatever was received.

Model decisions:

* The error interrupt (CR3.EIE) fires at the bad byte on the chip; here the sticky error flags
  are looked at when IDLE fires, so the answering break leaves up to one packet time later
  (<= 453 µs). The outcome on the FMU side (an aborted, retried transaction) is the same.
* Processing time: the reply's first start bit leaves ``REPLY_LATENCY_NS`` after IDLE
  (CRC-8 over <= 68 bytes plus the register access on a 24 MHz Cortex-M3; the reference says
  "tens of µs", not measured). It is charged as ``kernel.busy_ns`` so no extra event exists.
* A burst longer than the DMA buffer: the first 68 bytes complete the DMA and are processed
  (``handle_request``'s DMA-complete path), the rest lands in the re-armed buffer and is
  judged like any other reception.
"""

from __future__ import annotations

from typing import Final

from board.kernel import Kernel
from board.uart import FE, NF, ORE, Uart
from ioproc.protocol import PKT_MAX_SIZE, PageStore, handle_request

__all__ = ["REPLY_LATENCY_NS", "FmuLink"]

#: [model] IDLE interrupt -> first reply start bit.
REPLY_LATENCY_NS: Final = 20_000

_LINE_ERRORS: Final = ORE | NF | FE


class FmuLink:
    """Request/reply engine on USART2; counters mirror the IO's perf counters."""

    def __init__(self, kernel: Kernel, uart: Uart, store: PageStore) -> None:
        self.kernel = kernel
        self.uart = uart
        self.store = store
        self.packets = 0  #: requests processed (any reply)
        self.replies = 0
        self.bad_idle = 0  #: receptions shorter than their header announced (no reply)
        self.line_errors = 0  #: receptions dropped for ORE/NE/FE, answered with a break
        self.corrupt = 0  #: CORRUPT replies sent

    def start(self) -> None:
        """Arm the RX DMA on an empty buffer and enable the IDLE interrupt."""
        self.uart.reset_input_buffer()
        self.uart.take_errors()
        self.uart.on_idle(self._on_idle)

    def stop(self) -> None:
        self.uart.on_idle(None)

    def _on_idle(self, t_ns: int) -> None:
        uart = self.uart
        errors = uart.take_errors()
        data = uart.read()
        if errors & _LINE_ERRORS:
            self.line_errors += 1
            uart.send_break()  # abort the FMU's reception; this packet is discarded
            return
        now_us = t_ns // 1000
        for start in range(0, max(len(data), 1), PKT_MAX_SIZE):
            chunk = data[start:start + PKT_MAX_SIZE]
            reply = handle_request(chunk, self.store, now_us)
            if reply is None:
                self.bad_idle += 1
                continue
            self.packets += 1
            if reply[0] & 0xC0 == 0x40:
                self.corrupt += 1
            self.kernel.busy_ns += REPLY_LATENCY_NS
            uart.write(reply)
            self.replies += 1
