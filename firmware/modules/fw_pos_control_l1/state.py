"""What one run of fw_pos_control_l1 works on and produces (kept apart from the module so
that each file stays small)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from firmware.lib.tecs import TecsStatus

__all__ = ["Out", "State", "fill_tecs_status"]


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


def fill_tecs_status(t: Any, s: TecsStatus, now_us: int, throttle: float, pitch_rad: float,
                     airspeed_valid: bool, mode: int) -> None:
    """The tecs_status message from TECS's last update and what was published."""
    t.timestamp = now_us
    t.altitude_sp, t.altitude_filtered = s.altitude_sp_m, s.altitude_filtered_m
    t.height_rate_setpoint, t.height_rate = s.height_rate_sp_m_s, s.height_rate_m_s
    t.true_airspeed_sp, t.true_airspeed_filtered = s.tas_sp_m_s, s.tas_filtered_m_s
    t.true_airspeed_derivative_sp = s.tas_rate_sp_m_s2
    t.true_airspeed_derivative = s.tas_rate_m_s2
    t.total_energy_error, t.total_energy_rate_error = s.ste_error, s.ste_rate_error
    t.energy_distribution_error = s.seb_error
    t.energy_distribution_rate_error = s.seb_rate_error
    t.throttle_integ, t.pitch_integ = s.throttle_integ, s.pitch_integ
    t.throttle_sp, t.pitch_sp_rad = throttle, pitch_rad
    t.airspeed_valid = airspeed_valid
    t.mode = mode
