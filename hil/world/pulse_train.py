"""What an ESC and a servo share: a servo-PWM signal wire, as the PWM timer drives it.

``set_signal(t_ns, high_ns, period_ns)`` says "from t_ns on, a pulse of high_ns every
period_ns" (what a timer's compare registers do until changed). Records from the boards arrive
stamped, possibly ahead of the world's clock within a quantum, so they wait in ``_pending``
(sorted by time) until the world's step reaches them; each kind of receiver decides in
``_apply`` what a train means to it (a throttle, a position) and whether it is valid.
"""

from __future__ import annotations

import bisect

__all__ = ["PulseTrainInput"]


class PulseTrainInput:
    """Base of the world's PWM receivers: the pending signal changes and the last valid width."""

    __slots__ = ("_pending", "_valid", "_width_us")

    def __init__(self) -> None:
        self._pending: list[tuple[int, int, int]] = []  # (t_ns, high_ns, period_ns), sorted
        self._valid = False
        self._width_us = 0.0

    def set_signal(self, t_ns: int, high_ns: int, period_ns: int) -> None:
        """From t_ns on the signal is a pulse of high_ns every period_ns (0 high: line low)."""
        ev = (int(t_ns), int(high_ns), int(period_ns))
        pend = self._pending
        if not pend or pend[-1][0] <= ev[0]:
            pend.append(ev)
        else:
            bisect.insort(pend, ev)

    @property
    def signal_valid(self) -> bool:
        return self._valid

    @property
    def pulse_us(self) -> float:
        """Width of the current valid pulse train (us), 0 if none."""
        return self._width_us if self._valid else 0.0

    def _apply_due(self, t_ns: int) -> None:
        """Apply, in time order, the signal changes stamped at or before ``t_ns``."""
        pend = self._pending
        i = 0
        n = len(pend)
        while i < n and pend[i][0] <= t_ns:
            ev_t, high_ns, period_ns = pend[i]
            self._apply(ev_t, high_ns, period_ns)
            i += 1
        del pend[:i]

    def _apply(self, ev_t: int, high_ns: int, period_ns: int) -> None:  # pragma: no cover
        raise NotImplementedError
