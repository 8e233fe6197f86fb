"""Which CPUs the orchestrator and its board processes run on (``Orchestrator(isolate=...)``).

Only hil/ decides this: it changes how fast a run goes, never what it computes.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

__all__ = ["CpuPlan"]


class CpuPlan:
    """Which CPUs the orchestrator and its board processes may run on.

    One board (the FMU, which computes about as much as everything else together) gets a CPU
    of its own; the orchestrator and the other boards share the rest. Left to the scheduler on
    two cores, the three processes migrate, spinning waiters of :mod:`hil.ipc` land on the
    FMU's core, and the others block and pay semaphore wake-ups. With the FMU alone, a waiter's
    ``sched_yield`` only ever hands its core to the process it waits for, and the orchestrator
    lets waiters spin longer (:meth:`Orchestrator._spin_policy`): together worth ~1.3x on the
    default flight (docs/architecture.md, Lockstep). Results do not depend on it (lockstep is
    deterministic whatever runs where); only the wall clock does.

    Nothing is pinned when the orchestrator may use fewer than two CPUs, or when the system
    refuses (a container's CPU set, a platform without ``sched_setaffinity``): the run goes on
    unpinned and says why through ``log``. :meth:`restore` gives the orchestrator its CPUs
    back (it may be a test process that goes on with other work).
    """

    def __init__(self, isolate: str, board_cpus: set[int], shared_cpus: set[int],
                 original: set[int], log: Callable[[str], None]) -> None:
        self.isolate = isolate
        self.board_cpus = board_cpus
        self.shared_cpus = shared_cpus
        self.original = original
        self.log = log

    @classmethod
    def make(cls, isolate: str, log: Callable[[str], None] = lambda msg: None,
             cpus: set[int] | None = None) -> CpuPlan | None:
        """The plan for this process's CPUs (``cpus``: as if they were these), or None."""
        try:
            original = set(os.sched_getaffinity(0))
        except (AttributeError, OSError) as exc:
            log(f"hil: CPUs not pinned ({exc})")
            return None
        avail = sorted(cpus if cpus is not None else original)
        if len(avail) < 2:
            log("hil: CPUs not pinned (one CPU available)")
            return None
        return cls(isolate, {avail[-1]}, set(avail[:-1]), original, log)

    def cpus_for(self, board: str) -> set[int]:
        return self.board_cpus if board == self.isolate else self.shared_cpus

    def apply(self, handles: dict[str, Any]) -> None:
        """Pin these board processes and this process (the orchestrator) to their CPUs."""
        try:
            for name, handle in handles.items():
                pid = getattr(handle, "pid", None)
                if pid is not None:
                    os.sched_setaffinity(pid, self.cpus_for(name))
            os.sched_setaffinity(0, self.shared_cpus)
        except OSError as exc:
            self.log(f"hil: CPUs not pinned ({exc})")

    def restore(self) -> None:
        try:
            os.sched_setaffinity(0, self.original)
        except OSError:
            pass

    def describe(self) -> str:
        return (f"{self.isolate} on CPU {','.join(map(str, sorted(self.board_cpus)))}, "
                f"the rest on {','.join(map(str, sorted(self.shared_cpus)))}")
