"""Small math every layer uses, under PX4's names (``math::constrain``)."""

from __future__ import annotations

__all__ = ["constrain"]


def constrain(value: float, lo: float, hi: float) -> float:
    """``value`` limited to [lo, hi]; NaN falls through both tests and stays NaN, as PX4's
    ``math::constrain`` does (a NaN setpoint is caught where it is used, not hidden here)."""
    return lo if value < lo else (min(value, hi))
