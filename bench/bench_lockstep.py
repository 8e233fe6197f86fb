"""Lockstep cost: the orchestrator with two board processes, with and without the world.

Two kinds of "empty" board: truly empty ones (nothing ever due, so the orchestrator skips their
exchanges) and ticking ones (a 1 kHz timer, so every quantum is a real exchange with both
processes). The overhead figure uses ticking boards: it is the synchronisation cost every
real board pays per quantum.
"""

from __future__ import annotations

import statistics
import time

from hil.orchestrator import BoardSpec, Orchestrator
from hil.worldlink import WorldPorts

MS = 1_000_000
NS_PER_S = 1_000_000_000


def _boards(tick_us: int) -> dict[str, BoardSpec]:
    return {"fmu": BoardSpec("board.stock:EmptyBoard", {"name": "fmu", "tick_us": tick_us}),
            "io": BoardSpec("board.stock:EmptyBoard", {"name": "io", "tick_us": tick_us})}


def _measure(world: bool, virtual_s: float, tick_us: int = 0, runs: int = 5) -> list[float]:
    """Wall seconds per virtual second, per run (one system, warmed up first)."""
    results = []
    with Orchestrator(_boards(tick_us), world=WorldPorts() if world else None,
                      quantum_ns=MS) as orch:
        orch.run(duration_ns=200 * MS)  # warm-up: spin policies settle, caches fill
        for _ in range(runs):
            t0 = time.perf_counter()
            orch.run(duration_ns=int(virtual_s * NS_PER_S))
            results.append((time.perf_counter() - t0) / virtual_s)
    return results


def bench_lockstep_overhead_us_per_quantum() -> float:
    per_s = statistics.median(_measure(world=False, virtual_s=4.0, tick_us=1000))
    return per_s * 1e6 / 1000  # 1000 quanta per virtual second


def bench_rtf_world_two_empty_boards() -> float:
    return 1.0 / statistics.median(_measure(world=True, virtual_s=4.0))


def bench_rtf_world_two_ticking_boards() -> float:
    return 1.0 / statistics.median(_measure(world=True, virtual_s=4.0, tick_us=1000))


if __name__ == "__main__":
    print(f"lockstep_overhead_us_per_quantum: {bench_lockstep_overhead_us_per_quantum():.1f}")
    print(f"rtf_world_two_empty_boards: {bench_rtf_world_two_empty_boards():.1f}")
    print(f"rtf_world_two_ticking_boards: {bench_rtf_world_two_ticking_boards():.1f}")
