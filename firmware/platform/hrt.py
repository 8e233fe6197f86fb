"""High-resolution timer: ``hrt_absolute_time()`` and callouts in interrupt context.

On the real FMU the HRT is a free-running 1 MHz timer whose compare interrupt fires callouts.
Here the board kernel is the timer: callouts are kernel events at interrupt priority, and the
absolute time is the kernel's virtual time in microseconds (as seen inside the running context,
so a driver that has been blocked on SPI for 112 us sees the time move by 112 us).
"""

from __future__ import annotations

from typing import Any, Callable

from board.kernel import NS_PER_US, PRIO_ISR, Event, Kernel

__all__ = ["Hrt", "HrtCall"]


class HrtCall:
    """One pending callout (PX4's ``struct hrt_call``): cancel it, or ask whether it fired."""

    __slots__ = ("hrt", "fn", "args", "deadline_us", "period_us", "_entry", "fired")

    def __init__(self, hrt: Hrt, fn: Callable[..., Any], args: tuple, deadline_us: int,
                 period_us: int) -> None:
        self.hrt = hrt
        self.fn = fn
        self.args = args
        self.deadline_us = deadline_us
        self.period_us = period_us
        self.fired = False
        self._entry: Event | None = None

    def _arm(self) -> None:
        k = self.hrt.kernel
        t_ns = self.deadline_us * NS_PER_US
        if t_ns < k.now_ns:
            t_ns = k.now_ns
        if type(t_ns) is not int:  # what call_at would refuse; post skips its checks
            raise TypeError(f"hrt: deadline must be an integer number of us, got "
                            f"{self.deadline_us!r}")
        # Drivers re-arm a watchdog every cycle, so this is a hot path: post, not call_at.
        self._entry = k.post(t_ns, PRIO_ISR, self._fire, ())

    def _fire(self) -> None:
        k = self.hrt.kernel
        t_ns = self.deadline_us * NS_PER_US
        if t_ns > k.now_ns:
            # The deadline was pushed later by :meth:`rearm_after` while this entry was
            # pending: move on to it instead of firing (one heap entry per watchdog period,
            # not one per re-arm).
            self._entry = k.post(t_ns, PRIO_ISR, self._fire, ())
            return
        self.fired = True
        if self.period_us:
            self.deadline_us += self.period_us
            self._arm()
        else:
            self._entry = None
        k.in_isr = True
        try:
            self.fn(*self.args)
        finally:
            k.in_isr = False

    def rearm_after(self, delay_us: int) -> None:
        """Make this one-shot call fire ``delay_us`` from now instead (PX4's re-arming of a
        watchdog with ``ScheduleDelayed``). A later deadline than the pending one only moves
        the deadline; the pending entry re-posts itself when it comes up."""
        k = self.hrt.kernel
        deadline = (k.now_ns + k.busy_ns) // NS_PER_US + delay_us
        e = self._entry
        if e is not None and Kernel.pending(e) and not self.period_us \
                and Kernel.due_ns(e) <= deadline * NS_PER_US:
            self.deadline_us = deadline
            return
        Kernel.cancel(e)
        self.deadline_us = deadline
        self.period_us = 0
        self.fired = False
        self._arm()

    def cancel(self) -> None:
        if self._entry is not None:
            Kernel.cancel(self._entry)
            self._entry = None

    @property
    def pending(self) -> bool:
        return Kernel.pending(self._entry)


class Hrt:
    """The board's high-resolution timer."""

    __slots__ = ("kernel",)

    def __init__(self, kernel: Kernel) -> None:
        self.kernel = kernel

    def absolute_time(self) -> int:
        """Microseconds since boot, as seen by the running context."""
        k = self.kernel
        return (k.now_ns + k.busy_ns) // NS_PER_US

    def elapsed_time(self, then_us: int) -> int:
        return self.absolute_time() - then_us

    def call_after(self, delay_us: int, fn: Callable[..., Any], *args: Any) -> HrtCall:
        """Call ``fn(*args)`` in interrupt context ``delay_us`` from now."""
        if delay_us < 0:
            raise ValueError(f"hrt call_after: negative delay {delay_us} us")
        k = self.kernel
        call = HrtCall(self, fn, args, (k.now_ns + k.busy_ns) // NS_PER_US + delay_us, 0)
        call._arm()
        return call

    def call_at(self, t_us: int, fn: Callable[..., Any], *args: Any) -> HrtCall:
        """Call ``fn(*args)`` at absolute time ``t_us`` (now, if that has passed, as PX4 does)."""
        call = HrtCall(self, fn, args, t_us, 0)
        call._arm()
        return call

    def call_every(self, delay_us: int, interval_us: int, fn: Callable[..., Any],
                   *args: Any) -> HrtCall:
        """Call ``fn(*args)`` after ``delay_us`` and then every ``interval_us``."""
        if interval_us <= 0:
            raise ValueError(f"hrt call_every: interval must be positive, got {interval_us} us")
        if delay_us < 0:
            raise ValueError(f"hrt call_every: negative delay {delay_us} us")
        call = HrtCall(self, fn, args, self.absolute_time() + delay_us, interval_us)
        call._arm()
        return call

    @staticmethod
    def cancel(call: HrtCall | None) -> None:
        if call is not None:
            call.cancel()
