"""The safety switch on the GPS mast: a push button wired to the IO's PB5.

A host device owning the ``safety_button`` port. ``press(t_ns, hold_s)`` schedules the button
down at ``t_ns`` and up ``hold_s`` later (the IO toggles safety after holding ~1 s). Like the
RC transmitter it plays a timeline fixed before the run, so the hub may run it ahead.
"""

from __future__ import annotations

from typing import Any

__all__ = ["SafetySwitch"]


class SafetySwitch:
    runs_ahead = True

    def __init__(self, port: str = "safety_button") -> None:
        self.port = port
        self.ports = (port,)
        self._events: list[tuple[int, int]] = []  # (t_ns, level), kept sorted
        self._t_ns = 0
        self.presses = 0

    def press(self, t_ns: int, hold_s: float = 1.5) -> None:
        """Hold the button down from ``t_ns`` for ``hold_s`` seconds."""
        if t_ns < self._t_ns:
            raise ValueError(f"safety switch: press at {t_ns} ns is in the past "
                             f"({self._t_ns} ns already played)")
        self._events += [(t_ns, 1), (t_ns + int(hold_s * 1e9), 0)]
        self._events.sort()
        self.presses += 1

    def run_until(self, t_ns: int) -> None:
        self._t_ns = t_ns

    def outputs(self, until_ns: int) -> list:
        out = []
        while self._events and self._events[0][0] <= until_ns:
            t, level = self._events.pop(0)
            out.append((self.port, t, level))
        return out

    def input(self, port: str, t_ns: int, payload: Any) -> None:
        raise ValueError(f"the safety switch has no input port {port!r}")
