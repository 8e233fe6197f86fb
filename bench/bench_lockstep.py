"""Lockstep cost: the orchestrator with two empty board processes, with and without the world."""

from __future__ import annotations

import statistics
import time

from hil.orchestrator import BoardSpec, Orchestrator
from hil.worldlink import WorldPorts

MS = 1_000_000
NS_PER_S = 1_000_000_000


def _empty_boards() -> dict[str, BoardSpec]:
    return {"fmu": BoardSpec("board.stock:EmptyBoard", {"name": "fmu"}),
            "io": BoardSpec("board.stock:EmptyBoard", {"name": "io"})}


def _measure(world: bool, virtual_s: float, runs: int = 5) -> list[float]:
    """Wall seconds per virtual second, per run (one system, warmed up first)."""
    results = []
    with Orchestrator(_empty_boards(), world=WorldPorts() if world else None,
                      quantum_ns=MS) as orch:
        orch.run(duration_ns=200 * MS)  # warm-up: spin policies settle, caches fill
        for _ in range(runs):
            t0 = time.perf_counter()
            orch.run(duration_ns=int(virtual_s * NS_PER_S))
            results.append((time.perf_counter() - t0) / virtual_s)
    return results


def bench_lockstep_overhead_us_per_quantum() -> float:
    per_s = statistics.median(_measure(world=False, virtual_s=4.0))
    return per_s * 1e6 / 1000  # 1000 quanta per virtual second


def bench_rtf_world_two_empty_boards() -> float:
    return 1.0 / statistics.median(_measure(world=True, virtual_s=4.0))


if __name__ == "__main__":
    print(f"lockstep_overhead_us_per_quantum: {bench_lockstep_overhead_us_per_quantum():.1f}")
    print(f"rtf_world_two_empty_boards: {bench_rtf_world_two_empty_boards():.1f}")
