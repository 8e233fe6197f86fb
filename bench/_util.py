"""Timing helpers for benchmarks (the only place besides hil/ that reads the wall clock)."""

from __future__ import annotations

import statistics
import time
from typing import Callable


def median_rate(run: Callable[[], int], runs: int = 5) -> float:
    """Median over ``runs`` of (work units done by ``run()``) / (seconds it took)."""
    rates = []
    for _ in range(runs):
        t0 = time.perf_counter()
        n = run()
        rates.append(n / (time.perf_counter() - t0))
    return statistics.median(rates)


def median_seconds(run: Callable[[], object], runs: int = 5) -> float:
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        run()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)
