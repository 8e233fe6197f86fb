"""Offboard and joystick input from a companion computer or GCS.

* SET_POSITION_TARGET_LOCAL_NED / SET_POSITION_TARGET_GLOBAL_INT -> ``trajectory_setpoint``
  (fields the type mask ignores are NaN, as the position controller expects), global targets
  projected onto the local frame around the estimator's reference point;
* SET_ATTITUDE_TARGET -> ``vehicle_attitude_setpoint`` (or ``vehicle_rates_setpoint`` when the
  attitude is ignored);
* every setpoint message also publishes ``offboard_control_mode`` (what is being controlled and
  that the stream is alive), which the commander uses to allow and keep Offboard mode.

As in PX4, setpoints are only published while the commander has Offboard control enabled
(``vehicle_control_mode.flag_control_offboard_enabled``): a companion computer streaming
setpoints before the switch must not move the vehicle in another mode.

MANUAL_CONTROL -> ``manual_control_input`` with ``data_source = SOURCE_MAVLINK_0 + link``, on
an instance of its own (advertised on first use), as PX4's receiver publishes it; rc_update's
selector decides by COM_RC_IN_MODE whether it or RC becomes ``manual_control_setpoint``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Final

from pymavlink.dialects.v20 import common as mav

if TYPE_CHECKING:
    from firmware.modules.mavlink.instance import MavlinkInstance

__all__ = ["OffboardService", "project"]

EARTH_RADIUS_M: Final = 6371000.0
NAN: Final = float("nan")


def project(lat: float, lon: float, ref_lat: float, ref_lon: float) -> tuple[float, float]:
    """Azimuthal equidistant projection (what PX4's map projection does) -> (north, east) m."""
    la, lo = math.radians(lat), math.radians(lon)
    rla, rlo = math.radians(ref_lat), math.radians(ref_lon)
    cos_c = math.sin(rla) * math.sin(la) + math.cos(rla) * math.cos(la) * math.cos(lo - rlo)
    cos_c = max(-1.0, min(1.0, cos_c))
    c = math.acos(cos_c)
    k = c / math.sin(c) if abs(c) > 1e-12 else 1.0
    x = k * (math.cos(rla) * math.sin(la) - math.sin(rla) * math.cos(la) * math.cos(lo - rlo))
    y = k * math.cos(la) * math.sin(lo - rlo)
    return x * EARTH_RADIUS_M, y * EARTH_RADIUS_M


class OffboardService:
    def __init__(self, inst: MavlinkInstance) -> None:
        self.inst = inst
        orb = inst.platform.orb
        self._pubs: dict[str, Any] = {}
        self._msgs: dict[str, Any] = {}
        self._has_ocm = _known(orb, "offboard_control_mode")
        self.setpoints = 0
        self.setpoints_ignored = 0
        self.manual_inputs = 0

    def handlers(self) -> dict[int, Callable[[Any], None]]:
        return {mav.MAVLINK_MSG_ID_SET_POSITION_TARGET_LOCAL_NED: self._on_local,
                mav.MAVLINK_MSG_ID_SET_POSITION_TARGET_GLOBAL_INT: self._on_global,
                mav.MAVLINK_MSG_ID_SET_ATTITUDE_TARGET: self._on_attitude,
                mav.MAVLINK_MSG_ID_MANUAL_CONTROL: self._on_manual}

    def update(self, now_us: int) -> None:
        pass

    def _publish(self, topic: str, fill: Callable[[Any], None], multi: bool = False) -> None:
        pub = self._pubs.get(topic)
        if pub is None:
            module = self.inst.module
            pub = module.advertise(topic, None if multi else 0)
            self._pubs[topic] = pub
            self._msgs[topic] = self.inst.platform.orb.new(topic)
        msg = self._msgs[topic]
        msg.timestamp = self.inst.time_us()
        fill(msg)
        pub.publish(msg)

    def _offboard_enabled(self) -> bool:
        mode = self.inst.latest("vehicle_control_mode")
        return mode is not None and bool(mode.flag_control_offboard_enabled)

    def _control_mode(self, **flags: bool) -> None:
        if not self._has_ocm:
            return

        def fill(m: Any) -> None:
            for name in ("position", "velocity", "acceleration", "attitude", "body_rate"):
                if hasattr(m, name):
                    setattr(m, name, bool(flags.get(name, False)))
        self._publish("offboard_control_mode", fill)

    def _trajectory(self, m: Any, x: float, y: float, z: float) -> None:
        mask = int(m.type_mask)
        pos_ok = not mask & 0b111
        vel_ok = not mask & 0b111000
        acc_ok = not mask & 0b111000000
        self._control_mode(position=pos_ok, velocity=vel_ok and not pos_ok,
                           acceleration=acc_ok and not (pos_ok or vel_ok))
        if not self._offboard_enabled():
            self.setpoints_ignored += 1
            return
        yaw = NAN if mask & mav.POSITION_TARGET_TYPEMASK_YAW_IGNORE else float(m.yaw)
        yaw_rate = NAN if mask & mav.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE else \
            float(m.yaw_rate)

        def fill(t: Any) -> None:
            t.position = [x, y, z] if pos_ok else [NAN] * 3
            t.velocity = [m.vx, m.vy, m.vz] if vel_ok else [NAN] * 3
            t.acceleration = [m.afx, m.afy, m.afz] if acc_ok else [NAN] * 3
            t.jerk = [NAN] * 3
            t.yaw = yaw
            t.yawspeed = yaw_rate
        self._publish("trajectory_setpoint", fill)
        self.setpoints += 1

    def _on_local(self, m: Any) -> None:
        if m.coordinate_frame not in (mav.MAV_FRAME_LOCAL_NED, mav.MAV_FRAME_LOCAL_OFFSET_NED,
                                      mav.MAV_FRAME_BODY_NED, mav.MAV_FRAME_BODY_OFFSET_NED):
            self.setpoints_ignored += 1
            return
        self._trajectory(m, m.x, m.y, m.z)

    def _on_global(self, m: Any) -> None:
        lp = self.inst.latest("vehicle_local_position")
        if lp is None or not lp.xy_global:
            self.setpoints_ignored += 1
            return
        x, y = project(m.lat_int / 1e7, m.lon_int / 1e7, lp.ref_lat, lp.ref_lon)
        if m.coordinate_frame in (mav.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                                  mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT):
            home = self.inst.latest("home_position")
            home_z = home.z if home is not None and home.valid_lpos else 0.0
            z = home_z - m.alt
        else:
            z = -(m.alt - lp.ref_alt)
        self._trajectory(m, x, y, z)

    def _on_attitude(self, m: Any) -> None:
        mask = int(m.type_mask)
        att_ok = not mask & mav.ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE
        self._control_mode(attitude=att_ok, body_rate=not att_ok)
        if not self._offboard_enabled():
            self.setpoints_ignored += 1
            return
        thrust = [0.0, 0.0, -float(m.thrust)]
        if att_ok:
            w, x, y, z = m.q

            def fill(a: Any) -> None:
                a.q_d = [w, x, y, z]
                a.roll_body = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
                a.pitch_body = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
                a.yaw_body = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
                a.yaw_sp_move_rate = float(m.body_yaw_rate)
                a.thrust_body = thrust
            self._publish("vehicle_attitude_setpoint", fill)
        else:
            def fill_rates(r: Any) -> None:
                r.roll, r.pitch, r.yaw = m.body_roll_rate, m.body_pitch_rate, m.body_yaw_rate
                r.thrust_body = thrust
            self._publish("vehicle_rates_setpoint", fill_rates)
        self.setpoints += 1

    def _on_manual(self, m: Any) -> None:
        if m.target not in (0, self.inst.sysid):
            return
        idx = self.inst.index

        def fill(s: Any) -> None:
            s.timestamp_sample = s.timestamp
            s.valid = True
            s.data_source = s.SOURCE_MAVLINK_0 + idx if hasattr(s, "SOURCE_MAVLINK_0") \
                else 2 + idx
            s.pitch = max(-1.0, min(1.0, m.x / 1000.0))
            s.roll = max(-1.0, min(1.0, m.y / 1000.0))
            s.throttle = max(-1.0, min(1.0, m.z / 500.0 - 1.0))  # 0..1000 -> -1..1
            s.yaw = max(-1.0, min(1.0, m.r / 1000.0))
            s.sticks_moving = True
        self._publish("manual_control_input", fill, multi=True)
        self.manual_inputs += 1


def _known(orb: Any, topic: str) -> bool:
    try:
        orb.registry.topic(topic)
        return True
    except Exception:  # noqa: BLE001 - the registry says "unknown topic" its own way
        return False
