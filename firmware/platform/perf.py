"""Performance counters (PX4's ``perf_counter_t``): counts, elapsed times and intervals.

Elapsed and interval counters measure virtual time, so they are deterministic and describe the
emulated STM32 (time blocked on buses, modelled CPU time), not the host.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Final

if TYPE_CHECKING:
    from firmware.platform.hrt import Hrt

__all__ = ["PerfCounter", "PerfRegistry", "PC_COUNT", "PC_ELAPSED", "PC_INTERVAL"]

PC_COUNT: Final = "count"
PC_ELAPSED: Final = "elapsed"
PC_INTERVAL: Final = "interval"


class PerfCounter:
    """One counter. ``count()`` for events; ``begin()``/``end()`` for elapsed time; ``count()``
    on an interval counter records the time since the previous call.

    Statistics (min, max, mean, standard deviation) come from the count, sum and sum of
    squares of the samples: integers for the integer microseconds of virtual time, so they are
    exact however long the run, and a sample costs a few additions (no division) -- drivers hit
    their counters on every cycle.
    """

    __slots__ = ("name", "kind", "events", "_hrt", "_k", "_start_us", "_first_us", "_last_us",
                 "min_us", "max_us", "_n", "_sum", "_sumsq", "total_us", "count")

    def __init__(self, hrt: Hrt, kind: str, name: str) -> None:
        if kind not in (PC_COUNT, PC_ELAPSED, PC_INTERVAL):
            raise ValueError(f"perf counter {name!r}: unknown kind {kind!r}")
        self.name = name
        self.kind = kind
        self._hrt = hrt
        # The kernel itself: begin/end/count read the time inline (one attribute chain, no
        # call), since drivers hit them on every cycle.
        self._k = hrt.kernel
        # ``count`` is bound per kind once, so a count counter costs one increment and an
        # interval counter does not test its kind on every call.
        self.count = self._count_interval if kind == PC_INTERVAL else self._count_events
        self.reset()

    def reset(self) -> None:
        self.events = 0
        self._start_us = -1
        self._first_us = -1
        self._last_us = -1
        self._n = 0
        self.min_us = math.inf
        self.max_us = 0.0
        self._sum = 0  # integer microseconds: exact however long the run
        self._sumsq = 0
        self.total_us = 0

    def _sample(self, value_us: int) -> None:
        self._n += 1
        if value_us < self.min_us:
            self.min_us = float(value_us)
        if value_us > self.max_us:
            self.max_us = float(value_us)
        self._sum += value_us
        self._sumsq += value_us * value_us

    def _count_events(self) -> None:
        self.events += 1

    def _count_interval(self) -> None:
        self.events += 1
        k = self._k
        now = (k.now_ns + k.busy_ns) // 1000
        if self._first_us < 0:
            self._first_us = now
        else:
            self._sample(now - self._last_us)
            self.total_us = now - self._first_us
        self._last_us = now

    def begin(self) -> None:
        k = self._k
        self._start_us = (k.now_ns + k.busy_ns) // 1000

    def end(self) -> None:
        start = self._start_us
        if start < 0:
            return
        k = self._k
        v = (k.now_ns + k.busy_ns) // 1000 - start
        self._start_us = -1
        self.events += 1
        self.total_us += v
        self._sample(v)

    def cancel(self) -> None:
        self._start_us = -1

    def set_elapsed(self, elapsed_us: int) -> None:
        """Record one elapsed-time sample measured elsewhere."""
        self.events += 1
        self.total_us += elapsed_us
        self._sample(elapsed_us)

    @property
    def mean_us(self) -> float:
        n = self._n
        return self._sum / n if n else 0.0

    @property
    def stddev_us(self) -> float:
        """Population standard deviation (n * sumsq - sum^2 is exact for integer samples)."""
        n = self._n
        if n < 2:
            return 0.0
        return math.sqrt(max(0, n * self._sumsq - self._sum * self._sum)) / n

    def summary(self) -> str:
        if self.kind == PC_COUNT:
            return f"{self.name}: {self.events} events"
        if self.events == 0 or self.min_us == math.inf:
            return f"{self.name}: {self.events} events"
        if self.kind == PC_ELAPSED:
            return (f"{self.name}: {self.events} events, {self.total_us}us elapsed, "
                    f"{self.mean_us:.2f}us avg, min {self.min_us:.0f}us max {self.max_us:.0f}us "
                    f"{self.stddev_us:.3f}us rms")
        return (f"{self.name}: {self.events} events, {self.mean_us:.2f}us avg, "
                f"min {self.min_us:.0f}us max {self.max_us:.0f}us {self.stddev_us:.3f}us rms")


class PerfRegistry:
    """All counters of one board, in allocation order (``perf`` in the shell lists them)."""

    def __init__(self, hrt: Hrt) -> None:
        self.hrt = hrt
        self.counters: list[PerfCounter] = []

    def alloc(self, kind: str, name: str) -> PerfCounter:
        pc = PerfCounter(self.hrt, kind, name)
        self.counters.append(pc)
        return pc

    def free(self, pc: PerfCounter) -> None:
        if pc in self.counters:
            self.counters.remove(pc)

    def find(self, name: str) -> PerfCounter | None:
        for pc in self.counters:
            if pc.name == name:
                return pc
        return None

    def reset_all(self) -> None:
        for pc in self.counters:
            pc.reset()

    def report(self) -> str:
        return "\n".join(pc.summary() for pc in self.counters)
