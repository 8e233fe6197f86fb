"""The safety envelope a companion's rate setpoint must stay inside, as pure functions.

The companion computer is outside the FMU's control: its attitude law may be wrong, its
numbers may be garbage, its link may lie. What the FMU forwards to its rate controller must
therefore pass checks the FMU can make on its own, each naming what failed so the log line
says why the FMU took over:

- every number finite (a NaN in a rate setpoint would reach the motors through the PID);
- each body rate within the FMU's own limits (``MC_ROLLRATE_MAX`` ...), which the FMU's law
  obeys too: a rate beyond them is not clipped and flown, it is a sign of a broken law;
- the collective thrust within 0..1 (``thrust_body`` z in -1..0, x and y within -1..1);
- the vehicle's tilt within ``MC_CMP_ERR_MAX`` of the attitude setpoint: checked by the
  module over time (``tilt_error_rad`` here), since any law shows a large error for a moment
  after a step in the setpoint.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Final

from common.quaternion import Quat, body_z_ned

__all__ = ["AXES", "RATE_TOLERANCE", "rates_violation", "tilt_error_rad"]

#: the body axes and the parameter limiting each one's rate
AXES: tuple[tuple[str, str], ...] = (("roll", "MC_ROLLRATE_MAX"), ("pitch", "MC_PITCHRATE_MAX"),
                                     ("yaw", "MC_YAWRATE_MAX"))

#: a rate this much above the limit (relative) is still at the limit: float32 rounding
RATE_TOLERANCE: Final = 1.0 + 1e-6


def rates_violation(rates: Sequence[float], thrust_body: Sequence[float],
                    rate_max: Sequence[float]) -> str | None:
    """Why this rate setpoint (rad/s per axis, thrust in body axes) is outside the envelope,
    or None if it is inside. ``rate_max`` is rad/s per axis."""
    for (axis, _param), v in zip(AXES, rates):
        if not math.isfinite(v):
            return f"non-finite {axis} rate ({v})"
    for i, v in enumerate(thrust_body):
        if not math.isfinite(v):
            return f"non-finite thrust_body[{i}] ({v})"
    for (axis, param), v, lim in zip(AXES, rates, rate_max):
        # a companion at its own limit (the same parameter) is inside: its float32 message
        # may round the limit up by a few parts in 1e8
        if abs(v) > lim * RATE_TOLERANCE:
            return (f"{axis} rate {v:+.2f} rad/s beyond {param} "
                    f"({math.degrees(lim):.0f} deg/s)")
    tx, ty, tz = thrust_body[0], thrust_body[1], thrust_body[2]
    if not -1.0 <= tz <= 0.0 or abs(tx) > 1.0 or abs(ty) > 1.0:
        return f"thrust_body ({tx:.2f}, {ty:.2f}, {tz:.2f}) outside 0..1 up"
    return None


def tilt_error_rad(q: Quat, qd: Quat) -> float:
    """The angle (rad) between the body z axis of ``q`` and that of the setpoint ``qd``: the
    tilt error, blind to heading (a heading error is slow and harmless, a tilt error is not)."""
    ax, ay, az = body_z_ned(q)
    bx, by, bz = body_z_ned(qd)
    dot = ax * bx + ay * by + az * bz
    return math.acos(-1.0 if dot < -1.0 else (min(dot, 1.0)))
