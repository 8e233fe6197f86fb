"""Telemetry streams: which message each stream sends, from which topics, at which default rate.

A stream is a name (PX4's, which is the MAVLink message name), its message id and a builder
``fn(inst) -> message | None`` (None: nothing to send yet, such as GPS_RAW_INT before the first
fix message). Default rates per mode follow PX4's ``configure_streams_to_default`` for the
streams this stack has data for; ``mavlink stream`` and SET_MESSAGE_INTERVAL change them.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Final

from firmware.modules.mavlink.dialect import mav
from firmware.modules.mavlink.systime import system_time

if TYPE_CHECKING:
    from firmware.modules.mavlink.instance import MavlinkInstance

__all__ = ["DEFAULT_RATES", "MAX_INTERVAL_US", "STREAMS", "StreamDef", "base_mode_and_state",
           "custom_mode"]

UINT16_MAX: Final = 0xFFFF
INT16_MAX: Final = 0x7FFF

# vehicle_status.nav_state -> PX4 custom (main, sub) mode, as the HEARTBEAT carries it.
_MAIN: Final = {0: (1, 0), 1: (2, 0), 2: (3, 0), 3: (4, 4), 4: (4, 3), 5: (4, 5), 10: (5, 0),
         12: (4, 6), 13: (1, 0), 14: (6, 0), 15: (7, 0), 17: (4, 2), 18: (4, 6), 19: (4, 8),
         20: (4, 9), 21: (3, 0)}
_AUTO_NAV: Final = frozenset({3, 4, 5, 12, 17, 18, 19, 20})


def custom_mode(nav_state: int) -> int:
    """PX4's custom_mode union: main mode in byte 2, sub mode in byte 3."""
    main, sub = _MAIN.get(nav_state, (1, 0))
    return (main << 16) | (sub << 24)


def base_mode_and_state(status: Any, hitl: bool) -> tuple[int, int]:
    """HEARTBEAT base_mode flags and MAV_STATE from vehicle_status (PX4's mode-state mapping)."""
    if status is None:
        return mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, mav.MAV_STATE_UNINIT
    base = mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    armed = status.arming_state == 2
    if armed:
        base |= mav.MAV_MODE_FLAG_SAFETY_ARMED
    if hitl:
        base |= mav.MAV_MODE_FLAG_HIL_ENABLED
    nav = status.nav_state
    if nav in (0, 15, 1):      # manual (a multicopter's manual is stabilized), stab, altctl
        base |= mav.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | mav.MAV_MODE_FLAG_STABILIZE_ENABLED
    elif nav in (2, 21):       # position, orbit
        base |= (mav.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | mav.MAV_MODE_FLAG_STABILIZE_ENABLED
                 | mav.MAV_MODE_FLAG_GUIDED_ENABLED)
    elif nav == 10:            # acro
        base |= mav.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
    elif nav in _AUTO_NAV or nav == 14:
        base |= (mav.MAV_MODE_FLAG_AUTO_ENABLED | mav.MAV_MODE_FLAG_STABILIZE_ENABLED
                 | mav.MAV_MODE_FLAG_GUIDED_ENABLED)
    arming = status.arming_state
    if nav == 13:
        state = mav.MAV_STATE_FLIGHT_TERMINATION
    elif arming == 0:
        state = mav.MAV_STATE_BOOT
    elif arming in (3,) or (armed and status.failsafe):
        state = mav.MAV_STATE_CRITICAL
    elif armed:
        state = mav.MAV_STATE_ACTIVE
    elif arming == 4:
        state = mav.MAV_STATE_POWEROFF
    else:
        state = mav.MAV_STATE_STANDBY
    return base, state


def _euler(q: Any) -> tuple[float, float, float]:
    w, x, y, z = q
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


def _i(v: float, lo: int, hi: int) -> int:
    if not math.isfinite(v):
        return 0
    return max(lo, min(hi, round(v)))


# -- builders ----------------------------------------------------------------------------------

def _heartbeat(inst: MavlinkInstance) -> Any:
    status = inst.latest("vehicle_status")
    base, state = base_mode_and_state(status, bool(inst.param("SYS_HITL", 0)))
    cm = custom_mode(status.nav_state) if status is not None else 0
    return mav.MAVLink_heartbeat_message(int(inst.param("MAV_TYPE", 2)), mav.MAV_AUTOPILOT_PX4,
                                         base, cm, state, 3)


