"""Work queues and work items, in PX4's shape.

A work queue is a thread on the real FMU; here it is a dispatcher on the board kernel that runs
its queued items one at a time, in FIFO order, at thread priority. A work item's ``run()`` goes
to completion; the virtual time it took (time blocked on buses, plus the CPU time the item
declares it models) keeps its queue busy, so the next item on that queue starts that much later.
Queues of higher priority run first when several are due at the same instant.

Items schedule themselves PX4-style: ``schedule_now()``, ``schedule_delayed(us)``,
``schedule_on_interval(us)``, ``schedule_clear()``; a uORB callback subscription calls
``schedule_now()`` on publication.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Final

from mypy_extensions import mypyc_attr

from board.kernel import PRIO_THREAD, Kernel, KernelError

if TYPE_CHECKING:
    from firmware.platform import Platform
    from firmware.platform.hrt import HrtCall

__all__ = ["WqConfig", "WQ_CONFIGS", "WorkQueue", "WorkQueueManager", "WorkItem"]


@dataclass(frozen=True)
class WqConfig:
    name: str
    stack_bytes: int
    priority: int  # relative to the maximum, as in PX4: 0 is the highest, more negative is lower


def _table() -> dict[str, WqConfig]:
    rows: list[tuple[str, int, int]] = [("wq:rate_ctrl", 3150, 0)]
    rows += [(f"wq:SPI{i}", 2392, -1 - i) for i in range(7)]
    rows += [(f"wq:I2C{i}", 2336, -8 - i) for i in range(5)]
    rows += [("wq:nav_and_controllers", 2240, -13)]
    rows += [(f"wq:INS{i}", 6000, -14 - i) for i in range(4)]
    rows += [("wq:hp_default", 1900, -18), ("wq:uavcan", 3624, -19)]
    rows += [(f"wq:ttyS{i}", 1632, -21) for i in range(10)]
    rows += [("wq:lp_default", 1920, -50), ("wq:test1", 2000, 0), ("wq:test2", 2000, 0)]
    return {name: WqConfig(name, stack, prio) for name, stack, prio in rows}


#: PX4's work queue table: name, stack size, relative priority.
WQ_CONFIGS: Final[dict[str, WqConfig]] = _table()


class WorkQueue:
    """One work queue: a FIFO of items run to completion at this queue's thread priority."""

    __slots__ = ("kernel", "config", "name", "_q", "_armed", "busy_until_ns", "_kprio",
                 "items", "run_count", "busy_ns_total", "_disp")

    def __init__(self, kernel: Kernel, config: WqConfig) -> None:
        self.kernel = kernel
        self.config = config
        self.name = config.name
        self._q: deque[WorkItem] = deque()
        self._armed = False
        self.busy_until_ns = 0
        # Lower kernel priority values run first; PX4's 0 is the highest thread priority.
        self._kprio = PRIO_THREAD - config.priority
        self.items: list[WorkItem] = []
        self.run_count = 0
        self.busy_ns_total = 0
        # The bound dispatcher, made once: one dispatch event per work item run, the
        # platform's most frequent event, posted through Kernel.post (the kernel is the only
        # writer of its heap).
        self._disp = self._dispatch

    def add(self, item: WorkItem) -> None:
        if item._queued:
            return
        item._queued = True
        self._q.append(item)
        if not self._armed:
            self._armed = True
            k = self.kernel
            t = k.now_ns + k.busy_ns
            if self.busy_until_ns > t:
                t = self.busy_until_ns
            k.post(t, self._kprio, self._disp, ())

    def remove(self, item: WorkItem) -> None:
        if item._queued:
            self._q.remove(item)
            item._queued = False

    def _dispatch(self) -> None:
        k = self.kernel
        q = self._q
        try:
            item = q.popleft()
        except IndexError:
            # every queued item was removed (a module stopped) after this dispatch was posted
            self._armed = False
            return
        item._queued = False
        try:
            item.entry()
        except KernelError:
            raise
        except Exception as exc:
            raise KernelError(
                f"{k.name}: work item {item.name} on {self.name} raised at t={k.now_ns} ns: "
                f"{type(exc).__name__}: {exc}", k.now_ns, item.name) from exc
        cost = k.busy_ns + item.cpu_cost_ns
        item.run_count += 1
        item.busy_ns_total += cost
        self.run_count += 1
        self.busy_ns_total += cost
        self.busy_until_ns = t = k.now_ns + cost
        if q:
            k.post(t, self._kprio, self._disp, ())
        else:
            self._armed = False

    def __len__(self) -> int:
        return len(self._q)


