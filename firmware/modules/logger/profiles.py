"""Logger profiles: which topics are logged, and how often.

Modelled on PX4's ``logged_topics.cpp``: each entry names a topic and a maximum rate. A rate of
0 means "every message" (a queued topic is drained, so none is lost, e.g. ``vehicle_command``).
Profiles may list topics that this tree does not define yet; the logger skips those quietly, so
a module that adds a topic gets it logged without touching this file.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

__all__ = ["PROFILES", "LoggedTopic", "get_profile"]


@dataclass(frozen=True)
class LoggedTopic:
    name: str
    rate_hz: float = 0.0   # 0: every update

    @property
    def interval_us(self) -> int:
        return 0 if self.rate_hz <= 0 else round(1e6 / self.rate_hz)


def _t(*rows: tuple[str, float]) -> tuple[LoggedTopic, ...]:
    return tuple(LoggedTopic(name, rate) for name, rate in rows)


#: PX4-like default set: estimator and controller outputs at tens of Hz, raw sensors lower,
#: events (commands, status changes) at every update.
DEFAULT: Final = _t(
    ("actuator_armed", 0),
    ("actuator_controls_0", 50), ("actuator_controls_1", 20),
    ("actuator_outputs", 100),
    ("airspeed", 10),
    ("battery_status", 5),
    ("commander_state", 0),
    ("cpuload", 0),
    ("differential_pressure", 10),  # an airspeed sensor's (a plane's FMU); absent elsewhere
    ("esc_status", 4),            # PX4: every 250 ms; only ESC drivers that report publish it
    ("estimator_status", 5),
    ("home_position", 0),
    ("input_rc", 10),
    ("manual_control_setpoint", 20),
    ("mission", 0),
    ("parameter_update", 0),
    ("position_controller_status", 5),  # a plane's L1 guidance (acceptance radius, track)
    ("position_setpoint_triplet", 5),
    ("rc_channels", 10),
    ("safety", 0),
    ("sensor_accel", 50), ("sensor_gyro", 50), ("sensor_mag", 10), ("sensor_baro", 10),
    ("sensor_combined", 100),
    ("sensor_gps", 10), ("vehicle_gps_position", 10),
    ("tecs_status", 10),          # a plane's energy control; absent on a multicopter
    ("telemetry_status", 1),
    ("vehicle_air_data", 5),
    ("vehicle_angular_velocity", 50),
    ("vehicle_attitude", 50),
    ("vehicle_attitude_setpoint", 50),
    ("vehicle_command", 0),
    ("vehicle_global_position", 5),
    ("vehicle_land_detected", 0),
    ("vehicle_local_position", 10),
    ("vehicle_local_position_setpoint", 10),
    ("vehicle_magnetometer", 10),
    ("vehicle_rates_setpoint", 50),
    ("vehicle_status", 0),
    ("vtol_vehicle_status", 10),  # a VTOL's mode and transitions
)

#: estimator and control loops at full rate (PX4's "high rate" option)
HIGH_RATE: Final = _t(
    ("actuator_controls_0", 0), ("actuator_outputs", 0), ("vehicle_angular_velocity", 0),
    ("vehicle_attitude", 0), ("vehicle_attitude_setpoint", 0), ("vehicle_rates_setpoint", 0),
    ("sensor_combined", 0), ("vehicle_command", 0), ("vehicle_status", 0),
)

#: raw sensor data at full rate (PX4's "sensor comparison" / thermal calibration options)
SENSORS: Final = _t(
    ("sensor_accel", 0), ("sensor_gyro", 0), ("sensor_mag", 0), ("sensor_baro", 0),
    ("sensor_combined", 0), ("sensor_gps", 0), ("vehicle_command", 0), ("vehicle_status", 0),
)

PROFILES: Final[dict[str, tuple[LoggedTopic, ...]]] = {
    "default": DEFAULT,
    "high_rate": HIGH_RATE,
    "sensors": SENSORS,
}


def get_profile(profile: str | list[str] | tuple | dict) -> list[LoggedTopic]:
    """Resolve a profile: a name, names joined by '+' ('default+sensors'), a list of
    LoggedTopic / names / (name, rate_hz), or a {name: rate_hz} dict. When a topic is listed
    twice the highest rate wins (0, every update, being the highest)."""
    rows: list[LoggedTopic] = []
    if isinstance(profile, str):
        for part in profile.split("+"):
            try:
                rows.extend(PROFILES[part.strip()])
            except KeyError:
                raise ValueError(f"unknown logger profile {part!r}; known: "
                                 f"{', '.join(sorted(PROFILES))}") from None
    elif isinstance(profile, dict):
        rows = [LoggedTopic(k, float(v)) for k, v in profile.items()]
    else:
        for item in profile:
            if isinstance(item, LoggedTopic):
                rows.append(item)
            elif isinstance(item, str):
                rows.append(LoggedTopic(item))
            else:
                name, rate = item
                rows.append(LoggedTopic(name, float(rate)))
    merged: dict[str, LoggedTopic] = {}
    for row in rows:
        old = merged.get(row.name)
        if old is None or row.interval_us < old.interval_us:
            merged[row.name] = row
    return list(merged.values())
