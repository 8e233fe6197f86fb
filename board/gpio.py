"""GPIO pins and the STM32 EXTI interrupt lines.

A pin is a wire with a level. Whoever drives it (the MCU's own firmware, a device model's
data-ready output, the outside world through the lockstep endpoint) calls :meth:`Pin.set`; the
pin then tells its synchronous observers (``on_change``: timers latching a capture, the lockstep
endpoint forwarding the level to another process) and, through the EXTI block, queues the
interrupt handler as a kernel event at the edge time with ``PRIO_ISR``.

EXTI rules follow the STM32 reference manuals (RM0090 / RM0041 "EXTI"):

* Line *n* serves pin number *n* of exactly one port: SYSCFG_EXTICR (AFIO_EXTICR on the F1)
  selects the port. Attaching PB0 while PA0 owns line 0 therefore re-routes the line to PB0,
  exactly as writing EXTICR would: the earlier pin silently stops interrupting. We do the same,
  log a warning and count it in :attr:`Gpio.exti_rerouted`, because a driver doing this on real
  hardware has a bug that is hard to see.
* An edge sets the line's pending bit; the handler runs once for a pending bit however many
  edges arrived before it ran (the extra edges are counted in :attr:`ExtiLine.coalesced`).

Pulses (:meth:`Pin.pulse`): a device model's data-ready pulse drives a level now and returns
to its idle level a fixed time later. When nothing observes the return (no ``on_change``
listener, the pin's EXTI line not selecting that edge) the return is not a kernel event: the
pin remembers when it happens and the level is worked out when read (``level``, ``driven``, the
next drive). Attaching a listener or an interrupt that could see it turns it back into an
event. A later drive of the pin replaces a pending return. With ``sync=True`` (only for a
device model's own hardware event, at its event time with no bus time spent) an edge's EXTI
handler runs at once instead of as a queued event: same edge time, same ``in_isr``, same
pending-bit rules; only its place among other events at the very same nanosecond differs.
The handler runs after the model has finished updating its own state (it may read the chip).
The MPU6000's 8 kHz data-ready is the reason: three kernel events per sample become one.

A pin nobody drives reads its pull level: 1 for ``pull="up"``, 0 for ``"down"`` and, for a
floating input (``None``), 0 (real floating inputs are undefined; 0 keeps runs deterministic).
"""

from __future__ import annotations

import logging
import re
from collections.abc import Callable
from typing import Any, Final

from board.kernel import PRIO_HW, PRIO_ISR, Event, Kernel, call_in_isr

__all__ = ["ExtiLine", "Gpio", "Pin", "PinHandler", "PinListener", "call_in_isr"]

log = logging.getLogger(__name__)

#: ``listener(pin, t_ns, level)``: synchronous observer of a level change.
PinListener = Callable[["Pin", int, int], None]
#: ``handler(pin, t_ns)``: EXTI interrupt handler, runs in interrupt context.
PinHandler = Callable[["Pin", int], None]

_PIN_NAME: Final = re.compile(r"^P([A-K])(\d{1,2})$")
_PULLS = (None, "up", "down")


class ExtiLine:
    """One EXTI line: which pin is routed to it, edge selection, handler and pending state."""

    __slots__ = (
        "coalesced",
        "falling",
        "fired",
        "handler",
        "number",
        "pending",
        "pin",
        "rising",
    )

    def __init__(self, number: int) -> None:
        self.number = number
        self.pin: Pin | None = None
        self.handler: PinHandler | None = None
        self.rising = False
        self.falling = False
        #: True between an edge and the run of its handler (the EXTI_PR bit).
        self.pending = False
        #: Edges that arrived while the line was already pending (handled once).
        self.coalesced = 0
        #: Handler invocations so far.
        self.fired = 0


