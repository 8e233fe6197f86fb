"""Discrete-event kernel: the one owner of virtual time on a board.

Time is an integer count of nanoseconds since the board was powered. Events sit in a heap keyed
by ``(t_ns, priority, sequence)``: the sequence number is unique, so ties between events at the
same time and priority run in the order they were scheduled, and two runs of the same program
execute the same events in the same order. Lower priority values run first (interrupts before
work queues, see the ``PRIO_*`` constants).

Nothing here reads the wall clock, sleeps or starts threads.

Heap entries are plain lists ``[t_ns, priority, seq, fn, args]`` because lists compare in C, which
keeps the hot loop fast; a cancelled entry has ``fn`` set to ``None`` and is skipped when popped.
The entry is also the handle a scheduling call returns (:data:`Event`), but it is the kernel's:
only this module writes it or the heap. Callers cancel with :meth:`Kernel.cancel` and ask
:meth:`Kernel.pending`, :meth:`Kernel.due_ns` and :meth:`Kernel.event_args`; every push goes
through :meth:`Kernel.post` or the checked ``call_*``. (A handle object with a ``cancel()``
method would cost one more allocation per event on the platform's hottest path;
:class:`Periodic` is such an object, made once per timer.)
"""

from __future__ import annotations

import heapq
from typing import Any, Callable, Final

from mypy_extensions import mypyc_attr

__all__ = [
    "call_in_isr",
    "Event",
    "Kernel",
    "KernelError",
    "Periodic",
    "PRIO_HW",
    "PRIO_ISR",
    "PRIO_DEFAULT",
    "PRIO_THREAD",
    "NS_PER_US",
    "NS_PER_MS",
    "NS_PER_S",
]

NS_PER_US: Final = 1_000
NS_PER_MS: Final = 1_000_000
NS_PER_S: Final = 1_000_000_000

#: Hardware state changes (a sensor latching a sample, a wire delivering a byte).
PRIO_HW: Final = -20
#: Interrupt handlers (EXTI, timer, UART, HRT callouts).
PRIO_ISR: Final = -10
#: Anything not otherwise classified.
PRIO_DEFAULT: Final = 0
#: Threads: work queue dispatch and tasks (work queues add their own offset, higher runs first).
PRIO_THREAD: Final = 100

_heappush: Final = heapq.heappush
_heappop: Final = heapq.heappop

#: A scheduled call, as :meth:`Kernel.post`, :meth:`Kernel.call_at` and
#: :meth:`Kernel.call_later` return it: opaque outside this module (pass it to
#: :meth:`Kernel.cancel`, :meth:`Kernel.pending`, :meth:`Kernel.due_ns`).
Event = list


@mypyc_attr(native_class=False)
class KernelError(RuntimeError):
    """A callback raised; the message names the callback and the virtual time."""

    def __init__(self, message: str, t_ns: int, callback: str) -> None:
        super().__init__(message)
        self.t_ns = t_ns
        self.callback = callback


def callback_name(fn: Any) -> str:
    """A readable name for a callable (bound methods include their object's class)."""
    self_obj = getattr(fn, "__self__", None)
    qual = getattr(fn, "__qualname__", None)
    if qual is None:
        func = getattr(fn, "func", None)  # functools.partial
        if func is not None:
            return callback_name(func)
        return type(fn).__qualname__
    if self_obj is not None and not isinstance(self_obj, type):
        name = getattr(self_obj, "name", None)
        if isinstance(name, str):
            return f"{qual}[{name}]"
    return qual


class Periodic:
    """A repeating call made by :meth:`Kernel.call_every`; ``cancel()`` stops it.

    The n-th call happens at exactly ``first_ns + n * period_ns``: there is no drift however long
    the run.
    """

    __slots__ = ("kernel", "period_ns", "fn", "args", "priority", "next_ns", "_entry", "active")

    def __init__(self, kernel: Kernel, period_ns: int, fn: Callable[..., Any], args: tuple,
                 priority: int, first_ns: int) -> None:
        self.kernel = kernel
        self.period_ns = period_ns
        self.fn = fn
        self.args = args
        self.priority = priority
        self.next_ns = first_ns
        self.active = True
        self._entry = kernel.post(first_ns, priority, self._fire, ())

    def _fire(self) -> None:
        t = self.next_ns + self.period_ns
        self.next_ns = t
        # Reschedule before calling so that a callback may cancel its own timer.
        self._entry = self.kernel.post(t, self.priority, self._fire, ())
        self.fn(*self.args)

    def cancel(self) -> None:
        self.active = False
        self._entry[3] = None  # this module's own entry

    @property
    def name(self) -> str:
        return callback_name(self.fn)


