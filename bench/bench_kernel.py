"""Kernel throughput: events per second with 16 self-rescheduling timers in the heap."""

from __future__ import annotations

from bench._util import median_rate
from board.kernel import Kernel

N_EVENTS = 300_000


def _run() -> int:
    k = Kernel("bench")
    remaining = [N_EVENTS]

    def make(period_ns: int):
        def tick() -> None:
            if remaining[0] > 0:
                remaining[0] -= 1
                k.call_later(period_ns, tick)
        return tick

    for i in range(16):
        k.call_later(i, make(1000 + 37 * i))
    k.run(1 << 62)
    return k.events_run


def bench_kernel_events_per_s() -> float:
    return median_rate(_run)


if __name__ == "__main__":
    print(f"kernel_events_per_s: {bench_kernel_events_per_s():,.0f}")
