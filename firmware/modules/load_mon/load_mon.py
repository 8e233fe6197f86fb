"""load_mon: ``cpuload`` at 2 Hz from the modelled CPU time, as PX4's load monitor publishes it.

PX4's load_mon (src/modules/load_mon) runs every 500 ms on the low-priority work queue and
publishes the share of that interval the CPU was not idle, and the heap's use. Here the STM32's
CPU time is what the work queues are modelled to spend: every work item run adds its declared
``cpu_cost_ns`` plus the bus time it waited for to its queue's ``busy_ns_total`` (the figure
``top`` shows per queue). The load over an interval is the growth of their sum divided by the
interval, capped at 1 (queues are modelled as threads that can overlap; the MCU has one core).
Interrupt handlers are not in it (they are not costed), and neither is RAM: there is no heap
model, so ``ram_usage`` is NaN rather than an invented figure.

The logger logs ``cpuload`` (PX4's default set has it), Flight Review plots it, and MAVLink's
SYS_STATUS ``load`` is ``cpuload.load`` in permille, as PX4's.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Final

from firmware.platform.module import WorkItemModule

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["INTERVAL_US", "LoadMonModule"]

#: PX4's load_mon interval (2 Hz)
INTERVAL_US: Final = 500_000


class LoadMonModule(WorkItemModule):
    NAME = "load_mon"
    DESCRIPTION = "processor load (modelled work-queue time) on cpuload at 2 Hz"
    WQ = "wq:lp_default"
    INTERVAL_US = INTERVAL_US
    CPU_COST_NS = 10_000

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self._last_busy_ns = 0
        self._last_ns = 0
        self.load = 0.0

    def _busy_ns(self) -> int:
        return sum(wq.busy_ns_total for wq in self.platform.wq)

    def _start(self) -> None:
        self._pub = self.advertise("cpuload")
        self._msg = self.platform.orb.new("cpuload")
        self._last_busy_ns = self._busy_ns()
        self._last_ns = self.platform.kernel.now_ns

    def run(self) -> None:
        now_ns = self.platform.kernel.now_ns
        busy = self._busy_ns()
        dt = now_ns - self._last_ns
        if dt <= 0:
            return
        self.load = min(1.0, (busy - self._last_busy_ns) / dt)
        self._last_busy_ns, self._last_ns = busy, now_ns
        m = self._msg
        m.timestamp = self.platform.time_us()
        m.load = self.load
        m.ram_usage = float("nan")
        self._pub.publish(m)

    def status_lines(self) -> list[str]:
        return [f"CPU load: {100.0 * self.load:.1f} % (modelled work-queue time, last "
                f"{INTERVAL_US // 1000} ms); RAM: not modelled"]