def _sys_status(inst: MavlinkInstance) -> Any:
    st = inst.latest("vehicle_status")
    bat = inst.latest("battery_status")
    present = enabled = health = 0
    if st is not None:
        present, enabled = st.onboard_control_sensors_present, st.onboard_control_sensors_enabled
        health = st.onboard_control_sensors_health
    volt = cur = 0
    rem = -1
    if bat is not None and bat.connected:
        volt = _i(bat.voltage_filtered_v * 1000, 0, UINT16_MAX - 1)
        cur = _i(bat.current_filtered_a * 100, -1, INT16_MAX)
        rem = _i(bat.remaining * 100, -1, 100)
    drop = _i(inst.rx_drop_rate() * 10000, 0, 10000)
    return mav.MAVLink_sys_status_message(present, enabled, health, inst.load_permille(), volt,
                                          cur, rem, drop, inst.rx_errors & 0xFFFF, 0, 0, 0, 0)


def _attitude(inst: MavlinkInstance) -> Any:
    att = inst.latest("vehicle_attitude")
    if att is None:
        return None
    r, p, y = _euler(att.q)
    rates = inst.latest("vehicle_angular_velocity")
    wx, wy, wz = rates.xyz if rates is not None else (0.0, 0.0, 0.0)
    return mav.MAVLink_attitude_message(inst.boot_ms(), r, p, y, wx, wy, wz)


def _attitude_q(inst: MavlinkInstance) -> Any:
    att = inst.latest("vehicle_attitude")
    if att is None:
        return None
    rates = inst.latest("vehicle_angular_velocity")
    wx, wy, wz = rates.xyz if rates is not None else (0.0, 0.0, 0.0)
    w, x, y, z = att.q
    return mav.MAVLink_attitude_quaternion_message(inst.boot_ms(), w, x, y, z, wx, wy, wz,
                                                   [0.0, 0.0, 0.0, 0.0])


def _local_position(inst: MavlinkInstance) -> Any:
    lp = inst.latest("vehicle_local_position")
    if lp is None or not (lp.xy_valid or lp.z_valid):
        return None
    return mav.MAVLink_local_position_ned_message(inst.boot_ms(), lp.x, lp.y, lp.z, lp.vx,
                                                  lp.vy, lp.vz)


def _global_position(inst: MavlinkInstance) -> Any:
    gp = inst.latest("vehicle_global_position")
    lp = inst.latest("vehicle_local_position")
    if gp is None or lp is None:
        return None
    home = inst.latest("home_position")
    rel = gp.alt - home.alt if home is not None and home.valid_alt else -lp.z
    hdg = _i(math.degrees(lp.heading) % 360.0 * 100, 0, 35999) if math.isfinite(lp.heading) \
        else UINT16_MAX
    return mav.MAVLink_global_position_int_message(
        inst.boot_ms(), _i(gp.lat * 1e7, -900000000, 900000000),
        _i(gp.lon * 1e7, -1800000000, 1800000000), _i(gp.alt * 1000, -2**31, 2**31 - 1),
        _i(rel * 1000, -2**31, 2**31 - 1), _i(lp.vx * 100, -32768, 32767),
        _i(lp.vy * 100, -32768, 32767), _i(lp.vz * 100, -32768, 32767), hdg)


def _gps_raw(inst: MavlinkInstance) -> Any:
    g = inst.latest("sensor_gps")
    if g is None:
        return None
    cog = _i(math.degrees(g.cog_rad) % 360.0 * 100, 0, 35999)
    return mav.MAVLink_gps_raw_int_message(
        g.timestamp, g.fix_type, g.lat, g.lon, g.alt, _i(g.hdop * 100, 0, UINT16_MAX),
        _i(g.vdop * 100, 0, UINT16_MAX), _i(g.vel_m_s * 100, 0, UINT16_MAX - 1), cog,
        g.satellites_used, g.alt_ellipsoid, _i(g.eph * 1000, 0, 2**32 - 1),
        _i(g.epv * 1000, 0, 2**32 - 1), _i(g.s_variance_m_s * 1000, 0, 2**32 - 1),
        _i(math.degrees(g.c_variance_rad) * 1e5, 0, 2**32 - 1), 0)