class WorkQueueManager:
    """The board's work queues, created on first use from :data:`WQ_CONFIGS`."""

    def __init__(self, kernel: Kernel) -> None:
        self.kernel = kernel
        self.queues: dict[str, WorkQueue] = {}

    def get(self, name: str) -> WorkQueue:
        wq = self.queues.get(name)
        if wq is None:
            try:
                config = WQ_CONFIGS[name]
            except KeyError:
                raise ValueError(f"unknown work queue {name!r}; known: "
                                 f"{', '.join(sorted(WQ_CONFIGS))}") from None
            wq = self.queues[name] = WorkQueue(self.kernel, config)
        return wq

    def __iter__(self):
        return iter(sorted(self.queues.values(), key=lambda q: -q.config.priority))


@mypyc_attr(allow_interpreted_subclasses=True)
class WorkItem:
    """Base class of drivers and modules: override :meth:`run`.

    ``cpu_cost_ns`` is the CPU time one run is modelled to take on the STM32 (it adds to the
    queue's busy time and to the modelled load shown by ``top``); bus time is added on its own.
    """

    cpu_cost_ns: int = 0

    def __init__(self, platform: Platform, name: str, wq: str) -> None:
        self.platform = platform
        self.name = name
        self.wq = platform.wq.get(wq)
        self.wq.items.append(self)
        self._queued = False
        self._hrt_call: HrtCall | None = None
        self.run_count = 0
        self.busy_ns_total = 0
        #: What the dispatcher calls: ``run`` itself, unless the owner points it elsewhere (a
        #: module's bound ``run``, a profiling wrapper). An attribute, not a reassigned
        #: method, so that compiled classes (hil.native) can hold it too.
        self.entry: Callable[[], None] = self.run
        #: Host-time accumulator of a profiled item (firmware.system), else None.
        self.host_prof: list[float] | None = None

    def run(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError(f"{type(self).__name__}.run")

    # -- scheduling (PX4 names in snake_case) -----------------------------------------------

    def schedule_now(self) -> None:
        self.wq.add(self)

    def schedule_delayed(self, delay_us: int) -> None:
        """Run once, ``delay_us`` from now (replacing any pending delayed/interval schedule)."""
        c = self._hrt_call
        if c is not None and not c.period_us and delay_us >= 0:
            c.rearm_after(delay_us)  # drivers re-arm a watchdog every cycle: reuse the call
            return
        self._cancel_hrt()
        self._hrt_call = self.platform.hrt.call_after(delay_us, self.wq.add, self)

    def schedule_at(self, t_us: int) -> None:
        self._cancel_hrt()
        self._hrt_call = self.platform.hrt.call_at(t_us, self.wq.add, self)

    def schedule_on_interval(self, interval_us: int, delay_us: int = 0) -> None:
        """Run every ``interval_us``, first after ``delay_us`` (or one interval if 0)."""
        self._cancel_hrt()
        first = delay_us if delay_us > 0 else interval_us
        self._hrt_call = self.platform.hrt.call_every(first, interval_us, self.wq.add, self)

    def schedule_clear(self) -> None:
        """Cancel pending delayed/interval runs and a queued run."""
        self._cancel_hrt()
        self.wq.remove(self)

    def _cancel_hrt(self) -> None:
        if self._hrt_call is not None:
            self._hrt_call.cancel()
            self._hrt_call = None

    @property
    def scheduled(self) -> bool:
        return self._queued or (self._hrt_call is not None and self._hrt_call.pending)

    @property
    def interval_us(self) -> int:
        c = self._hrt_call
        return c.period_us if c is not None and c.pending else 0

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name} on {self.wq.name}>"
