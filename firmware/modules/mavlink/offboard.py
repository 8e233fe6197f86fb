"""Offboard and joystick input from a companion computer or GCS.

Setpoints, as PX4 1.14's MavlinkReceiver handles them:

* SET_POSITION_TARGET_LOCAL_NED in MAV_FRAME_LOCAL_NED (position, velocity, acceleration, each
  axis ignored by its type_mask bit -> NaN) or MAV_FRAME_BODY_NED (velocity rotated by the
  heading, acceleration by the attitude; no position); SET_POSITION_TARGET_GLOBAL_INT in
  MAV_FRAME_GLOBAL_INT / MAV_FRAME_GLOBAL_RELATIVE_ALT_INT (position projected around the
  estimator's reference, which must be global; relative altitude needs home). Each becomes a
  ``trajectory_setpoint``; yaw and yaw rate unless ignored.
* SET_ATTITUDE_TARGET: the attitude (quaternion, normalised) and thrust as
  ``vehicle_attitude_setpoint``, or with the attitude ignored the body rates as
  ``vehicle_rates_setpoint``.

Every accepted setpoint publishes ``offboard_control_mode`` (what is controlled: the commander's
proof of life, COM_OF_LOSS_T, and its choice of controllers); the setpoint itself only while
the vehicle is in Offboard mode (``vehicle_status.nav_state``), so a companion computer
streaming before the switch does not move the vehicle in another mode.

Refused, with a STATUSTEXT (at most one a second per reason, where PX4 sends one per message)
and counted in ``setpoints_ignored``: an unsupported coordinate frame, FORCE_SET with an
acceleration, nothing controlled (PX4: "invalid"), and, the emulator's own guard, an infinite
value in a field the type_mask uses. NaN in a used field is left as PX4 leaves it (that axis is
not given); the position controller refuses a setpoint it cannot fly and stops instead.

MANUAL_CONTROL -> ``manual_control_input`` with ``data_source = SOURCE_MAVLINK_0 + link``, on
an instance of its own (advertised on first use), as PX4's receiver publishes it; rc_update's
selector decides by COM_RC_IN_MODE whether it or RC becomes ``manual_control_setpoint``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Final

from firmware.modules.mavlink.dialect import mav

if TYPE_CHECKING:
    from firmware.modules.mavlink.instance import MavlinkInstance

__all__ = ["OffboardService", "project"]

NAV_OFFBOARD: Final = 14        # vehicle_status.NAVIGATION_STATE_OFFBOARD
_POS_MASK: Final = 0b111
_VEL_MASK: Final = 0b111000
_ACC_MASK: Final = 0b111000000
_LOCAL_FRAMES: Final = (mav.MAV_FRAME_LOCAL_NED, mav.MAV_FRAME_BODY_NED)
_GLOBAL_AMSL: Final = mav.MAV_FRAME_GLOBAL_INT
_GLOBAL_REL: Final = mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
TEXT_INTERVAL_US: Final = 1_000_000

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
        self._pubs: dict[str, Any] = {}
        self._msgs: dict[str, Any] = {}
        self._texts: dict[str, int] = {}
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

    def _for_us(self, m: Any) -> bool:
        return m.target_system in (0, self.inst.sysid) and \
            m.target_component in (0, self.inst.compid)

    def _refuse(self, text: str) -> None:
        """Count an ignored setpoint; tell the sender, at most once a second per reason."""
        self.setpoints_ignored += 1
        now = self.inst.time_us()
        last = self._texts.get(text)
        if last is None or now - last >= TEXT_INTERVAL_US:
            self._texts[text] = now
            self.inst.send_text(mav.MAV_SEVERITY_CRITICAL, text)

    def _control_mode(self, position: bool = False, velocity: bool = False,
                      acceleration: bool = False, attitude: bool = False,
                      body_rate: bool = False) -> None:
        def fill(m: Any) -> None:
            m.position, m.velocity, m.acceleration = position, velocity, acceleration
            m.attitude, m.body_rate = attitude, body_rate
            m.thrust_and_torque = m.direct_actuator = False
        self._publish("offboard_control_mode", fill)

    def _in_offboard(self) -> bool:
        return self.inst.nav_state() == NAV_OFFBOARD

    def _trajectory(self, what: str, mask: int, pos: list[float], vel: list[float],
                    acc: list[float], yaw: float, yaw_rate: float) -> None:
        """Publish one position/velocity/acceleration setpoint (NaN: not given)."""
        if any(math.isinf(v) for v in (*pos, *vel, *acc, yaw, yaw_rate)):
            self._refuse(f"{what}: infinite value, setpoint ignored")
            return
        has_pos = not all(math.isnan(v) for v in pos)
        has_vel = not all(math.isnan(v) for v in vel)
        has_acc = not all(math.isnan(v) for v in acc)
        if has_acc and mask & mav.POSITION_TARGET_TYPEMASK_FORCE_SET:
            self._refuse(f"{what} force not supported")
            return
        if not (has_pos or has_vel or has_acc):
            self._refuse(f"{what} invalid")
            return
        self._control_mode(position=has_pos, velocity=has_vel, acceleration=has_acc)
        if not self._in_offboard():
            self.setpoints_ignored += 1
            return

        def fill(t: Any) -> None:
            t.position, t.velocity, t.acceleration = pos, vel, acc
            t.jerk = [NAN] * 3
            t.yaw = yaw
            t.yawspeed = yaw_rate
        self._publish("trajectory_setpoint", fill)
        self.setpoints += 1

    @staticmethod
    def _axes(mask: int, shift: int, values: tuple[float, float, float]) -> list[float]:
        return [NAN if mask & (1 << (shift + i)) else float(values[i]) for i in range(3)]

    @staticmethod
    def _yaw(mask: int, m: Any) -> tuple[float, float]:
        yaw = NAN if mask & mav.POSITION_TARGET_TYPEMASK_YAW_IGNORE else float(m.yaw)
        rate = NAN if mask & mav.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE else float(m.yaw_rate)
        return yaw, rate

    def _on_local(self, m: Any) -> None:
        if not self._for_us(m):
            return
        what = "SET_POSITION_TARGET_LOCAL_NED"
        mask = int(m.type_mask)
        if m.coordinate_frame not in _LOCAL_FRAMES:
            self._refuse(f"{what} coordinate frame {m.coordinate_frame} unsupported")
            return
        if m.coordinate_frame == mav.MAV_FRAME_LOCAL_NED:
            pos = self._axes(mask, 0, (m.x, m.y, m.z))
            vel = self._axes(mask, 3, (m.vx, m.vy, m.vz))
            acc = self._axes(mask, 6, (m.afx, m.afy, m.afz))
        else:
            # body frame: PX4 rotates the velocity by the heading (vz stays down) and the
            # acceleration by the whole attitude; an ignored axis counts as 0 there
            att = self.inst.latest("vehicle_attitude")
            q = tuple(att.q) if att is not None else (1.0, 0.0, 0.0, 0.0)
            pos = [NAN] * 3
            vel, acc = [NAN] * 3, [NAN] * 3
            if not mask & _VEL_MASK:
                bx, by, bz = (0.0 if mask & (1 << (3 + i)) else float(v)
                              for i, v in enumerate((m.vx, m.vy, m.vz)))
                w, x, y, z = q
                hdg = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
                c, s = math.cos(hdg), math.sin(hdg)
                vel = [c * bx - s * by, s * bx + c * by, bz]
            if not mask & _ACC_MASK:
                body = tuple(0.0 if mask & (1 << (6 + i)) else float(v)
                             for i, v in enumerate((m.afx, m.afy, m.afz)))
                acc = list(_rotate(q, body))
        yaw, rate = self._yaw(mask, m)
        self._trajectory(what, mask, pos, vel, acc, yaw, rate)

    def _on_global(self, m: Any) -> None:
        if not self._for_us(m):
            return
        what = "SET_POSITION_TARGET_GLOBAL_INT"
        mask = int(m.type_mask)
        pos = [NAN] * 3
        if not mask & _POS_MASK:
            lp = self.inst.latest("vehicle_local_position")
            if lp is None or not (lp.xy_global and lp.z_global):
                self._refuse(f"{what}: no global position reference")
                return
            if m.coordinate_frame == _GLOBAL_AMSL:
                alt = float(m.alt)
            elif m.coordinate_frame == _GLOBAL_REL:
                home = self.inst.latest("home_position")
                if home is None or not home.valid_alt:
                    self._refuse(f"{what}: relative altitude needs home")
                    return
                alt = float(home.alt) + float(m.alt)
            else:
                self._refuse(f"{what} invalid coordinate frame {m.coordinate_frame}")
                return
            x, y = project(m.lat_int / 1e7, m.lon_int / 1e7, lp.ref_lat, lp.ref_lon)
            pos = [x, y, float(lp.ref_alt) - alt]
        vel = self._axes(mask, 3, (m.vx, m.vy, m.vz))
        acc = self._axes(mask, 6, (m.afx, m.afy, m.afz))
        yaw, rate = self._yaw(mask, m)
        self._trajectory(what, mask, pos, vel, acc, yaw, rate)

    def _on_attitude(self, m: Any) -> None:
        if not self._for_us(m):
            return
        what = "SET_ATTITUDE_TARGET"
        mask = int(m.type_mask)
        att_ok = not mask & mav.ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE
        rates_ok = not mask & (mav.ATTITUDE_TARGET_TYPEMASK_BODY_ROLL_RATE_IGNORE
                               | mav.ATTITUDE_TARGET_TYPEMASK_BODY_PITCH_RATE_IGNORE)
        yaw_rate = NAN if mask & mav.ATTITUDE_TARGET_TYPEMASK_BODY_YAW_RATE_IGNORE else \
            float(m.body_yaw_rate)
        thrust = float(m.thrust)
        if not math.isfinite(thrust) or (not math.isnan(yaw_rate)
                                         and not math.isfinite(yaw_rate)):
            self._refuse(f"{what}: thrust or yaw rate not finite, setpoint ignored")
            return
        thrust_body = [0.0, 0.0, -min(max(thrust, 0.0), 1.0)]
        if att_ok:
            q = [float(v) for v in m.q]
            n = math.sqrt(sum(v * v for v in q)) if all(math.isfinite(v) for v in q) else 0.0
            if not math.isfinite(n) or n < 1e-6:
                self._refuse(f"{what}: attitude quaternion invalid, setpoint ignored")
                return
            w, x, y, z = (v / n for v in q)
            self._control_mode(attitude=True)
            if not self._in_offboard():
                self.setpoints_ignored += 1
                return

            def fill(a: Any) -> None:
                a.q_d = [w, x, y, z]
                a.roll_body = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
                a.pitch_body = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
                a.yaw_body = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
                a.yaw_sp_move_rate = 0.0 if math.isnan(yaw_rate) else yaw_rate
                a.thrust_body = thrust_body
            self._publish("vehicle_attitude_setpoint", fill)
        elif rates_ok:
            rates = (float(m.body_roll_rate), float(m.body_pitch_rate),
                     0.0 if math.isnan(yaw_rate) else yaw_rate)
            if not all(math.isfinite(v) for v in rates):
                self._refuse(f"{what}: body rate not finite, setpoint ignored")
                return
            self._control_mode(body_rate=True)
            if not self._in_offboard():
                self.setpoints_ignored += 1
                return

            def fill_rates(r: Any) -> None:
                r.roll, r.pitch, r.yaw = rates
                r.thrust_body = thrust_body
            self._publish("vehicle_rates_setpoint", fill_rates)
        else:
            self._refuse(f"{what} invalid")
            return
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


def _rotate(q: tuple[float, ...], v: tuple[float, ...]) -> tuple[float, float, float]:
    """Body -> NED: v rotated by the attitude quaternion (w, x, y, z)."""
    w, x, y, z = q
    vx, vy, vz = v
    # t = 2 q_vec x v; v' = v + w t + q_vec x t
    tx, ty, tz = 2 * (y * vz - z * vy), 2 * (z * vx - x * vz), 2 * (x * vy - y * vx)
    return (vx + w * tx + (y * tz - z * ty), vy + w * ty + (z * tx - x * tz),
            vz + w * tz + (x * ty - y * tx))
