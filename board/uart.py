"""Emulated USART and the wires between USARTs.

A :class:`Uart` is one USART of a chip: a transmitter that turns ``write()`` calls into timed
bursts on its link, and a receiver with a buffer, STM32-like error flags and interrupts.

The seam between boards is the *link*: any object with
``transmit(t_start_ns, config, data)``. A transmitter calls it once per ``write()`` (or
``send_break()``, with ``data`` set to :data:`~board.uart_line.BREAK`), at write time, with the
start of the first start bit, which may lie in the future. In one process :func:`connect` and
:class:`UartWire` deliver straight to the peer's :meth:`Uart.receive`; across processes the
orchestrator carries the same three values and calls ``receive`` on the other side, possibly
late (see :meth:`Uart.receive`).

Speed: with no per-byte interrupt handler registered, the receiver schedules no per-byte
events. It keeps the bursts it was given and works out, when the firmware reads, which bytes
have arrived by then. That is exact because the buffer only drains on reads: between two reads
bytes are only added, in time order, and lost once it is full.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import Any, Final

from board.kernel import PRIO_ISR, Event, Kernel, call_in_isr
from board.uart_line import (
    BREAK,
    FE,
    LBD,
    NF,
    NS_PER_S,
    ORE,
    PE,
    LineBreak,
    LineDecoder,
    UartConfig,
)
from board.uart_link import DirectLink, RecordingLink, UartLink, UartWire, connect

__all__ = ["BREAK", "FE", "LBD", "NF", "ORE", "PE", "DirectLink", "RecordingLink", "Uart",
           "UartConfig", "UartLink", "UartWire", "connect"]

#: Runs after every other event of the same nanosecond, so that writes made in that instant
#: are known before the line decoder assumes the line went idle.
_PRIO_LAST: Final = 1 << 30

_MASK7: Final = bytes(b & 0x7F for b in range(256))

RxHandler = Callable[[int, int, int], Any]
TimeHandler = Callable[[int], Any]


class Uart:
    """One USART: timed transmitter, buffered receiver, STM32-like flags and interrupts.

    Receive buffer: ``rx_buffer_size`` bytes stand for whatever the firmware reads from (the DMA
    ring of PX4IO, NuttX's serial buffer). A byte arriving while it is full is lost: ORE is set
    and ``overruns`` counts the lost bytes.

    Error flags are sticky bits in STM32 ``USART_SR`` positions (:data:`PE`, :data:`FE`,
    :data:`ORE`, :data:`LBD`), set when the offending byte arrives; :meth:`take_errors` returns
    and clears them (like the SR-read-then-DR-read sequence). Counters (``overruns``,
    ``framing_errors``, ``parity_errors``, ``breaks``) only grow.

    Interrupts run as kernel events at ``PRIO_ISR`` with ``kernel.in_isr`` set:

    - ``on_rx(handler)``: RXNE, ``handler(t_ns, byte, flags)`` once per byte at its arrival.
      The handler *is* the data-register read: the byte is handed to it and not buffered.
      Registering it costs one kernel event per byte; leave it unset for DMA-style use.
    - ``on_idle(handler)``: IDLE, ``handler(t_ns)`` when the line has been at mark for one
      receiver character time (rounded up to a ns) after the last received byte; the firmware
      then ``read()``s the buffer. It fires once per idle period, and not at all while the line
      rests at space (inverted-line mismatch).
    - ``on_tx_complete(handler)``: TC, ``handler(t_ns)`` when the transmitter runs dry.
    - ``on_rx_dma(half_bytes, handler)``: the half- and full-transfer interrupts of a circular
      RX DMA ring of ``2 * half_bytes`` bytes, ``handler(t_ns)`` at the arrival of every
      ``half_bytes``-th buffered word of a burst: one kernel event per half ring, not per byte.

    A received break reads as 0x00 with FE and LBD (an STM32 outside LIN mode gives 0x00 + FE).
    Data words are bytes: a 9-bit line sends bit 8 as 0 and buffers words masked to 8 bits
    (``on_rx`` gets the full word); a 7-bit line drops bit 7.
    """

    def __init__(self, kernel: Kernel, name: str, config: UartConfig | None = None,
                 rx_buffer_size: int = 1024, tx_buffer_size: int | None = None) -> None:
        if type(rx_buffer_size) is not int or rx_buffer_size <= 0:
            raise ValueError(f"Uart {name}: rx_buffer_size must be an int > 0: {rx_buffer_size!r}")
        if tx_buffer_size is not None and (type(tx_buffer_size) is not int or tx_buffer_size <= 0):
            raise ValueError(f"Uart {name}: tx_buffer_size must be None or an int > 0: "
                             f"{tx_buffer_size!r}")
        self.kernel = kernel
        self.name = name
        self._config = self._check_config(config if config is not None else UartConfig())
        self.link: UartLink | None = None
        self.rx_buffer_size = rx_buffer_size
        self.tx_buffer_size = tx_buffer_size
        # transmitter
        self._tx_idle_ns = 0
        self._tx_bursts: deque[tuple[int, int, int, int, int]] = deque()  # t0, K, baud, n, end
        self._tc_handler: TimeHandler | None = None
        self._tc_event: Event | None = None
        self.tx_bytes = 0
        self.breaks_sent = 0
        # receiver
        self._buf = bytearray()
        self._pending: deque[list] = deque()
        self._decoder = LineDecoder()
        self._decode_event: Event | None = None
        self._rx_handler: RxHandler | None = None
        self._idle_handler: TimeHandler | None = None
        self._idle_event: Event | None = None
        self._last_rx_ns = 0
        self._idle_armed = False
        self._dma_handler: TimeHandler | None = None
        self._dma_half = 0
        self._dma_count = 0   # buffered words since registration, modulo _dma_half
        self._dma_gen = 0     # bumped per registration: older ring events are ignored
        self._flags = 0
        self.rx_bytes = 0
        self.overruns = 0
        self.framing_errors = 0
        self.parity_errors = 0
        self.breaks = 0
        #: A line fault on the RX pin (``board.uart_fault.LineNoise``): it sees each burst
        #: first and hands the surviving bytes to :meth:`receive_clean`.
        self.line_noise: Any = None

    # -- configuration --------------------------------------------------------------------------

    def _check_config(self, config: Any) -> UartConfig:
        if not isinstance(config, UartConfig):
            raise TypeError(f"Uart {self.name}: config must be a UartConfig, got {config!r}")
        return config

    @property
    def config(self) -> UartConfig:
        return self._config

    @config.setter
    def config(self, config: UartConfig) -> None:
        """Reprogramming the USART affects bursts received or written from now on."""
        self._config = self._check_config(config)

    def attach(self, link: UartLink | None) -> None:
        """Plug the TX pin into ``link`` (None: TX pin unconnected, bytes still take time)."""
        self.link = link

    # -- transmitter ----------------------------------------------------------------------------

    def write(self, data: bytes | bytearray | memoryview) -> int:
        """Queue bytes; they go out back to back after anything still being sent.

        Returns how many bytes were accepted (all of them unless ``tx_buffer_size`` is set and
        the pending bytes would not fit). The whole accepted chunk is handed to the link at once.
        """
        if type(data) is not bytes:
            data = bytes(data)
        if not data:
            return 0
        k = self.kernel
        now = k.now_ns + k.busy_ns
        if self.tx_buffer_size is not None:
            room = self.tx_buffer_size - self._tx_pending_at(now)
            if room <= 0:
                return 0
            if len(data) > room:
                data = data[:room]
        cfg = self._config
        t0 = max(self._tx_idle_ns, now)
        n = len(data)
        kbits = cfg.bits_per_frame * NS_PER_S
        end = t0 + (n * kbits) // cfg.baud
        self._tx_idle_ns = end
        bursts = self._tx_bursts
        while bursts and bursts[0][4] <= now:
            bursts.popleft()
        bursts.append((t0, kbits, cfg.baud, n, end))
        self.tx_bytes += n
        link = self.link
        if link is not None:
            link.transmit(t0, cfg, data)
        if self._tc_handler is not None:
            self._schedule_tc()
        return n

    def send_break(self) -> None:
        """Send a break (STM32 SBK): a frame's worth of space, then the stop bits at mark.

        PX4IO uses it to resynchronise the FMU-IO link; the receiver reads it as 0x00 with FE
        and LBD.
        """
        k = self.kernel
        now = k.now_ns + k.busy_ns
        cfg = self._config
        t0 = max(now, self._tx_idle_ns)
        nbits = cfg.bits_per_frame + cfg.stop_bits
        end = t0 + (nbits * NS_PER_S) // cfg.baud
        self._tx_idle_ns = end
        self._tx_bursts.append((t0, nbits * NS_PER_S, cfg.baud, 0, end))
        self.breaks_sent += 1
        if self.link is not None:
            self.link.transmit(t0, cfg, BREAK)
        if self._tc_handler is not None:
            self._schedule_tc()

    @property
    def tx_idle_ns(self) -> int:
        """When the transmitter finishes what it has been given (end of the last stop bit)."""
        return self._tx_idle_ns

    @property
    def tx_busy(self) -> bool:
        return self.kernel.context_ns < self._tx_idle_ns

    def _tx_pending_at(self, t_ns: int) -> int:
        pending = 0
        for t0, kbits, baud, n, end in self._tx_bursts:
            if end <= t_ns:
                continue
            if t_ns < t0:
                pending += n
            else:
                sent = ((t_ns - t0 + 1) * baud - 1) // kbits
                pending += n - min(n, sent)
        return pending

    @property
    def tx_pending(self) -> int:
        """Bytes accepted by write() whose last stop bit has not ended yet."""
        return self._tx_pending_at(self.kernel.context_ns)

    def on_tx_complete(self, handler: TimeHandler | None) -> None:
        """TC interrupt: ``handler(t_ns)`` when the transmitter has sent everything."""
        self._tc_handler = handler
        Kernel.cancel(self._tc_event)
        self._tc_event = None
        if handler is not None and self._tx_idle_ns > self.kernel.now_ns:
            self._schedule_tc()

    def _schedule_tc(self) -> None:
        Kernel.cancel(self._tc_event)
        self._tc_event = self.kernel.call_at(self._tx_idle_ns, self._tc_isr, priority=PRIO_ISR)

    def _tc_isr(self) -> None:
        self._tc_event = None
        handler = self._tc_handler
        if handler is not None:
            call_in_isr(self.kernel, handler, self.kernel.now_ns)

    # -- receiver: entry point from the link ----------------------------------------------------

    def receive(self, t_start_ns: int, tx_config: UartConfig,
                data: bytes | LineBreak) -> None:
        """A burst reaches the RX pin: through the line fault if one is installed, else
        straight to :meth:`receive_clean`."""
        noise = self.line_noise
        if noise is not None:
            noise.on_burst(t_start_ns, tx_config, data)
            return
        self.receive_clean(t_start_ns, tx_config, data)

    def receive_clean(self, t_start_ns: int, tx_config: UartConfig,
                      data: bytes | LineBreak) -> None:
        """A burst reaches the RX pin: ``data`` sent back to back from ``t_start_ns`` (leading
        edge of the first start bit) in the transmitter's format ``tx_config``.

        Each byte arrives when its last stop bit ends. ``t_start_ns`` may be in the past of this
        receiver's kernel (a burst from another process arrives up to one lockstep quantum
        late): bytes whose arrival time has already passed arrive *now*, in order, and later
        ones at their own time.

        If the format differs from ours in baud, data bits, parity or inversion, the burst goes
        through the bit-level :class:`~board.uart_line.LineDecoder`; stop bits never need to
        match (only the first stop bit is checked, as on the STM32).
        """
        now = self.kernel.now_ns
        ev = self._idle_event
        if ev is not None and Kernel.pending(ev) and t_start_ns < Kernel.due_ns(ev):
            Kernel.cancel(ev)  # the line is busy again before IDLE would have been detected
            self._idle_event = None
        rx = self._config
        if isinstance(data, LineBreak):
            if tx_config.line_format == rx.line_format and not self._decoder.pending:
                t = max(tx_config.byte_end_ns(t_start_ns, 0), now)
                self._deliver_entries([(t, 0, FE | LBD)], True)
                return
            self._receive_slow(t_start_ns, tx_config, data, now)
            return
        if not data:
            return
        if tx_config.line_format != rx.line_format or self._decoder.pending:
            self._receive_slow(t_start_ns, tx_config, data, now)
            return
        if rx.data_bits == 7:
            data = data.translate(_MASK7)
        kbits = tx_config.bits_per_frame * NS_PER_S
        baud = tx_config.baud
        n = len(data)
        last = t_start_ns + (n * kbits) // baud
        if self._rx_handler is not None:
            call_at = self.kernel.call_at
            isr = self._rx_isr
            for i, b in enumerate(data):
                t = t_start_ns + ((i + 1) * kbits) // baud
                call_at(max(now, t), isr, b, 0, priority=PRIO_ISR)
        else:
            if type(data) is not bytes:
                data = bytes(data)
            self._pending.append([0, t_start_ns, kbits, baud, data, 0])
            if self._dma_handler is not None:
                if t_start_ns >= self._last_rx_ns + rx.frame_ns_ceil:
                    self._dma_count = 0   # the line went idle: the driver re-armed the ring
                self._schedule_dma_burst(t_start_ns, kbits, baud, n, now)
        last = max(last, now)
        self._last_rx_ns = last
        if self._idle_handler is not None:
            self._schedule_idle(last + rx.frame_ns_ceil)

    def _receive_slow(self, t_start_ns: int, tx_config: UartConfig, data: bytes | LineBreak,
                      now: int) -> None:
        self._decoder.feed(t_start_ns, tx_config, data, self._config)
        self._run_decoder(False, now)

    def _run_decoder(self, final: bool, now: int) -> None:
        frames, wake_ns, mark_since = self._decoder.decode(self._config, final)
        Kernel.cancel(self._decode_event)
        self._decode_event = None
        if frames:
            self._deliver_entries([(max(now, t), v, f) for t, v, f in frames], False)
            self._idle_armed = True
        if wake_ns is not None:
            self._decode_event = self.kernel.call_at(max(wake_ns, now), self._decode_final,
                                                     priority=_PRIO_LAST)
        elif self._idle_armed and mark_since is not None and self._idle_handler is not None:
            # IDLE needs a full character of mark after both the last word and the last space.
            self._idle_armed = False
            self._schedule_idle(max(self._last_rx_ns, mark_since) + self._config.frame_ns_ceil)

    def _decode_final(self) -> None:
        self._decode_event = None
        self._run_decoder(True, self.kernel.now_ns)

    def _deliver_entries(self, entries: list[tuple[int, int, int]], idle: bool) -> None:
        """Queue explicitly timed words (from the decoder, or a break) for reception."""
        if self._rx_handler is not None:
            call_at = self.kernel.call_at
            for t, v, f in entries:
                call_at(t, self._rx_isr, v, f, priority=PRIO_ISR)
        else:
            self._pending.append([1, entries, 0])
            if self._dma_handler is not None:
                if entries[0][0] >= self._last_rx_ns + 2 * self._config.frame_ns_ceil:
                    self._dma_count = 0   # idle before this word (its start bit included)
                self._schedule_dma_entries(entries)
        last = entries[-1][0]
        self._last_rx_ns = last
        if idle and self._idle_handler is not None:
            self._schedule_idle(last + self._config.frame_ns_ceil)

    # -- receiver: firmware side ----------------------------------------------------------------

    def _drain(self, t_ns: int) -> None:
        """Move every byte that has arrived by ``t_ns`` into the buffer (or lose it)."""
        pending = self._pending
        while pending:
            ch = pending[0]
            if ch[0] == 0:
                _, t0, kbits, baud, data, idx = ch
                n = ((t_ns - t0 + 1) * baud - 1) // kbits
                if n <= idx:
                    return
                ln = len(data)
                if n >= ln:
                    self._accept(data[idx:] if idx else data)
                    pending.popleft()
                    continue
                self._accept(data[idx:n])
                ch[5] = n
                return
            entries = ch[1]
            idx = ch[2]
            ln = len(entries)
            while idx < ln and entries[idx][0] <= t_ns:
                _, v, f = entries[idx]
                if f:
                    self._note_errors(f)
                self._accept(bytes((v & 0xFF,)))
                idx += 1
            if idx < ln:
                ch[2] = idx
                return
            pending.popleft()

    def _accept(self, chunk: bytes) -> None:
        buf = self._buf
        n = len(chunk)
        self.rx_bytes += n
        room = self.rx_buffer_size - len(buf)
        if n > room:  # the bytes beyond the free space are lost
            room = max(room, 0)
            self.overruns += n - room
            self._flags |= ORE
            chunk = chunk[:room]
        buf += chunk

    def _note_errors(self, flags: int) -> None:
        self._flags |= flags
        if flags & FE:
            self.framing_errors += 1
        if flags & PE:
            self.parity_errors += 1
        if flags & LBD:
            self.breaks += 1

    def read(self, n: int = -1) -> bytes:
        """Bytes that have arrived by the current context time, oldest first (all if n < 0)."""
        k = self.kernel
        if self._pending:
            self._drain(k.now_ns + k.busy_ns)
        buf = self._buf
        if n < 0 or n >= len(buf):
            out = bytes(buf)
            buf.clear()
            return out
        out = bytes(buf[:n])
        del buf[:n]
        return out

    @property
    def in_waiting(self) -> int:
        """Bytes in the receive buffer now (pyserial's name)."""
        if self._pending:
            self._drain(self.kernel.context_ns)
        return len(self._buf)

    def reset_input_buffer(self) -> None:
        """Discard what has arrived so far (pyserial's name)."""
        if self._pending:
            self._drain(self.kernel.context_ns)
        self._buf.clear()

    @property
    def flags(self) -> int:
        """Sticky error flags (PE|FE|ORE|LBD bits) for bytes arrived so far; not cleared."""
        if self._pending:
            self._drain(self.kernel.context_ns)
        return self._flags

    def take_errors(self) -> int:
        """Return the sticky error flags and clear them."""
        f = self.flags
        self._flags = 0
        return f

    @property
    def overrun(self) -> bool:
        return bool(self.flags & ORE)

    @property
    def framing_error(self) -> bool:
        return bool(self.flags & FE)

    @property
    def parity_error(self) -> bool:
        return bool(self.flags & PE)

    @property
    def noise_error(self) -> bool:
        """Never set: the model has no line noise."""
        return bool(self.flags & NF)

    @property
    def break_detected(self) -> bool:
        return bool(self.flags & LBD)

    # -- interrupts -----------------------------------------------------------------------------

    def on_rx(self, handler: RxHandler | None) -> None:
        """RXNE interrupt per received word: ``handler(t_ns, byte, flags)``; None to stop.

        Bytes already waiting stay in the buffer; words arriving from bursts received after
        this call go to the handler.
        """
        self._rx_handler = handler

    def on_idle(self, handler: TimeHandler | None) -> None:
        """IDLE-line interrupt: ``handler(t_ns)`` one character time after a burst's last byte."""
        self._idle_handler = handler
        if handler is None:
            Kernel.cancel(self._idle_event)
            self._idle_event = None

    def on_rx_dma(self, half_bytes: int, handler: TimeHandler | None) -> None:
        """RX DMA half/full-transfer interrupts: ``handler(t_ns)`` when every ``half_bytes``-th
        buffered word has arrived; None to stop.

        The STM32 way for a fast serial port (NuttX's RX DMA, PX4IO): the DMA fills a circular
        ring and interrupts at its half and its end, and the IDLE interrupt (:meth:`on_idle`)
        catches the tail of a burst. The driver re-arms the ring at IDLE (as PX4IO's link does),
        so the count restarts with each burst that follows an idle line: a message shorter
        than ``half_bytes`` gives IDLE only, a long stream one interrupt per ``half_bytes``.
        Only bytes that go to the buffer count (not those handed to an :meth:`on_rx` handler).
        """
        if handler is not None and (type(half_bytes) is not int or half_bytes <= 0):
            raise ValueError(f"Uart {self.name}: half_bytes must be an int > 0: {half_bytes!r}")
        self._dma_handler = handler
        self._dma_half = half_bytes if handler is not None else 0
        self._dma_count = 0
        self._dma_gen += 1

    def _schedule_dma_burst(self, t_start_ns: int, kbits: int, baud: int, n: int,
                            now: int) -> None:
        half = self._dma_half
        c = self._dma_count
        call_at = self.kernel.call_at
        isr = self._dma_isr
        gen = self._dma_gen
        for i in range(half - c, n + 1, half):  # 1-based index of each ring-half's last word
            call_at(max(now, t_start_ns + (i * kbits) // baud), isr, gen, priority=PRIO_ISR)
        self._dma_count = (c + n) % half

    def _schedule_dma_entries(self, entries: list[tuple[int, int, int]]) -> None:
        half = self._dma_half
        c = self._dma_count
        n = len(entries)
        for i in range(half - c, n + 1, half):
            self.kernel.call_at(entries[i - 1][0], self._dma_isr, self._dma_gen,
                                priority=PRIO_ISR)
        self._dma_count = (c + n) % half

    def _dma_isr(self, gen: int) -> None:
        handler = self._dma_handler
        if handler is not None and gen == self._dma_gen:
            call_in_isr(self.kernel, handler, self.kernel.now_ns)

    def _rx_isr(self, byte: int, flags: int) -> None:
        if flags:
            self._note_errors(flags)
        handler = self._rx_handler
        if handler is None:  # unregistered after the burst came in: the byte is buffered
            self._accept(bytes((byte & 0xFF,)))
            return
        self.rx_bytes += 1
        call_in_isr(self.kernel, handler, self.kernel.now_ns, byte, flags)

    def _schedule_idle(self, t_ns: int) -> None:
        Kernel.cancel(self._idle_event)
        now = self.kernel.now_ns
        self._idle_event = self.kernel.call_at(max(now, t_ns), self._idle_isr,
                                               priority=PRIO_ISR)

    def _idle_isr(self) -> None:
        self._idle_event = None
        handler = self._idle_handler
        if handler is not None:
            call_in_isr(self.kernel, handler, self.kernel.now_ns)

    def __repr__(self) -> str:
        return f"<Uart {self.name} {self._config}>"

