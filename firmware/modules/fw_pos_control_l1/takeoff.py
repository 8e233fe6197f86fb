"""Takeoff phases of fw_pos_control_l1: runway takeoff and hand/catapult launch detection.

Runway (``RWTO_TKOFF`` 1), PX4's RunwayTakeoff in shape: the throttle ramps up over
``RWTO_RAMP_TIME`` with the wings level, the pitch at ``RWTO_PSP`` and the heading held with the
rudder (the steered wheel); at ``FW_AIRSPD_MIN * RWTO_AIRSPD_SCL`` the aircraft rotates and
climbs out on the runway heading with the roll limited to ``RWTO_MAX_ROLL``; from
``RWTO_NAV_ALT`` above the runway L1 navigates to the takeoff waypoint.

Launch (``RWTO_TKOFF`` 0): with ``LAUN_ALL_ON`` 1 the motor stays at idle until the body's
forward specific force has been above ``LAUN_CAT_A`` for ``LAUN_CAT_T`` (the throw or the
catapult), then after ``LAUN_CAT_MDEL`` the climb-out starts; with launch detection off the
climb-out starts at once (a throw with the motor running).
"""

from __future__ import annotations

from typing import Final

__all__ = ["LaunchDetector", "RunwayTakeoff"]

RW_THROTTLE_RAMP: Final = 0
RW_CLAMPED: Final = 1
RW_CLIMBOUT: Final = 2
RW_FLY: Final = 3


class RunwayTakeoff:
    """State of a runway takeoff (reset with :meth:`reset` when a new takeoff begins)."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.state = RW_THROTTLE_RAMP
        self.t_start_us = -1
        self.start_alt_m = 0.0
        self.heading_rad = 0.0
        self.initialised = False

    def init(self, now_us: int, alt_m: float, heading_rad: float) -> None:
        self.reset()
        self.t_start_us = now_us
        self.start_alt_m = alt_m
        self.heading_rad = heading_rad
        self.initialised = True

    def update(self, now_us: int, airspeed_m_s: float, alt_m: float, rotate_speed_m_s: float,
               ramp_time_s: float, nav_alt_m: float) -> int:
        """Advance the state machine; returns the state."""
        if self.state == RW_THROTTLE_RAMP and \
                (now_us - self.t_start_us) * 1e-6 >= ramp_time_s:
            self.state = RW_CLAMPED
        if self.state == RW_CLAMPED and airspeed_m_s >= rotate_speed_m_s:
            self.state = RW_CLIMBOUT
        if self.state == RW_CLIMBOUT and alt_m - self.start_alt_m >= nav_alt_m:
            self.state = RW_FLY
        return self.state

    def throttle(self, now_us: int, ramp_time_s: float, max_thr: float, idle: float) -> float:
        """The runway throttle: a ramp from idle to the maximum, then the maximum."""
        if self.state == RW_THROTTLE_RAMP:
            f = (now_us - self.t_start_us) * 1e-6 / max(ramp_time_s, 0.1)
            return idle + (max_thr - idle) * min(max(f, 0.0), 1.0)
        return max_thr

    @property
    def on_ground(self) -> bool:
        return self.state in (RW_THROTTLE_RAMP, RW_CLAMPED)


class LaunchDetector:
    """The throw or catapult: forward specific force above a threshold for long enough."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.above_s = 0.0
        self.detected_us = -1

    def update(self, now_us: int, dt_s: float, accel_x_m_s2: float, accel_thr_m_s2: float,
               time_thr_s: float) -> bool:
        if self.detected_us >= 0:
            return True
        self.above_s = self.above_s + dt_s if accel_x_m_s2 > accel_thr_m_s2 else 0.0
        if self.above_s >= time_thr_s:
            self.detected_us = now_us
        return self.detected_us >= 0

    def motor_on(self, now_us: int, delay_s: float) -> bool:
        return self.detected_us >= 0 and (now_us - self.detected_us) * 1e-6 >= delay_s
