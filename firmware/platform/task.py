"""Tasks and poll(): blocking-style code on a discrete-event kernel.

PX4 has two ways to run code: work items (run to completion, see workqueue.py) and tasks,
threads that block in ``px4_poll()`` or ``px4_usleep()``. A task here is a Python generator
that yields what it waits for::

    def main(task):
        sub = Subscription(task.platform.orb, "sensor_gyro")
        while not task.should_exit:
            n = yield task.poll([sub], timeout_ms=100)   # n = subscriptions with new data
            if n and sub.updated():
                gyro = sub.update()
            yield task.sleep_us(500)

The same waiting machinery (:class:`PollWaiter`) lets a work item wait on several topics with a
timeout and be scheduled when one of them publishes or the deadline passes.

Serial ports (:class:`firmware.platform.serial.SerialPort`) are pollable like topics, as on
NuttX where both are files: ``yield task.poll([sub, port], timeout_ms=10)`` wakes for a
publication or for bytes on the UART (the RX line's IDLE after a burst, or every half RX DMA
ring of a long stream), and ``n`` counts every ready item. A port keeps the same poll list a
topic node has (``node.callbacks``), so waiting on topics works exactly as before.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable, Generator, Sequence, Union

from board.kernel import NS_PER_US, PRIO_THREAD, KernelError
from firmware.platform.serial import SerialError, SerialPort
from firmware.platform.uorb import Subscription

if TYPE_CHECKING:
    from firmware.platform import Platform
    from firmware.platform.hrt import HrtCall

__all__ = ["Poll", "Pollable", "Sleep", "PollWaiter", "Task"]

#: What poll() waits on: a topic subscription or a serial port (both files on NuttX).
Pollable = Union[Subscription, SerialPort]


def _check_pollable(items: list[Pollable]) -> None:
    """A clear error for something poll() cannot wait on, or a closed port."""
    for s in items:
        if isinstance(s, Subscription):
            continue
        if isinstance(s, SerialPort):
            if s.closed:
                raise SerialError(f"poll on {s.device}: the port is closed")
            continue
        raise TypeError(f"poll() waits on Subscriptions and SerialPorts, not {s!r}")


class Poll:
    """What a task yields to wait for any of ``subs`` (topics, serial ports) to be ready, or
    ``timeout_us`` (< 0: never). Checked here, so bad use fails inside the task's code."""

    __slots__ = ("subs", "timeout_us")

    def __init__(self, subs: Sequence[Pollable], timeout_us: int) -> None:
        self.subs: list[Pollable] = list(subs)
        _check_pollable(self.subs)
        self.timeout_us = timeout_us


class Sleep:
    """What a task yields to sleep ``us`` microseconds of virtual time."""

    __slots__ = ("us",)

    def __init__(self, us: int) -> None:
        if us < 0:
            raise ValueError(f"sleep of negative time {us} us")
        self.us = us


class PollWaiter:
    """Wait until one of ``subs`` has new data or the timeout expires, then ``on_done(n)``.

    ``subs`` are subscriptions and serial ports. ``n`` is the number of items with unread data
    (0 means the timeout expired), as ``poll()`` returns. If data is already waiting,
    ``on_done`` runs at once (as a new event). ``on_done`` runs as a thread-priority event
    after the publisher's (or the UART interrupt's) context has finished.
    """

    __slots__ = ("platform", "subs", "on_done", "priority", "_done", "_timer", "_registered")

    def __init__(self, platform: Platform, subs: Sequence[Pollable], timeout_us: int,
                 on_done: Callable[[int], Any], priority: int = PRIO_THREAD) -> None:
        self.platform = platform
        self.subs: list[Pollable] = list(subs)
        _check_pollable(self.subs)
        self.on_done = on_done
        self.priority = priority
        self._done = False
        self._timer: HrtCall | None = None
        self._registered = False
        if any(s.updated() for s in self.subs) or timeout_us == 0:
            self._finish()
            return
        for s in self.subs:
            s.node.callbacks.append(self._wake)
        self._registered = True
        if timeout_us > 0:
            self._timer = platform.hrt.call_after(timeout_us, self._wake)

    def _wake(self) -> None:
        if not self._done:
            self._finish()

    def _finish(self) -> None:
        self._done = True
        k = self.platform.kernel
        k.post(k.now_ns + k.busy_ns, self.priority, self._resume, ())  # call_at, unchecked

    def _resume(self) -> None:
        # Callbacks are removed here, not in _wake, so a publisher's callback list is never
        # changed while it is being iterated.
        if self._registered:
            for s in self.subs:
                s.node.callbacks.remove(self._wake)
            self._registered = False
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None
        self.on_done(sum(1 for s in self.subs if s.updated()))

    def cancel(self) -> None:
        self._done = True
        if self._registered:
            for s in self.subs:
                s.node.callbacks.remove(self._wake)
            self._registered = False
        if self._timer is not None:
            self._timer.cancel()
            self._timer = None


class Task:
    """A generator-based thread of the flight stack (``px4_task_spawn_cmd``)."""

    def __init__(self, platform: Platform, name: str,
                 main: Callable[[Task], Generator[Any, Any, Any]], priority: int = 0) -> None:
        self.platform = platform
        self.name = name
        self.priority = priority
        self._kprio = PRIO_THREAD - priority
        self._main = main
        self._gen: Generator[Any, Any, Any] | None = None
        self.should_exit = False
        self.running = False
        self.result: Any = None

    # -- what a task yields ---------------------------------------------------------------

    @staticmethod
    def poll(subs: Sequence[Pollable], timeout_ms: int) -> Poll:
        return Poll(subs, timeout_ms * 1000 if timeout_ms >= 0 else -1)

    @staticmethod
    def sleep_us(us: int) -> Sleep:
        return Sleep(us)

    # -- life cycle -------------------------------------------------------------------------

    def start(self) -> None:
        if self.running:
            raise RuntimeError(f"task {self.name} already running")
        self._gen = self._main(self)
        self.running = True
        k = self.platform.kernel
        k.call_at(k.now_ns + k.busy_ns, self._step, None, priority=self._kprio)

    def request_stop(self) -> None:
        self.should_exit = True

    def _step(self, value: Any) -> None:
        if not self.running or self._gen is None:
            return
        k = self.platform.kernel
        try:
            req = self._gen.send(value)
        except StopIteration as stop:
            self.running = False
            self.result = stop.value
            return
        except KernelError:
            raise
        except Exception as exc:
            self.running = False
            raise KernelError(f"{k.name}: task {self.name} raised at t={k.now_ns} ns: "
                              f"{type(exc).__name__}: {exc}", k.now_ns, self.name) from exc
        t = k.now_ns + k.busy_ns
        if isinstance(req, Poll):
            PollWaiter(self.platform, req.subs, req.timeout_us, self._step, self._kprio)
        elif isinstance(req, Sleep):
            k.call_at(t + req.us * NS_PER_US, self._step, None, priority=self._kprio)
        elif req is None:
            k.call_at(t, self._step, None, priority=self._kprio)
        else:
            self.running = False
            raise KernelError(f"{k.name}: task {self.name} yielded {req!r}; expected "
                              f"task.poll(...), task.sleep_us(...) or None", k.now_ns, self.name)