def _vfr_hud(inst: MavlinkInstance) -> Any:
    lp = inst.latest("vehicle_local_position")
    if lp is None:
        return None
    gp = inst.latest("vehicle_global_position")
    sp = inst.latest("vehicle_attitude_setpoint")
    gs = math.hypot(lp.vx, lp.vy)
    heading = _i(math.degrees(lp.heading) % 360.0, 0, 359) if math.isfinite(lp.heading) else 0
    thr = _i(-sp.thrust_body[2] * 100, 0, 100) if sp is not None else 0
    alt = gp.alt if gp is not None else -lp.z
    return mav.MAVLink_vfr_hud_message(gs, gs, heading, thr, alt, -lp.vz)


def _battery(inst: MavlinkInstance) -> Any:
    b = inst.latest("battery_status")
    if b is None:
        return None
    cells = max(int(b.cell_count), 0)
    volts = [UINT16_MAX] * 10
    if b.connected and cells:
        for i in range(min(cells, 10)):
            volts[i] = _i(b.voltage_filtered_v / cells * 1000, 0, UINT16_MAX - 1)
    charge = {0: 1, 1: 2, 2: 3, 3: 4, 4: 5}.get(int(b.warning), 0)
    return mav.MAVLink_battery_status_message(
        0, mav.MAV_BATTERY_FUNCTION_ALL, mav.MAV_BATTERY_TYPE_LIPO, INT16_MAX, volts,
        _i(b.current_filtered_a * 100, -1, INT16_MAX), _i(b.discharged_mah, -1, 2**31 - 1), -1,
        _i(b.remaining * 100, -1, 100) if b.connected else -1, 0, charge)


def _rc_channels(inst: MavlinkInstance) -> Any:
    rc = inst.latest("input_rc")
    if rc is None:
        return None
    n = min(int(rc.channel_count), 18)
    ch = [int(rc.values[i]) if i < n else UINT16_MAX for i in range(18)]
    rssi = 255 if rc.rssi < 0 else _i(rc.rssi * 254 / 100, 0, 254)
    return mav.MAVLink_rc_channels_message(inst.boot_ms(), n, *ch, rssi)


def _servo_output(inst: MavlinkInstance) -> Any:
    a = inst.latest("actuator_outputs")
    if a is None:
        return None
    out = [_i(v, 0, UINT16_MAX) if i < a.noutputs else 0 for i, v in enumerate(a.output)]
    return mav.MAVLink_servo_output_raw_message(a.timestamp & 0xFFFFFFFF, 0, *out)


def _extended_sys_state(inst: MavlinkInstance) -> Any:
    land = inst.latest("vehicle_land_detected")
    st = inst.latest("vehicle_status")
    if land is None and st is None:
        return None
    state = mav.MAV_LANDED_STATE_UNDEFINED
    if land is not None:
        state = mav.MAV_LANDED_STATE_ON_GROUND if land.landed else mav.MAV_LANDED_STATE_IN_AIR
    if st is not None and st.arming_state == 2 and land is not None:
        if st.nav_state == 17 and not land.landed:
            state = mav.MAV_LANDED_STATE_TAKEOFF
        elif st.nav_state in (12, 18, 20) and not land.landed:
            state = mav.MAV_LANDED_STATE_LANDING
    vtol_state = mav.MAV_VTOL_STATE_UNDEFINED
    if st is not None and st.is_vtol:  # PX4: vtol_vehicle_status's state (the same numbers)
        vs = inst.latest("vtol_vehicle_status")
        if vs is not None:
            vtol_state = int(vs.vehicle_vtol_state)
    return mav.MAVLink_extended_sys_state_message(vtol_state, state)


def _home(inst: MavlinkInstance) -> Any:
    h = inst.latest("home_position")
    if h is None or not h.valid_hpos:
        return None
    q = [math.cos(h.yaw / 2), 0.0, 0.0, math.sin(h.yaw / 2)]
    return mav.MAVLink_home_position_message(
        _i(h.lat * 1e7, -900000000, 900000000), _i(h.lon * 1e7, -1800000000, 1800000000),
        _i(h.alt * 1000, -2**31, 2**31 - 1), h.x, h.y, h.z, q, 0.0, 0.0, 0.0, h.timestamp)


