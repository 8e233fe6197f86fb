"""Performance counters (PX4's ``perf_counter_t``): counts, elapsed times and intervals.

Elapsed and interval counters measure virtual time, so they are deterministic and describe the
emulated STM32 (time blocked on buses, modelled CPU time), not the host.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from firmware.platform.hrt import Hrt

__all__ = ["PerfCounter", "PerfRegistry", "PC_COUNT", "PC_ELAPSED", "PC_INTERVAL"]

PC_COUNT = "count"
PC_ELAPSED = "elapsed"
PC_INTERVAL = "interval"


class PerfCounter:
    """One counter. ``count()`` for events; ``begin()``/``end()`` for elapsed time; ``count()``
    on an interval counter records the time since the previous call.

    Statistics (min, max, mean, standard deviation) use Welford's running update so a counter
    hit 8000 times a second stays exact and cheap.
    """

    __slots__ = ("name", "kind", "events", "_hrt", "_start_us", "_first_us", "_last_us",
                 "min_us", "max_us", "_n", "_mean", "_m2", "total_us")

    def __init__(self, hrt: Hrt, kind: str, name: str) -> None:
        if kind not in (PC_COUNT, PC_ELAPSED, PC_INTERVAL):
            raise ValueError(f"perf counter {name!r}: unknown kind {kind!r}")
        self.name = name
        self.kind = kind
        self._hrt = hrt
        self.reset()

    def reset(self) -> None:
        self.events = 0
        self._start_us = -1
        self._first_us = -1
        self._last_us = -1
        self._n = 0
        self.min_us = math.inf
        self.max_us = 0.0
        self._mean = 0.0
        self._m2 = 0.0
        self.total_us = 0

    def _sample(self, value_us: float) -> None:
        self._n = n = self._n + 1
        if value_us < self.min_us:
            self.min_us = value_us
        if value_us > self.max_us:
            self.max_us = value_us
        delta = value_us - self._mean
        self._mean += delta / n
        self._m2 += delta * (value_us - self._mean)

    def count(self) -> None:
        self.events += 1
        if self.kind != PC_INTERVAL:
            return
        now = self._hrt.absolute_time()
        if self._first_us < 0:
            self._first_us = now
        else:
            self._sample(now - self._last_us)
            self.total_us = now - self._first_us
        self._last_us = now

    def begin(self) -> None:
        self._start_us = self._hrt.absolute_time()

    def end(self) -> None:
        if self._start_us < 0:
            return
        self.set_elapsed(self._hrt.absolute_time() - self._start_us)
        self._start_us = -1

    def cancel(self) -> None:
        self._start_us = -1

    def set_elapsed(self, elapsed_us: int) -> None:
        """Record one elapsed-time sample measured elsewhere."""
        self.events += 1
        self.total_us += elapsed_us
        self._sample(elapsed_us)

    @property
    def mean_us(self) -> float:
        return self._mean

    @property
    def stddev_us(self) -> float:
        n = self._n
        return math.sqrt(self._m2 / n) if n > 1 else 0.0

    def summary(self) -> str:
        if self.kind == PC_COUNT:
            return f"{self.name}: {self.events} events"
        if self.events == 0 or self.min_us == math.inf:
            return f"{self.name}: {self.events} events"
        if self.kind == PC_ELAPSED:
            return (f"{self.name}: {self.events} events, {self.total_us}us elapsed, "
                    f"{self._mean:.2f}us avg, min {self.min_us:.0f}us max {self.max_us:.0f}us "
                    f"{self.stddev_us:.3f}us rms")
        return (f"{self.name}: {self.events} events, {self._mean:.2f}us avg, "
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
