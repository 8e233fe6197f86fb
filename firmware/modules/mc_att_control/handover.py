"""Bumpless hand-over between attitude controllers swapped in flight.

Issue 23: one attitude controller may replace another in flight (``mc_att_control stop;
mc_att_control_so3 start`` from the shell, or ``MC_ATT_IMPL`` through ``mc_att_select``).
The rate controller downstream keeps running, so what it must not see is a step or a pause in
``vehicle_rates_setpoint``. Two laws give different rates for the same attitude error (they
agree to first order only), so the newcomer takes the last rate setpoint of the old controller
from uORB (still there: a late subscriber reads the latest message) and removes the
difference: a controller with an integrator starts its integrator at the difference
(back-calculation, the textbook bumpless transfer of a PID), a memoryless one adds the
difference as an offset that fades with ``HANDOVER_TAU_S``.

It also measures what a swap costs and says it once, on the first output: how long the rate
setpoint went without a new message (the gap) and how far the first output is from the last
one (the step), so a flight log shows both.
"""

from __future__ import annotations

import math
from typing import Any, Final

__all__ = ["ATT_CONTROLLERS", "HANDOVER_MAX_AGE_US", "HANDOVER_TAU_S", "Handover",
           "other_att_controller"]

#: the attitude controllers by their MC_ATT_IMPL number: at most one may run
ATT_CONTROLLERS: Final[dict[int, str]] = {0: "mc_att_control", 1: "mc_att_control_so3",
                                          2: "mc_att_companion"}

#: a previous rate setpoint older than this is not continued from (the old controller
#: stopped long ago, or there was none): 25 attitude periods at 250 Hz
HANDOVER_MAX_AGE_US: Final = 100_000
#: the fade of a memoryless controller's hand-over offset: 0.2 s, five times the attitude
#: loop's time constant (1 / MC_ROLL_P ~ 0.15 s), so the fade is slow against the loop and
#: leaves no step of its own
HANDOVER_TAU_S: Final = 0.2


def other_att_controller(modules: Any, me: str) -> str | None:
    """The attitude controller other than ``me`` running now, if any: two would publish
    competing rate setpoints, so a start refuses while another runs (stop it on the same
    line, or set MC_ATT_IMPL)."""
    return next((n for n in ATT_CONTROLLERS.values() if n != me and modules.is_running(n)),
                None)


class Handover:
    """The previous controller's last rate setpoint, and the fading offset toward it."""

    __slots__ = ("prev", "gap_us", "active", "t0_us", "off")

    def __init__(self) -> None:
        self.prev: Any = None
        self.gap_us = -1
        self.active = False
        self.t0_us = 0
        self.off = (0.0, 0.0, 0.0)

    def take(self, last: Any, now_us: int) -> bool:
        """Keep ``last`` (the latest vehicle_rates_setpoint before our first output) if it is
        recent enough to continue from; returns whether it is."""
        if last is None:
            return False
        gap = now_us - int(last.timestamp)
        if gap < 0 or gap > HANDOVER_MAX_AGE_US:
            return False
        self.prev = last
        self.gap_us = gap
        return True

    def difference(self, roll: float, pitch: float, yaw: float) -> tuple[float, float, float]:
        """Previous minus this output, per axis (rad/s)."""
        p = self.prev
        return (float(p.roll) - roll, float(p.pitch) - pitch, float(p.yaw) - yaw)

    def start_offset(self, off: tuple[float, float, float], now_us: int) -> None:
        """Fade ``off`` (rad/s per axis) out from ``now_us`` (a memoryless law's bumpless start)."""
        self.off = off
        self.t0_us = now_us
        self.active = True

    def apply(self, roll: float, pitch: float, yaw: float, now_us: int
              ) -> tuple[float, float, float]:
        """The rates with the fading offset added; the offset ends after five time constants."""
        t = (now_us - self.t0_us) * 1e-6
        if t >= 5.0 * HANDOVER_TAU_S:
            self.active = False
            return roll, pitch, yaw
        k = math.exp(-t / HANDOVER_TAU_S)
        o = self.off
        return roll + k * o[0], pitch + k * o[1], yaw + k * o[2]

    def report(self, roll: float, pitch: float, yaw: float, law_step: float) -> str:
        """The log line of the first output: gap, step left, and the step the laws alone gave."""
        dr, dp, dy = self.difference(roll, pitch, yaw)
        step = math.sqrt(dr * dr + dp * dp + dy * dy)
        return (f"took over: first rate setpoint {self.gap_us / 1000:.1f} ms after the last, "
                f"step {step:.4f} rad/s (laws differ by {law_step:.4f})")