def _altitude(inst: MavlinkInstance) -> Any:
    lp = inst.latest("vehicle_local_position")
    air = inst.latest("vehicle_air_data")
    if lp is None and air is None:
        return None
    nan = float("nan")
    mono = air.baro_alt_meter if air is not None else nan
    gp = inst.latest("vehicle_global_position")
    home = inst.latest("home_position")
    local = -lp.z if lp is not None else nan
    rel = -(lp.z - home.z) if lp is not None and home is not None and home.valid_lpos else local
    return mav.MAVLink_altitude_message(inst.time_us(), mono, gp.alt if gp is not None else nan,
                                        local, rel, nan, nan)


def _estimator_status(inst: MavlinkInstance) -> Any:
    e = inst.latest("estimator_status")
    if e is None:
        return None
    flags = 0
    if e.filter_fault_flags == 0:
        flags = (mav.ESTIMATOR_ATTITUDE | mav.ESTIMATOR_VELOCITY_HORIZ
                 | mav.ESTIMATOR_VELOCITY_VERT | mav.ESTIMATOR_POS_VERT_ABS)
        if e.control_mode_flags & (1 << 2):
            flags |= mav.ESTIMATOR_POS_HORIZ_REL | mav.ESTIMATOR_POS_HORIZ_ABS
    return mav.MAVLink_estimator_status_message(
        e.timestamp, flags, e.vel_test_ratio, e.pos_test_ratio, e.hgt_test_ratio,
        e.mag_test_ratio, e.hagl_test_ratio, e.tas_test_ratio, e.pos_horiz_accuracy,
        e.pos_vert_accuracy)


def _highres_imu(inst: MavlinkInstance) -> Any:
    s = inst.latest("sensor_combined")
    if s is None:
        return None
    air = inst.latest("vehicle_air_data")
    mag = inst.latest("vehicle_magnetometer")
    ax, ay, az = s.accelerometer_m_s2
    gx, gy, gz = s.gyro_rad
    mx = my = mz = 0.0
    fields = 0b111111
    if mag is not None and hasattr(mag, "magnetometer_ga"):
        mx, my, mz = mag.magnetometer_ga
        fields |= 0b111000000
    press = alt = temp = 0.0
    if air is not None:
        press, alt, temp = air.baro_pressure_pa / 100.0, air.baro_alt_meter, \
            air.baro_temp_celcius
        fields |= (1 << 9) | (1 << 11) | (1 << 12)
    return mav.MAVLink_highres_imu_message(s.timestamp, ax, ay, az, gx, gy, gz, mx, my, mz,
                                           press, 0.0, alt, temp, fields, 0)


def _mission_current(inst: MavlinkInstance) -> Any:
    mission = inst.latest("mission")
    if mission is None:
        return None
    res = inst.latest("mission_result")
    seq = int(res.seq_current) if res is not None and res.valid else int(mission.current_seq)
    state = mav.MISSION_STATE_NO_MISSION if mission.count == 0 else \
        mav.MISSION_STATE_COMPLETE if res is not None and res.finished else \
        mav.MISSION_STATE_ACTIVE if inst.nav_state() == 3 else mav.MISSION_STATE_NOT_STARTED
    return mav.MAVLink_mission_current_message(max(seq, 0), int(mission.count), state, 0)


def _current_mode(inst: MavlinkInstance) -> Any:
    return inst.available_modes.current_mode()


def _modes_monitor(inst: MavlinkInstance) -> Any:
    """PX4's AVAILABLE_MODES stream: it sends AVAILABLE_MODES_MONITOR (the list itself only on
    request, see :mod:`firmware.modules.mavlink.available_modes`)."""
    return inst.available_modes.monitor()


class StreamDef:
    """One stream: message name and id, builder, and whether it may be requested once."""

    __slots__ = ("build", "msg_id", "name")

    def __init__(self, name: str, build: Callable[[MavlinkInstance], Any]) -> None:
        self.name = name
        self.msg_id: int = getattr(mav, f"MAVLINK_MSG_ID_{name}")
        self.build = build