class Pin:
    """A named pin such as ``PD15``; its level is 0 or 1."""

    __slots__ = ("_driven", "_gpio", "_level", "_listeners", "_ret_drive", "_ret_entry", "_ret_t",
                 "name", "number", "port", "pull")

    def __init__(self, gpio: Gpio, name: str, port: str, number: int, pull: str | None) -> None:
        self._gpio = gpio
        self.name = name
        self.port = port
        self.number = number
        self.pull = pull
        self._driven: int | None = None
        self._level = 1 if pull == "up" else 0
        self._listeners: list[PinListener] = []
        #: A lazy return (see :meth:`pulse`): its time (-1: none) and the drive it restores.
        self._ret_t = -1
        self._ret_drive: int | None = None
        #: A return nobody could see turned into a kernel event because something can now.
        self._ret_entry: Event | None = None

    @property
    def level(self) -> int:
        """The level on the wire now (the driven level, else the pull level)."""
        if self._ret_t >= 0:
            self._settle(self._gpio.kernel.now_ns)
        return self._level

    @property
    def driven(self) -> bool:
        """True if something drives the pin (as opposed to the pull resistor)."""
        if self._ret_t >= 0:
            self._settle(self._gpio.kernel.now_ns)
        return self._driven is not None

    def value(self) -> int:
        """MicroPython ``Pin.value()`` spelling of :attr:`level`."""
        return self.level

    def _settle(self, t_ns: int) -> None:
        """Apply a lazy return due at or before ``t_ns`` (silently: nobody observes it)."""
        t = self._ret_t
        if 0 <= t <= t_ns:
            self._ret_t = -1
            d = self._driven = self._ret_drive
            self._level = d if d is not None else (1 if self.pull == "up" else 0)

    def _drop_return(self, t_ns: int) -> None:
        """A drive at ``t_ns``: a return due by then happens first, a later one is replaced."""
        if self._ret_t >= 0:
            self._settle(t_ns)
            self._ret_t = -1
        entry = self._ret_entry
        if entry is not None:
            self._ret_entry = None
            Kernel.cancel(entry)
            due = Kernel.due_ns(entry)
            if due <= t_ns:  # due already (inside a bus wait): it happens first
                self._apply(Kernel.event_args(entry)[0], due)

    def _materialize(self) -> None:
        """Something may now observe a lazy return: make a future one a kernel event."""
        if self._ret_t < 0:
            return
        kernel = self._gpio.kernel
        self._settle(kernel.now_ns)
        t = self._ret_t
        if t >= 0:
            self._ret_t = -1
            self._ret_entry = kernel.post(t, PRIO_HW, self._return, (self._ret_drive, t))

    def _return(self, drive: int | None, t_ns: int) -> None:
        self._ret_entry = None
        self._apply(drive, t_ns)

    def pulse(self, on: int | None, off: int | None, end_ns: int, sync: bool = False) -> None:
        """Drive ``on`` now (``kernel.context_ns``) and ``off`` at ``end_ns`` (None: release).

        The return is lazy when nothing can observe it (see the module docstring). ``sync``
        runs the EXTI handler of the leading edge at once; only a device model's own
        ``PRIO_HW`` event at its event time may ask for it (elsewhere it would preempt a thread).
        Edge detection, listeners and pending-bit coalescing are :meth:`_apply`'s, inlined: this
        is the per-sample data-ready path (8 kHz on the MPU6000).
        """
        gpio = self._gpio
        kernel = gpio.kernel
        busy = kernel.busy_ns
        t = kernel.now_ns + busy
        pull = 1 if self.pull == "up" else 0
        rt = self._ret_t
        if rt >= 0:  # the previous pulse's lazy return (_drop_return, inlined)
            self._ret_t = -1
            if rt <= t:
                d = self._ret_drive
                self._level = d if d is not None else pull
        if self._ret_entry is not None:
            self._drop_return(t)
        self._driven = on
        new = on if on is not None else pull
        edge = new != self._level
        self._level = new
        line = gpio.exti[self.number]
        mine = line.pin is self
        listeners = self._listeners
        if listeners or (mine and (line.rising if (off if off is not None else pull)
                                   else line.falling)):
            self._ret_entry = kernel.post(end_ns, PRIO_HW, self._return, (off, end_ns))
        else:
            self._ret_t = end_ns
            self._ret_drive = off
        if not edge:
            return
        if listeners:
            for listener in tuple(listeners):
                listener(self, t, new)
        if not mine or not (line.rising if new else line.falling):
            return
        if line.pending:
            line.coalesced += 1
            return
        line.pending = True
        if sync and not busy:
            gpio._fire(line, self, t)
        else:
            kernel.post(t, PRIO_ISR, gpio._fire, (line, self, t))

    def set(self, level: int, t_ns: int | None = None) -> None:
        """Drive the pin to ``level`` (0 or 1).

        With ``t_ns`` omitted the change happens at ``kernel.context_ns`` (so a driver that
        has just spent 100 us on a bus toggles the pin 100 us after its event started). A
        ``t_ns`` later than that schedules the change as a hardware event at that time, which
        is how device models and the lockstep endpoint place edges inside a quantum.
        """
        if level is not True and level is not False and level not in (0, 1):
            raise ValueError(f"pin {self.name}: level must be 0 or 1, got {level!r}")
        self._drive(int(level), t_ns)

    def high(self, t_ns: int | None = None) -> None:
        """Drive the pin high (``set(1)``)."""
        if t_ns is None:  # the per-sample data-ready path: skip _drive's checks
            k = self._gpio.kernel
            self._apply(1, k.now_ns + k.busy_ns)
        else:
            self._drive(1, t_ns)

    def low(self, t_ns: int | None = None) -> None:
        """Drive the pin low (``set(0)``)."""
        if t_ns is None:
            k = self._gpio.kernel
            self._apply(0, k.now_ns + k.busy_ns)
        else:
            self._drive(0, t_ns)

    def release(self, t_ns: int | None = None) -> None:
        """Stop driving: the pin falls back to its pull level (open drain, tri-state)."""
        self._drive(None, t_ns)

    def _drive(self, level: int | None, t_ns: int | None) -> None:
        kernel = self._gpio.kernel
        ctx = kernel.now_ns + kernel.busy_ns
        if t_ns is None:
            self._apply(level, ctx)
            return
        if type(t_ns) is not int:
            raise ValueError(f"pin {self.name}: t_ns must be an int number of ns, got {t_ns!r}")
        if t_ns < kernel.now_ns:
            raise ValueError(
                f"pin {self.name}: set at t={t_ns} ns is in the past (now={kernel.now_ns} ns)")
        if t_ns <= ctx:
            self._apply(level, t_ns)
        else:
            kernel.post(t_ns, PRIO_HW, self._apply, (level, t_ns))  # checked above

    def _apply(self, level: int | None, t_ns: int, defer: list | None = None) -> None:
        """The level changes at ``t_ns`` (>= now): listeners, then the EXTI edge.

        The EXTI part: an edge the line is armed for sets its pending bit and queues the
        handler (an edge while pending is coalesced, as EXTI_PR holds one bit). Per data-ready
        edge of the ST chips, so the listener snapshot is only taken when there are listeners.
        ``defer``: a device model's own hardware event at its event time collects the handler
        calls there and makes them itself once its state is consistent (``Gpio._fire(*args)``
        for each), instead of queueing an event per edge (see :meth:`pulse`).
        """
        if self._ret_t >= 0 or self._ret_entry is not None:
            self._drop_return(t_ns)
        self._driven = level
        new = level if level is not None else (1 if self.pull == "up" else 0)
        if new == self._level:
            return  # same level again: not an edge
        self._level = new
        if self._listeners:
            for listener in tuple(self._listeners):
                listener(self, t_ns, new)
        gpio = self._gpio
        line = gpio.exti[self.number]
        if line.pin is not self or not (line.rising if new else line.falling):
            return
        if line.pending:
            line.coalesced += 1
            return
        line.pending = True
        kernel = gpio.kernel
        if defer is not None and t_ns == kernel.now_ns and not kernel.busy_ns:
            defer.append((line, self, t_ns))
        else:
            # kernel.post: t_ns is the edge time, never before now (call_at's checks are moot).
            kernel.post(t_ns, PRIO_ISR, gpio._fire, (line, self, t_ns))

    def on_change(self, listener: PinListener) -> None:
        """Call ``listener(pin, t_ns, level)`` synchronously on every level change.

        For observers that are not interrupts: input-capture hardware, the lockstep endpoint,
        test probes. Listeners run inside whatever context changed the pin.
        """
        if not callable(listener):
            raise TypeError(f"pin {self.name}: on_change listener {listener!r} is not callable")
        self._materialize()
        self._listeners.append(listener)

    def remove_listener(self, listener: PinListener) -> None:
        """Undo :meth:`on_change`; removing an unknown listener raises ValueError."""
        try:
            self._listeners.remove(listener)
        except ValueError:
            raise ValueError(f"pin {self.name}: listener {listener!r} is not attached") from None

    def attach_interrupt(self, handler: PinHandler, rising: bool = True,
                         falling: bool = False) -> None:
        """Shortcut for :meth:`Gpio.attach_interrupt` on this pin."""
        self._gpio.attach_interrupt(self, handler, rising=rising, falling=falling)

    def detach_interrupt(self) -> None:
        """Shortcut for :meth:`Gpio.detach` on this pin."""
        self._gpio.detach(self)

    def __repr__(self) -> str:
        return f"<Pin {self.name}={self.level}{'' if self.driven else ' (pull)'}>"


