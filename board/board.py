"""A board: one chip with its kernel, its peripherals, and the ports its wires leave through.

What leaves a board is only what real wires carry: UART bytes, pin levels, PWM pulse widths,
CAN frames, and (into the FMU) the physical quantities its sensors measure. Each of those goes
through a named *port*. During a quantum, outputs are collected as stamped records; inputs
arrive as stamped records and are applied at their time (or at once, if that time has passed:
a record from another process is late by up to one quantum).

A record is ``(port, t_ns, payload)`` with a payload of plain data (ints, floats, bytes,
tuples), so it can be marshalled to another process unchanged. The payload per port kind:

========  =======================================================================
``uart``  ``(baud, data_bits, parity, stop_bits, invert, data)``; ``data`` is bytes, or None
          for a line break
``pin``   level, 0 or 1 (or -1: released, the pin floats to its pull level)
``pwm``   ``(high_ns, period_ns)``; ``(0, 0)`` when the output stops (a dead chip's pin)
``can``   ``(arbitration_id, is_extended, is_remote, data)``
``value`` any plain data, for analog inputs such as sensor truth
========  =======================================================================
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Final

from mypy_extensions import mypyc_attr

from board.kernel import Kernel

if TYPE_CHECKING:  # protocols: erased at run time, plain objects to mypyc
    from board.protocols import InputPin, OutputPin, PwmOutput, UartPort

__all__ = ["Board", "PortInfo", "Record"]

#: (port, t_ns, payload)
Record = tuple[str, int, Any]

PORT_KINDS: Final[tuple[str, ...]] = ("uart", "pin", "pwm", "can", "value")


@dataclass(frozen=True)
class PortInfo:
    name: str
    kind: str       # one of PORT_KINDS
    direction: str  # "in", "out" or "inout"


@mypyc_attr(allow_interpreted_subclasses=True)
class Board:
    """Base of the FMU and IO boards (and of test boards): kernel plus exposed ports.

    Subclasses build their peripherals in ``__init__`` and expose the ones that leave the chip
    with the ``expose_*`` methods. :meth:`advance` is the lockstep step used by the endpoint.
    """

    def __init__(self, name: str, seed: int = 0) -> None:
        self.name = name
        self.seed = seed
        self.kernel = Kernel(name)
        self.ports: dict[str, PortInfo] = {}
        self._inputs: dict[str, Callable[[int, Any], None]] = {}
        self._outbox: list[Record] = []
        #: the present level of each pin and PWM output (what a mended wire carries again)
        self.port_levels: dict[str, Any] = {}
        #: Halted CPU (:meth:`ctl_hang`): None when running, else the records held at the
        #: chip's boundary until :meth:`ctl_release`.
        self._hung: list[Record] | None = None
        self.hung_since_ns: int | None = None
        #: Input ports whose handlers are pure hardware (a UART's receiver, the physics the
        #: sensors sample): they keep working while the CPU is halted. Subclasses add theirs.
        self.hw_inputs: set[str] = set()

    # -- exposing ports ------------------------------------------------------------------------

    def _add_port(self, name: str, kind: str, direction: str) -> None:
        if name in self.ports:
            raise ValueError(f"board {self.name}: port {name!r} exposed twice")
        if kind not in PORT_KINDS:
            raise ValueError(f"board {self.name}: unknown port kind {kind!r}")
        self.ports[name] = PortInfo(name, kind, direction)

    def emit(self, port: str, t_ns: int, payload: Any) -> None:
        """Record an output on ``port`` (called by the port adapters)."""
        self._outbox.append((port, t_ns, payload))

    def expose_uart(self, name: str, uart: UartPort) -> None:
        """Expose a :class:`board.uart.Uart`: its TX bursts leave, bursts arriving feed its RX."""
        self._add_port(name, "uart", "inout")
        self.hw_inputs.add(name)  # the USART (and its DMA) receives with the CPU halted
        from board.uart import BREAK, UartConfig

        uart.attach(_UartOut(self, name))
        configs: dict[tuple, UartConfig] = {}

        def deliver(t_ns: int, payload: Any) -> None:
            key = payload[:5]
            cfg = configs.get(key)
            if cfg is None:
                baud, bits, parity, stop, invert = key
                cfg = configs[key] = UartConfig(baud, bits, parity, stop, bool(invert))
            data = payload[5]
            uart.receive(t_ns, cfg, BREAK if data is None else data)

        self._inputs[name] = deliver

    def expose_pin_out(self, name: str, pin: OutputPin) -> None:
        """Expose a pin this chip drives; its level changes leave as records."""
        self._add_port(name, "pin", "out")
        levels = self.port_levels

        def changed(_pin: Any, t_ns: int, level: int) -> None:
            levels[name] = level
            self.emit(name, t_ns, level)

        pin.on_change(changed)

    def expose_pin_in(self, name: str, pin: InputPin) -> None:
        """Expose a pin driven from outside (a switch, another chip's output)."""
        self._add_port(name, "pin", "in")
        k = self.kernel

        def deliver(t_ns: int, level: int) -> None:
            t = t_ns if t_ns > k.now_ns else None
            if level < 0:
                pin.release(t)
            else:
                pin.set(level, t)

        self._inputs[name] = deliver

    def expose_pwm(self, name: str, channel: PwmOutput) -> None:
        """Expose a timer channel's PWM output (pulse width and period as they change)."""
        self._add_port(name, "pwm", "out")
        levels = self.port_levels

        def changed(t_ns: int, high_ns: int, period_ns: int) -> None:
            levels[name] = (high_ns, period_ns)
            self.emit(name, t_ns, (high_ns, period_ns))

        channel.on_pwm(changed)

    def expose_input(self, name: str, handler: Callable[[int, Any], None], kind: str = "value"
                     ) -> None:
        """Expose a generic input; ``handler(t_ns, payload)`` runs when a record arrives."""
        self._add_port(name, kind, "in")
        self._inputs[name] = handler

    def expose_output(self, name: str, kind: str = "value") -> Callable[[int, Any], None]:
        """Expose a generic output; returns the function that emits on it."""
        self._add_port(name, kind, "out")
        if kind in ("pwm", "pin"):
            levels = self.port_levels

            def emit_level(t_ns: int, payload: Any) -> None:
                levels[name] = payload
                self.emit(name, t_ns, payload)

            return emit_level
        return lambda t_ns, payload: self.emit(name, t_ns, payload)

    # -- lockstep ------------------------------------------------------------------------------

    def deliver(self, records: list[Record]) -> None:
        """Apply input records: each at its time, or now if that time has passed.

        A late record's handler still gets its original stamp: a UART burst that started in the
        past delivers the bytes still in flight at their exact wire times.
        """
        k = self.kernel
        for port, t_ns, payload in records:
            handler = self._inputs.get(port)
            if handler is None:
                raise ValueError(f"board {self.name}: no input port {port!r} "
                                 f"(inputs: {', '.join(sorted(self._inputs)) or 'none'})")
            if t_ns <= k.now_ns:
                handler(t_ns, payload)
            else:
                k.call_at(t_ns, handler, t_ns, payload)

    def advance(self, until_ns: int, inputs: list[Record], start_ns: int | None = None
                ) -> list[Record]:
        """Run to ``start_ns`` (the quantum's start), apply ``inputs``, run to ``until_ns``;
        return the outputs stamped inside.

        ``start_ns`` matters when the orchestrator skipped this board for quanta in which it
        had nothing due: the board first catches up to the quantum's start, so a late input is
        applied at the same time as if it had never been skipped.
        """
        if self._hung is not None:
            return self._advance_hung(until_ns, inputs, start_ns)
        k = self.kernel
        if start_ns is not None and start_ns > k.now_ns:
            k.run(start_ns)
        if inputs:
            self.deliver(inputs)
        k.run(until_ns)
        out = self._outbox
        self._outbox = []
        return out

    def next_event_ns(self) -> int | None:
        if self._hung is not None:
            return None  # a halted CPU has nothing due until released
        return self.kernel.peek_ns()

    # -- a halted CPU (fault injection) ----------------------------------------------------------

    def _advance_hung(self, until_ns: int, inputs: list[Record], start_ns: int | None
                      ) -> list[Record]:
        """The clock moves, no event runs: firmware, interrupts and timers' callbacks are all
        stopped. The hardware inputs (UART receivers, physics) still take what arrives; the
        rest is held and applied when the CPU is released."""
        k = self.kernel
        if start_ns is not None and start_ns > k.now_ns:
            k.now_ns = start_ns
        hw = self.hw_inputs
        held = self._hung
        assert held is not None
        inputs_by_port = self._inputs
        for rec in inputs:
            if rec[0] in hw:
                # applied at once with its stamp: a UART works out arrival times itself, and
                # no kernel event would run to apply it later
                inputs_by_port[rec[0]](rec[1], rec[2])
            else:
                held.append(rec)
        if until_ns > k.now_ns:
            k.now_ns = until_ns
        out = self._outbox  # bursts written before the hang that are still on the wire
        self._outbox = []
        return out

    def ctl_hang(self) -> int:
        """Halt the CPU now (a lock-up with interrupts masked, a hard fault loop): the kernel
        stops dispatching events, so no firmware, interrupt or callout runs and nothing new is
        transmitted; pins keep their last level and timers their last PWM, as a halted STM32's
        peripherals do. The process stays alive (unlike a kill) and :meth:`ctl_release` resumes
        it. Returns the halt time (ns). Hanging twice is harmless."""
        if self._hung is None:
            self._hung = []
            self.hung_since_ns = self.kernel.now_ns
        return self.hung_since_ns  # type: ignore[return-value]

    def ctl_release(self) -> int:
        """Resume a halted CPU now: the interrupts and timer events that fell due meanwhile run
        first (by priority), then everything continues from the present; held inputs are
        applied now. Returns the number of overdue events (0 if the board was not halted)."""
        held = self._hung
        if held is None:
            return 0
        self._hung = None
        self.hung_since_ns = None
        k = self.kernel
        n = k.resume_at(k.now_ns)
        if held:
            self.deliver(held)
        return n

    def ctl_hung(self) -> bool:
        return self._hung is not None

    # -- bus faults (fault injection) ------------------------------------------------------------

    def _bus(self, kind: str, name: str) -> Any:
        buses: dict[str, Any] = getattr(self, kind, {})
        if name not in buses:
            raise ValueError(f"board {self.name}: no {kind.upper()} bus {name!r} (buses: "
                             f"{', '.join(sorted(buses)) or 'none'})")
        return buses[name]

    def ctl_spi_miso_stuck(self, bus: str, level: int | None) -> None:
        """Short an SPI bus's MISO high (1), low (0), or heal it (None): see
        :meth:`board.spi.SpiBus.set_miso_stuck`."""
        self._bus("spi", bus).set_miso_stuck(level)

    def ctl_i2c_fault(self, bus: str, nak_rate: float = 0.0, sda_stuck: bool = False) -> None:
        """A NAK storm (``nak_rate`` of the transactions NAKed, seeded) or SDA held low on an
        I2C bus; both off heals it (see :class:`board.i2c.I2cFault`)."""
        from board.i2c import I2cFault

        b = self._bus("i2c", bus)
        if not nak_rate and not sda_stuck:
            b.set_fault(None)
            return
        b.set_fault(I2cFault(nak_rate, sda_stuck, seed=self.seed, name=f"{self.name}.{bus}"))

    def ctl_bus_stats(self, kind: str, bus: str) -> dict[str, int]:
        """Counters of one bus (``kind`` "spi" or "i2c")."""
        b = self._bus(kind, bus)
        keys = ("transfers", "bytes") if kind == "spi" else \
            ("transactions", "nak_count", "addr_nak_count", "data_nak_count", "timeouts")
        return {k: getattr(b, k) for k in keys}

    # -- UART line faults (fault injection) ------------------------------------------------------

    def uart_named(self, name: str) -> Any:
        """A UART of this board by its chip name (``USART6``) or its port (``io_link``)."""
        uarts: dict[str, Any] = getattr(self, "uarts", {})
        if name in uarts:
            return uarts[name]
        for u in uarts.values():
            link = getattr(u, "link", None)
            if isinstance(link, _UartOut) and link.port == name:
                return u
        raise ValueError(f"board {self.name}: no UART {name!r} (UARTs: "
                         f"{', '.join(sorted(uarts)) or 'none'})")

    def ctl_uart_fault(self, uart: str, bit_error_rate: float = 0.0, drop_rate: float = 0.0,
                       seed: int | None = None) -> None:
        """Noise on a UART's RX line: each bit of every received frame (start, data, parity,
        stop) flips with ``bit_error_rate``, and each byte is lost with ``drop_rate`` (its start
        bit never seen). Seeded from the board's seed and the UART's name unless ``seed`` is
        given. Both rates 0 removes the fault (see board/uart_fault.py)."""
        from board.uart_fault import LineNoise

        u = self.uart_named(uart)
        if not bit_error_rate and not drop_rate:
            LineNoise.remove(u)
            return
        LineNoise(u, bit_error_rate, drop_rate,
                  self.seed if seed is None else seed).install()

    def ctl_uart_fault_stats(self, uart: str) -> dict[str, int]:
        """Counters of the line fault on ``uart`` (bytes seen, corrupted, dropped, framing and
        parity errors made); zeros when none is installed."""
        from board.uart_fault import LineNoise

        noise = LineNoise.installed(self.uart_named(uart))
        return noise.stats() if noise is not None else {}

    def call(self, method: str, *args: Any) -> Any:
        """Run a named control method (``ctl_<method>``) of this board: shell commands, fault
        injection, state queries for tests. Only plain data crosses."""
        fn = getattr(self, f"ctl_{method}", None)
        if fn is None:
            raise AttributeError(f"board {self.name} has no control method {method!r}")
        return fn(*args)

    def ctl_time_ns(self) -> int:
        return self.kernel.now_ns

    def ctl_port_level(self, port: str) -> Any:
        """The present level of a pin or PWM output port (None if it never changed)."""
        return self.port_levels.get(port)

    def ctl_ports(self) -> list[tuple[str, str, str]]:
        return [(p.name, p.kind, p.direction) for p in self.ports.values()]


class _UartOut:
    """The link a board's exposed UART transmits into: bursts become output records."""

    __slots__ = ("board", "port")

    def __init__(self, board: Board, port: str) -> None:
        self.board = board
        self.port = port

    def transmit(self, t_start_ns: int, config: Any, data: Any) -> None:
        raw = None if not isinstance(data, (bytes, bytearray, memoryview)) else bytes(data)
        self.board.emit(self.port, t_start_ns, (config.baud, config.data_bits, config.parity,
                                                config.stop_bits, int(config.invert), raw))
