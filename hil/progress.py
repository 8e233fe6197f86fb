"""What a run is doing, printed as it goes: the progress lines of ``hil run``.

A flight spends its first virtual half-minute booting, waiting for a GPS fix and the
estimator, uploading the mission and arming; a user who sees nothing (or "real-time factor 0.0")
for that long cannot tell a slow run from a stuck one. So every line says what the run is doing
now, at which virtual time, and the real-time factor since the run started (virtual seconds per
wall second, boot included), and a line comes at least every few wall seconds even when nothing
changes. The reporter only reads the orchestrator's clock and prints: it never changes what
the boards compute, so a run with progress and one without write the same bytes.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, TextIO

__all__ = ["Progress"]

NS_PER_S = 1_000_000_000


class Progress:
    """Prints ``[  12.30 s] waiting for a GPS fix and the estimator  (real-time factor 2.4)``.

    :meth:`doing` names the current activity (printed at once), :meth:`event` a milestone;
    called every quantum (``orch.on_quantum``), it repeats the activity every
    ``every_wall_s`` wall seconds, so a long wait still shows the clock moving."""

    def __init__(self, enabled: bool = True, every_wall_s: float = 5.0,
                 out: TextIO | None = None,
                 clock: Callable[[], float] = time.perf_counter) -> None:
        self.enabled = enabled
        self.every_wall_s = every_wall_s
        self.out = out
        self.clock = clock
        self.wall0 = clock()
        self.activity = "starting"
        self.t_ns = 0
        self._next_wall = self.wall0 + every_wall_s

    def rtf(self) -> float:
        """Virtual seconds per wall second since this reporter was made (the run's start)."""
        wall = self.clock() - self.wall0
        return self.t_ns / NS_PER_S / wall if wall > 0 else 0.0

    def line(self, text: str) -> str:
        return f"  [{self.t_ns / NS_PER_S:7.2f} s] {text}   (real-time factor {self.rtf():.1f})"

    def say(self, text: str) -> None:
        if self.enabled:
            print(self.line(text), file=self.out, flush=True)
        self._next_wall = self.clock() + self.every_wall_s

    def doing(self, activity: str) -> None:
        """Start an activity ("waiting for ..."): printed now and repeated while it lasts."""
        self.activity = activity
        self.say(activity)

    def event(self, text: str) -> None:
        """A milestone (a phase reached): printed once; the current activity goes on."""
        self.say(text)

    def __call__(self, orch: Any) -> None:
        self.t_ns = orch.t_ns
        if self.enabled and self.clock() >= self._next_wall:
            self.say(self.activity)