class Kernel:
    """Virtual clock plus event heap for one board.

    ``busy_ns`` is the time the currently running context has spent blocked on buses (an SPI
    transfer, an I2C transaction). Buses add to it; the work-queue dispatcher resets it before a
    work item runs and uses it afterwards to delay the next item on that queue, so a driver that
    reads a sensor for 100 us occupies its queue for 100 us of virtual time. ``context_ns`` is
    the time as seen from inside the running context.
    """

    __slots__ = ("name", "now_ns", "busy_ns", "_queue", "_seq", "_stop", "_trace", "in_isr",
                 "events_run")

    def __init__(self, name: str = "kernel") -> None:
        self.name = name
        self.now_ns = 0
        self.busy_ns = 0
        self._queue: list[list] = []
        self._seq = 0
        self._stop = False
        self._trace: Callable[[int, int, int, str], None] | None = None
        #: True while an interrupt-context callback runs (set by the platform layer).
        self.in_isr = False
        self.events_run = 0

    # -- scheduling ---------------------------------------------------------------------------

    def post(self, t_ns: int, priority: int, fn: Callable[..., Any], args: tuple) -> Event:
        """``call_at`` without argument checks, for the platform's hot paths (t_ns >= now)."""
        self._seq = seq = self._seq + 1
        entry = [t_ns, priority, seq, fn, args]
        _heappush(self._queue, entry)
        return entry

    def call_at(self, t_ns: int, fn: Callable[..., Any], *args: Any,
                priority: int = PRIO_DEFAULT) -> Event:
        """Run ``fn(*args)`` at virtual time ``t_ns``; returns a handle for :meth:`cancel`."""
        if t_ns < self.now_ns:
            raise ValueError(
                f"{self.name}: call_at({callback_name(fn)}) at t={t_ns} ns is in the past "
                f"(now={self.now_ns} ns)")
        if type(t_ns) is not int:
            raise TypeError(f"{self.name}: time must be an integer number of ns, got {t_ns!r}")
        self._seq = seq = self._seq + 1
        entry = [t_ns, priority, seq, fn, args]
        _heappush(self._queue, entry)
        return entry

    def call_later(self, delay_ns: int, fn: Callable[..., Any], *args: Any,
                   priority: int = PRIO_DEFAULT) -> Event:
        """Run ``fn(*args)`` ``delay_ns`` after now; returns a handle for :meth:`cancel`."""
        if delay_ns < 0:
            raise ValueError(
                f"{self.name}: call_later({callback_name(fn)}) with negative delay {delay_ns} ns")
        if type(delay_ns) is not int:
            raise TypeError(
                f"{self.name}: delay must be an integer number of ns, got {delay_ns!r}")
        self._seq = seq = self._seq + 1
        entry = [self.now_ns + delay_ns, priority, seq, fn, args]
        _heappush(self._queue, entry)
        return entry

    def call_every(self, period_ns: int, fn: Callable[..., Any], *args: Any,
                   first_ns: int | None = None, priority: int = PRIO_DEFAULT) -> Periodic:
        """Run ``fn(*args)`` every ``period_ns``, first at ``first_ns`` (default now + period)."""
        if type(period_ns) is not int or period_ns <= 0:
            raise ValueError(f"{self.name}: period must be a positive integer ns, got {period_ns!r}")
        if first_ns is None:
            first_ns = self.now_ns + period_ns
        elif first_ns < self.now_ns:
            raise ValueError(
                f"{self.name}: call_every({callback_name(fn)}) first call at t={first_ns} ns is "
                f"in the past (now={self.now_ns} ns)")
        return Periodic(self, period_ns, fn, args, priority, first_ns)

    @staticmethod
    def cancel(handle: Event | Periodic | None) -> None:
        """Cancel a pending call; cancelling twice, after it ran, or ``None`` is harmless.

        The entry stays in the heap, dead, until it comes up (cheaper than removing it)."""
        if handle is None:
            return
        if isinstance(handle, Periodic):
            handle.cancel()
        else:
            handle[3] = None

    @staticmethod
    def pending(handle: Event | None) -> bool:
        """True if ``handle`` (from post/call_at/call_later) has not run and was not
        cancelled. An entry is marked dead only by :meth:`cancel`; one that ran is popped, so
        its owner drops the handle in the callback (the devices and timers here do)."""
        return handle is not None and handle[3] is not None

    @staticmethod
    def due_ns(handle: Event) -> int:
        """The virtual time ``handle`` is (or was) due at."""
        t: int = handle[0]
        return t

    @staticmethod
    def event_args(handle: Event) -> tuple:
        """The arguments ``handle``'s callback gets (a cancelled entry keeps them)."""
        args: tuple = handle[4]
        return args

    # -- running ------------------------------------------------------------------------------

    def resume_at(self, t_ns: int) -> int:
        """A halted CPU resumes at ``t_ns``: every event that fell due while it was halted
        becomes due at ``t_ns`` (pending interrupts are served as soon as it runs again, by
        priority), and periodic calls restart their cadence from ``t_ns``. Returns how many
        events were overdue. See :meth:`board.board.Board.ctl_hang`."""
        q = self._queue
        n = 0
        for e in q:
            if e[0] < t_ns and e[3] is not None:
                e[0] = t_ns
                n += 1
                owner = getattr(e[3], "__self__", None)
                if isinstance(owner, Periodic):
                    owner.next_ns = t_ns
        heapq.heapify(q)
        if t_ns > self.now_ns:
            self.now_ns = t_ns
        return n

    def peek_ns(self) -> int | None:
        """Time of the next live event, or None if nothing is scheduled."""
        q = self._queue
        while q and q[0][3] is None:
            _heappop(q)
        return q[0][0] if q else None

    def stop(self) -> None:
        """Make the current :meth:`run` return after the running callback."""
        self._stop = True

    def set_trace(self, trace: Callable[[int, int, int, str], None] | None) -> None:
        """Call ``trace(t_ns, priority, seq, name)`` before every event (slow; for debugging and
        determinism checks)."""
        self._trace = trace

    def step(self) -> bool:
        """Run the next event; returns False if there was none."""
        q = self._queue
        while q:
            entry = _heappop(q)
            fn = entry[3]
            if fn is None:
                continue
            self.now_ns = entry[0]
            self._dispatch(entry, fn)
            return True
        return False

    def _dispatch(self, entry: list, fn: Callable[..., Any]) -> None:
        if self._trace is not None:
            self._trace(entry[0], entry[1], entry[2], callback_name(fn))
        self.busy_ns = 0
        self.events_run += 1
        try:
            fn(*entry[4])
        except KernelError:
            raise
        except Exception as exc:
            name = callback_name(fn)
            raise KernelError(
                f"{self.name}: callback {name} raised at t={entry[0]} ns: "
                f"{type(exc).__name__}: {exc}", entry[0], name) from exc

    def run(self, until_ns: int) -> None:
        """Run every event due at or before ``until_ns``, then set the clock to ``until_ns``.

        An exception in a callback stops the run with a :class:`KernelError` naming it; the
        clock stays at that event's time.
        """
        if until_ns < self.now_ns:
            raise ValueError(
                f"{self.name}: run(until={until_ns} ns) is in the past (now={self.now_ns} ns)")
        self._stop = False
        if self._trace is not None:
            self._run_slow(until_ns)
            return
        q = self._queue
        pop = _heappop
        n = 0
        fn = None
        try:
            while q and q[0][0] <= until_ns:
                # One UNPACK_SEQUENCE instead of three subscripts: ~30k events per virtual
                # second on an FMU, so the loop's own bytecode count matters.
                t_ns, _prio, _seq, fn, args = pop(q)
                if fn is None:
                    continue
                self.now_ns = t_ns
                self.busy_ns = 0
                n += 1
                fn(*args)
                if self._stop:
                    self.events_run += n
                    return
        except KernelError:
            self.events_run += n
            raise
        except Exception as exc:
            self.events_run += n
            name = callback_name(fn)
            raise KernelError(
                f"{self.name}: callback {name} raised at t={self.now_ns} ns: "
                f"{type(exc).__name__}: {exc}", self.now_ns, name) from exc
        self.events_run += n
        self.now_ns = until_ns

    def _run_slow(self, until_ns: int) -> None:
        q = self._queue
        while q and q[0][0] <= until_ns:
            entry = _heappop(q)
            fn = entry[3]
            if fn is None:
                continue
            self.now_ns = entry[0]
            self._dispatch(entry, fn)
            if self._stop:
                return
        self.now_ns = until_ns

    def run_for(self, duration_ns: int) -> None:
        """Run for ``duration_ns`` of virtual time from now."""
        self.run(self.now_ns + duration_ns)

    @property
    def context_ns(self) -> int:
        """Virtual time inside the running context: event time plus time blocked on buses."""
        return self.now_ns + self.busy_ns

    @property
    def now_us(self) -> int:
        return self.now_ns // NS_PER_US

    def __len__(self) -> int:
        return sum(1 for e in self._queue if e[3] is not None)

    def __repr__(self) -> str:
        return f"<Kernel {self.name} t={self.now_ns} ns, {len(self)} pending>"


def call_in_isr(kernel: Kernel, fn: Callable[..., Any], *args: Any) -> Any:
    """Call ``fn(*args)`` with ``kernel.in_isr`` set, restoring the previous value afterwards.

    Interrupt handlers must know they run in interrupt context (no blocking bus transfers in
    PX4 style drivers, no sleeping); nested use keeps the flag right. Every peripheral's
    interrupt (UART, CAN, timers, EXTI) goes through this.
    """
    prev = kernel.in_isr
    kernel.in_isr = True
    try:
        return fn(*args)
    finally:
        kernel.in_isr = prev
