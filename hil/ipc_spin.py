"""How a receiver of :mod:`hil.ipc` waits: spin, yield, then block (:class:`SpinPolicy`).

Kept apart from the channel itself because it is a policy the orchestrator chooses per board
(``hil.cpu_plan``, paced runs) while the ring layout and wake-up protocol never change.
"""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["SpinPolicy"]


@dataclass
class SpinPolicy:
    """How long a receiver busy-waits before blocking on the semaphore.

    Spinning saves the wake-up latency of a sleeping process, which on the target VM is 30-40 us
    (waking an idle virtual CPU), far more than the message itself costs. But with three
    processes on two cores a spinner may hold a core somebody else needs, so the spin loop calls
    ``os.sched_yield()`` between rounds (``yield_cpu``): a runnable process on the same core gets
    it at once, and the spin costs nothing when the core would otherwise be idle.

    ``adaptive``: spin only while the recent waits (exponential average of the *true* wait, i.e.
    the time from starting to wait until the sender published, taken from the sender's
    timestamp, so blocking does not bias it) are below ``max_us``. When waits are long (paced
    runs, slow boards) the receiver blocks at once instead of burning ``max_us`` per message.
    ``max_us == 0`` gives pure blocking. ``adaptive=False`` always spins up to ``max_us``.

    Default 200 us, adaptive, yielding. With empty boards, 50, 200 and 1000 us were
    indistinguishable in the noise (20-35 us per quantum); pure blocking was 4x slower and
    spinning without yield 4x slower too. 200 us is chosen for real boards: the orchestrator
    waiting for a board that computes a few hundred microseconds per quantum keeps its vCPU
    awake instead of paying the ~35 us idle wake-up, while paced runs (waits near the quantum,
    1 ms) and slow boards fall back to blocking and cost no CPU. Caveat: with Linux's EEVDF
    scheduler ``sched_yield`` only pushes the yielder's deadline back, so two spinners sharing
    a core occasionally stall each other for a scheduler slice (p99.9 of a few ms per quantum);
    pinning the boards away from the orchestrator removes most of it but is the orchestrator's
    decision, not the transport's.
    """

    max_us: float = 200.0
    adaptive: bool = True
    yield_cpu: bool = True
    #: weight of the newest wait in the running average
    alpha: float = 0.125
    #: head checks between two yields (each ~60 ns)
    round_checks: int = 32
    _avg_us: float = field(default=0.0, repr=False)

    def budget_s(self) -> float:
        """Spin budget for the next wait, in seconds."""
        if self.adaptive and self._avg_us > self.max_us:
            return 0.0
        return self.max_us * 1e-6

    def observe(self, waited_us: float) -> None:
        """Feed the true duration of a completed wait, in microseconds."""
        # Clamp so that one long pause (start-up, a slow quantum) moves the average by a bounded
        # amount: it takes a run of long waits, not a single one, to stop spinning.
        w = min(max(waited_us, 0.0), 4.0 * self.max_us + 1.0)
        self._avg_us += self.alpha * (w - self._avg_us)
