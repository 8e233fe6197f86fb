"""What one run of fw_pos_control_l1 works on and produces (kept apart from the module so
that each file stays small)."""

from __future__ import annotations

__all__ = ["Out", "State"]


class State:
    """The vehicle state one run works on (local NED, AMSL altitude)."""

    __slots__ = ("pos", "vel", "alt", "climb", "accel_x", "yaw", "now", "dt")

    def __init__(self, pos: tuple[float, float], vel: tuple[float, float], alt: float,
                 climb: float, accel_x: float, yaw: float, now: int, dt: float) -> None:
        self.pos, self.vel, self.alt, self.climb = pos, vel, alt, climb
        self.accel_x, self.yaw, self.now, self.dt = accel_x, yaw, now, dt


class Out:
    """One run's attitude setpoint and throttle."""

    __slots__ = ("roll", "pitch", "yaw", "throttle", "target", "wheel")

    def __init__(self, roll: float, pitch: float, yaw: float, throttle: float,
                 target: tuple[float, float] | None, wheel: bool = False) -> None:
        self.roll, self.pitch, self.yaw, self.throttle = roll, pitch, yaw, throttle
        self.target, self.wheel = target, wheel