STREAMS: Final[dict[str, StreamDef]] = {s.name: s for s in (
    StreamDef("HEARTBEAT", _heartbeat), StreamDef("SYS_STATUS", _sys_status),
    StreamDef("ATTITUDE", _attitude), StreamDef("ATTITUDE_QUATERNION", _attitude_q),
    StreamDef("LOCAL_POSITION_NED", _local_position),
    StreamDef("GLOBAL_POSITION_INT", _global_position), StreamDef("GPS_RAW_INT", _gps_raw),
    StreamDef("VFR_HUD", _vfr_hud), StreamDef("BATTERY_STATUS", _battery),
    StreamDef("RC_CHANNELS", _rc_channels), StreamDef("SERVO_OUTPUT_RAW", _servo_output),
    StreamDef("EXTENDED_SYS_STATE", _extended_sys_state), StreamDef("HOME_POSITION", _home),
    StreamDef("ALTITUDE", _altitude), StreamDef("ESTIMATOR_STATUS", _estimator_status),
    StreamDef("HIGHRES_IMU", _highres_imu), StreamDef("MISSION_CURRENT", _mission_current),
    StreamDef("SYSTEM_TIME", system_time), StreamDef("CURRENT_MODE", _current_mode),
    StreamDef("AVAILABLE_MODES", _modes_monitor),
)}
STREAM_BY_ID: Final[dict[int, StreamDef]] = {s.msg_id: s for s in STREAMS.values()}
#: the longest stream interval: what MESSAGE_INTERVAL's int32 interval_us can report (~36 min)
MAX_INTERVAL_US: Final = 0x7FFFFFFF

_NORMAL: Final = {"HEARTBEAT": 1.0, "SYS_STATUS": 1.0, "ATTITUDE": 15.0, "ATTITUDE_QUATERNION": 10.0,
           "LOCAL_POSITION_NED": 1.0, "GLOBAL_POSITION_INT": 5.0, "GPS_RAW_INT": 1.0,
           "VFR_HUD": 4.0, "BATTERY_STATUS": 0.5, "RC_CHANNELS": 5.0, "SERVO_OUTPUT_RAW": 1.0,
           "EXTENDED_SYS_STATE": 1.0, "HOME_POSITION": 0.5, "ALTITUDE": 1.0,
           "ESTIMATOR_STATUS": 0.5, "MISSION_CURRENT": 1.0, "SYSTEM_TIME": 1.0,
           "CURRENT_MODE": 0.5, "AVAILABLE_MODES": 0.3}
_ONBOARD: Final = {"HEARTBEAT": 1.0, "SYS_STATUS": 5.0, "ATTITUDE": 100.0,
            "ATTITUDE_QUATERNION": 50.0, "LOCAL_POSITION_NED": 30.0,
            "GLOBAL_POSITION_INT": 50.0, "GPS_RAW_INT": 5.0, "VFR_HUD": 10.0,
            "BATTERY_STATUS": 0.5, "RC_CHANNELS": 20.0, "SERVO_OUTPUT_RAW": 10.0,
            "EXTENDED_SYS_STATE": 5.0, "HOME_POSITION": 0.5, "ALTITUDE": 10.0,
            "ESTIMATOR_STATUS": 1.0, "HIGHRES_IMU": 50.0, "MISSION_CURRENT": 1.0,
            "SYSTEM_TIME": 1.0, "CURRENT_MODE": 0.5, "AVAILABLE_MODES": 0.3}
_CONFIG: Final = {"HEARTBEAT": 1.0, "SYS_STATUS": 1.0, "ATTITUDE": 50.0, "ATTITUDE_QUATERNION": 50.0,
           "LOCAL_POSITION_NED": 30.0, "GLOBAL_POSITION_INT": 10.0, "GPS_RAW_INT": 10.0,
           "VFR_HUD": 20.0, "BATTERY_STATUS": 0.5, "RC_CHANNELS": 10.0,
           "SERVO_OUTPUT_RAW": 20.0, "EXTENDED_SYS_STATE": 2.0, "HOME_POSITION": 0.5,
           "ALTITUDE": 10.0, "ESTIMATOR_STATUS": 1.0, "HIGHRES_IMU": 50.0,
           "MISSION_CURRENT": 1.0, "SYSTEM_TIME": 1.0, "CURRENT_MODE": 0.5,
           "AVAILABLE_MODES": 0.3}
#: mode -> stream -> default rate (Hz)
DEFAULT_RATES: Final[dict[str, dict[str, float]]] = {"normal": _NORMAL, "onboard": _ONBOARD,
                                              "config": _CONFIG, "minimal": {"HEARTBEAT": 1.0}}