class Gpio:
    """All GPIO pins of one MCU plus its 16 EXTI lines."""

    def __init__(self, kernel: Kernel, name: str = "gpio") -> None:
        self.kernel = kernel
        self.name = name
        self._pins: dict[str, Pin] = {}
        self.exti = [ExtiLine(n) for n in range(16)]
        #: Times an attach re-routed a line away from another port's pin.
        self.exti_rerouted = 0

    def pin(self, name: str, pull: str | None = None) -> Pin:
        """The pin ``name`` (``'PA0'`` … ``'PK15'``), created on first use.

        ``pull`` given on a later call changes the pull resistor (as reconfiguring the GPIO
        would); omitted, it leaves it alone.
        """
        if pull not in _PULLS:
            raise ValueError(f"{self.name}: pin {name}: pull must be None, 'up' or 'down', "
                             f"got {pull!r}")
        pin = self._pins.get(name)
        if pin is None:
            m = _PIN_NAME.match(name) if isinstance(name, str) else None
            if m is None or int(m.group(2)) > 15:
                raise ValueError(f"{self.name}: {name!r} is not a pin name like 'PD15' "
                                 f"(port A..K, number 0..15)")
            pin = Pin(self, name, m.group(1), int(m.group(2)), pull)
            self._pins[name] = pin
        elif pull is not None and pull != pin.pull:
            pin._settle(self.kernel.now_ns)
            pin.pull = pull
            if not pin.driven:
                pin._apply(None, self.kernel.context_ns)
        return pin

    def __getitem__(self, name: str) -> Pin:
        return self.pin(name)

    @property
    def pins(self) -> dict[str, Pin]:
        """Pins created so far, by name (a copy)."""
        return dict(self._pins)

    def _resolve(self, pin: Pin | str, where: str) -> Pin:
        if isinstance(pin, Pin):
            if pin._gpio is not self:
                raise ValueError(f"{self.name}.{where}: {pin.name} belongs to another Gpio")
            return pin
        return self.pin(pin)

    def attach_interrupt(self, pin: Pin | str, handler: PinHandler, rising: bool = True,
                         falling: bool = False) -> None:
        """Route EXTI line ``pin.number`` to ``pin`` and run ``handler(pin, t_ns)`` on edges.

        Re-routes the line if another port's pin with the same number had it (hardware
        behaviour, see the module docstring); attaching the same pin again replaces the
        handler and edge selection.
        """
        p = self._resolve(pin, "attach_interrupt")
        if not callable(handler):
            raise TypeError(f"{self.name}.attach_interrupt({p.name}): handler {handler!r} "
                             f"is not callable")
        if not (rising or falling):
            raise ValueError(f"{self.name}.attach_interrupt({p.name}): select rising and/or "
                             f"falling edges")
        line = self.exti[p.number]
        if line.pin is not None and line.pin is not p:
            self.exti_rerouted += 1
            log.warning("%s: EXTI line %d re-routed from %s to %s; %s no longer interrupts",
                        self.name, p.number, line.pin.name, p.name, line.pin.name)
        p._materialize()
        line.pin = p
        line.handler = handler
        line.rising = bool(rising)
        line.falling = bool(falling)

    def detach(self, pin: Pin | str) -> None:
        """Disable the pin's EXTI line (a pending handler still runs, as EXTI_PR stays set)."""
        p = self._resolve(pin, "detach")
        line = self.exti[p.number]
        if line.pin is not p:
            raise ValueError(f"{self.name}.detach: no interrupt attached to {p.name}")
        line.pin = None
        line.rising = line.falling = False

    def _fire(self, line: ExtiLine, pin: Pin, t_ns: int) -> None:
        line.pending = False
        handler = line.handler
        if handler is None:
            return
        line.fired += 1
        # call_in_isr, inlined: this runs for every data-ready edge.
        k = self.kernel
        prev = k.in_isr
        k.in_isr = True
        try:
            handler(pin, t_ns)
        finally:
            k.in_isr = prev
