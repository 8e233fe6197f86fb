"""navigator: position setpoints for the auto modes (PX4's navigator, behaviour not code).

Runs at 20 Hz on ``wq:nav_and_controllers``. The commander's ``vehicle_status.nav_state`` picks
the mode (Takeoff, Hold, Mission, Return, Land); the mode writes ``position_setpoint_triplet``
(previous / current / next, global coordinates, AMSL altitudes), published when it changes and
at 1 Hz. In the other states the triplet is published once as invalid, so the position
controller never follows a stale auto setpoint. Reached-checks use ``vehicle_global_position``;
landing completes on ``vehicle_land_detected.landed``.

The mission comes from dataman (``firmware.modules.dataman``): the ``mission`` topic says which
slot and item are active, the items are read from the running dataman's store.
``vehicle_command`` is read for what the commander leaves to the navigator: the takeoff altitude
(NAV_TAKEOFF param7), the hold position (DO_REPOSITION), the first mission item
(MISSION_START param1). DO_CHANGE_SPEED is the navigator's own: it sets the cruise speed and
acks it (``VEHICLE_COMMANDS``, so the commander leaves it alone). A mission's RTL item is passed
to the commander as a command.

Fixed wing (``vehicle_status.vehicle_type``, from the airframe's MAV_TYPE), as PX4's navigator:
altitudes count as reached within NAV_FW_ALT_RAD (NAV_FW_ALTL_RAD for the waypoint before a
landing) instead of NAV_MC_ALT_RAD; a waypoint within the larger of its acceptance radius and
the L1 distance fw_pos_control_l1 reports in ``position_controller_status`` (a plane must turn
before it gets there); every setpoint carries the loiter radius (NAV_LOITER_RAD) the position
controller circles at. The modes' own differences are in their files.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, ClassVar, Final

from firmware.modules.dataman import find_store
from firmware.modules.navigator.geo import distance_m
from firmware.modules.navigator.mission import MissionMode
from firmware.modules.navigator.modes import (
    SP_IDLE,
    SP_LAND,
    SP_LOITER,
    LandMode,
    LoiterMode,
    NavMode,
    TakeoffMode,
    copy_setpoint,
)
from firmware.modules.navigator.params import PARAMS
from firmware.modules.navigator.rtl import RtlMode
from firmware.platform.module import WorkItemModule

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["NavigatorModule"]

# vehicle_status.NAVIGATION_STATE_*
NAV_MISSION: Final = 3
NAV_LOITER: Final = 4
NAV_RTL: Final = 5
NAV_TAKEOFF: Final = 17
NAV_LAND: Final = 18
VEHICLE_TYPE_FIXED_WING: Final = 2
POS_TIMEOUT_US: Final = 1_000_000
REPUBLISH_US: Final = 1_000_000
CMD_TAKEOFF: Final = 22
CMD_REPOSITION: Final = 192
CMD_MISSION_START: Final = 300
CMD_DO_CHANGE_SPEED: Final = 178


class NavigatorModule(WorkItemModule):
    NAME = "navigator"
    DESCRIPTION = "auto modes: takeoff, hold, mission, return, land setpoints"
    WQ = "wq:nav_and_controllers"
    INTERVAL_US = 50_000
    CPU_COST_NS = 120_000
    PARAMS = PARAMS
    #: commands this module answers with its own vehicle_command_ack (see the commander)
    VEHICLE_COMMANDS: ClassVar[frozenset[int]] = frozenset({CMD_DO_CHANGE_SPEED})

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.takeoff_alt_cmd: float | None = None
        self.reposition: tuple[float, float, float, float] | None = None
        self.armed = False
        self.now_us = 0

    def _start(self) -> None:
        orb = self.platform.orb
        self._sub_status = self.subscribe("vehicle_status")
        self._sub_gpos = self.subscribe("vehicle_global_position")
        self._sub_lpos = self.subscribe("vehicle_local_position")
        self._sub_home = self.subscribe("home_position")
        self._sub_land = self.subscribe("vehicle_land_detected")
        self._sub_mission = self.subscribe("mission")
        self._sub_cmd = self.subscribe("vehicle_command")
        self._sub_param = self.subscribe("parameter_update")
        # fw_pos_control_l1's acceptance radius (the L1 distance), when the build has the topic
        self._sub_pcs = self.subscribe("position_controller_status") \
            if "position_controller_status" in orb.registry.topics else None
        self._pub_triplet = self.advertise("position_setpoint_triplet")
        self._pub_result = self.advertise("mission_result")
        self._pub_cmd = self.advertise("vehicle_command")
        self._pub_ack = self.advertise("vehicle_command_ack")
        self._ack = orb.new("vehicle_command_ack")
        self.triplet = orb.new("position_setpoint_triplet")
        #: cruise speed set by a mission's DO_CHANGE_SPEED, m/s (-1: the controller's default)
        self.cruise_speed = -1.0
        self.result = orb.new("mission_result")
        self.result.seq_reached = -1
        self._cmd = orb.new("vehicle_command")
        self.mission = MissionMode(self)
        self.modes: dict[int, NavMode] = {
            NAV_TAKEOFF: TakeoffMode(self), NAV_LOITER: LoiterMode(self),
            NAV_MISSION: self.mission, NAV_RTL: RtlMode(self), NAV_LAND: LandMode(self)}
        self.active: NavMode | None = None
        self.nav_state = -1
        self._dirty = False
        self._last_pub_us = 0
        self._load_params()

    def _load_params(self) -> None:
        self.p = {d.name: float(self.param(d.name)) for d in PARAMS}

    # -- helpers for the modes --------------------------------------------------------------

    def position(self) -> tuple[float, float, float] | None:
        node = self._sub_gpos.node
        g = node.last
        if g is None or self.now_us - node.last_publish_ns // 1000 > POS_TIMEOUT_US:
            return None
        return g.lat, g.lon, g.alt

    def heading(self) -> float:
        lp = self._sub_lpos.node.last
        return float(lp.heading) if lp is not None else math.nan

    def home(self) -> tuple[float, float, float, float] | None:
        h = self._sub_home.node.last
        if h is None or not h.valid_hpos:
            return None
        return h.lat, h.lon, h.alt, h.yaw

    def home_alt(self) -> float | None:
        h = self._sub_home.node.last
        return float(h.alt) if h is not None and h.valid_alt else None

    def landed(self) -> bool:
        m = self._sub_land.node.last
        return True if m is None else bool(m.landed)

    def fixed_wing(self) -> bool:
        """The commander says the vehicle flies as a plane (MAV_TYPE 1, or a VTOL in FW)."""
        st = self._sub_status.node.last
        return st is not None and st.vehicle_type == VEHICLE_TYPE_FIXED_WING

    def is_vtol(self) -> bool:
        st = self._sub_status.node.last
        return st is not None and bool(st.is_vtol)

    def vtol_state_is(self, fixed_wing: bool) -> bool:
        """A VTOL's transition is over and it flies as ``fixed_wing`` says (the commander's
        vehicle_type from vtol_vehicle_status)."""
        st = self._sub_status.node.last
        return st is not None and not st.in_transition_mode and \
            (st.vehicle_type == VEHICLE_TYPE_FIXED_WING) == fixed_wing

    def alt_acc(self) -> float:
        """Altitude acceptance radius (PX4's get_altitude_acceptance_radius): NAV_MC_ALT_RAD,
        on a plane NAV_FW_ALT_RAD, or NAV_FW_ALTL_RAD while the next setpoint is a landing."""
        if not self.fixed_wing():
            return self.p["NAV_MC_ALT_RAD"]
        n = self.triplet.next
        if n.valid and n.type == SP_LAND:
            return self.p["NAV_FW_ALTL_RAD"]
        return self.p["NAV_FW_ALT_RAD"]

    def acc_radius(self, radius: float | None = None) -> float:
        """Horizontal acceptance radius (PX4's get_acceptance_radius): ``radius`` (default
        NAV_ACC_RAD), or the position controller's own when that is larger and newer than
        the current setpoint (a plane's L1 distance)."""
        r = self.p["NAV_ACC_RAD"] if radius is None or radius <= 0 else float(radius)
        sub = self._sub_pcs
        pcs = sub.node.last if sub is not None else None
        if pcs is not None and pcs.timestamp > self.triplet.current.timestamp and \
                math.isfinite(pcs.acceptance_radius) and pcs.acceptance_radius > r:
            r = float(pcs.acceptance_radius)
        return r

    def loiter_radius(self) -> float:
        return self.p["NAV_LOITER_RAD"]

    def is_at(self, lat: float, lon: float, alt: float) -> bool:
        pos = self.position()
        return pos is not None and abs(pos[2] - alt) <= self.alt_acc() and \
            distance_m(pos[0], pos[1], lat, lon) <= self.acc_radius()

    def set_current(self, sp_type: int, lat: float, lon: float, alt: float, yaw: float,
                    previous: bool = True, acc: float | None = None,
                    loiter_radius: float | None = None) -> None:
        """New current setpoint; the old one becomes ``previous``; ``next`` is cleared. A
        plane's setpoints carry the loiter radius (``loiter_radius``, else NAV_LOITER_RAD)."""
        t = self.triplet
        if previous and t.current.valid:
            copy_setpoint(t.previous, t.current)
        else:
            t.previous.valid = False
        c = t.current
        c.timestamp = self.now_us
        c.valid = True
        c.type = sp_type
        c.lat, c.lon, c.alt = float(lat), float(lon), float(alt)
        c.yaw_valid = math.isfinite(yaw)
        c.yaw = float(yaw) if c.yaw_valid else math.nan
        c.acceptance_radius = acc if acc is not None else self.p["NAV_ACC_RAD"]
        if self.fixed_wing():
            c.loiter_radius = loiter_radius if loiter_radius is not None and \
                loiter_radius > 0 else self.p["NAV_LOITER_RAD"]
        c.cruising_speed = self.cruise_speed
        c.vx = c.vy = c.vz = 0.0
        t.next.valid = False
        self._dirty = True

    def set_next(self, sp: tuple[int, float, float, float] | None) -> None:
        n = self.triplet.next
        if sp is None:
            n.valid = False
        else:
            n.timestamp = self.now_us
            n.valid = True
            n.type, n.lat, n.lon, n.alt = sp[0], float(sp[1]), float(sp[2]), float(sp[3])
            if self.fixed_wing():
                n.loiter_radius = self.p["NAV_LOITER_RAD"]
            n.yaw_valid = False
            n.yaw = math.nan
        self._dirty = True

    def set_idle(self) -> None:
        """On the ground: motors at idle, no position to follow."""
        pos = self.position()
        lat, lon, alt = pos if pos is not None else (0.0, 0.0, 0.0)
        self.set_current(SP_IDLE, lat, lon, alt, self.heading(), previous=False)

    def set_invalid(self) -> None:
        t = self.triplet
        t.previous.valid = t.current.valid = t.next.valid = False
        self._dirty = True

    def hold_here(self, at_setpoint: bool = False) -> None:
        cur = self.triplet.current
        if at_setpoint and cur.valid:
            self.set_current(SP_LOITER, cur.lat, cur.lon, cur.alt, cur.yaw)
            return
        pos = self.position()
        if pos is None:
            self.set_invalid()
        else:
            self.set_current(SP_LOITER, pos[0], pos[1], pos[2], self.heading())

    def result_finished(self, finished: bool) -> None:
        self.result.finished = finished
        self.publish_result()

    def publish_result(self) -> None:
        self.result.timestamp = self.now_us
        self._pub_result.publish(self.result)

    def send_command(self, command: int, param1: float = 0.0) -> None:
        c = self._cmd
        c.timestamp = self.now_us
        c.command = command
        c.param1 = param1
        c.param5 = c.param6 = math.nan
        c.param7 = math.nan
        c.target_system = 0
        c.source_component = 190  # MAV_COMP_ID_MISSIONPLANNER, as PX4's navigator
        self._pub_cmd.publish(c)

    # -- the loop ---------------------------------------------------------------------------

    def run(self) -> None:
        self.now_us = now = self.platform.time_us()
        if self._sub_param.updated():
            self._sub_param.copy()
            self._load_params()
        self._read_commands()
        if self._sub_mission.updated():
            self.mission.load(find_store(self.system), self._sub_mission.copy())
            if self.active is self.mission:
                self.mission.on_activation()
        st = self._sub_status.node.last
        nav_state = st.nav_state if st is not None else -1
        armed = st is not None and st.arming_state == st.ARMING_STATE_ARMED
        mode = self.modes.get(nav_state)
        if nav_state != self.nav_state or armed != self.armed:
            self.armed = armed
            self.nav_state = nav_state
            if self.active is not None and self.active is not mode:
                self.active.on_inactivation()
            self.active = mode
            if mode is not None:
                mode.on_activation()
            else:
                self.set_invalid()
        if mode is not None:
            mode.on_active()
        if self._dirty or (mode is not None and now - self._last_pub_us >= REPUBLISH_US):
            self._dirty = False
            self._last_pub_us = now
            self.triplet.timestamp = now
            self._pub_triplet.publish(self.triplet)

    def _read_commands(self) -> None:
        while True:
            cmd = self._sub_cmd.update()
            if cmd is None:
                return
            if cmd.command == CMD_TAKEOFF:
                self.takeoff_alt_cmd = cmd.param7 if math.isfinite(cmd.param7) else None
            elif cmd.command == CMD_REPOSITION:
                self.reposition = (cmd.param5, cmd.param6, cmd.param7, cmd.param4)
            elif cmd.command == CMD_MISSION_START and cmd.param1 >= 0 and \
                    math.isfinite(cmd.param1):
                self.mission.start_at(int(cmd.param1))
            elif cmd.command == CMD_DO_CHANGE_SPEED:
                self.change_speed(cmd.param2)
                self._answer(cmd, 0)  # ACCEPTED

    def change_speed(self, speed_m_s: float) -> None:
        """DO_CHANGE_SPEED (PX4's navigator): a speed above zero is the new cruise speed,
        anything else (0, -1, NaN) goes back to the controller's default (MPC_XY_CRUISE). The
        current setpoint takes it at once (PX4 applies it to the active triplet)."""
        self.cruise_speed = float(speed_m_s) if speed_m_s > 0.0 and math.isfinite(
            speed_m_s) else -1.0
        if self.triplet.current.valid:
            self.triplet.current.cruising_speed = self.cruise_speed
            self._dirty = True

    def _answer(self, cmd: Any, result: int) -> None:
        a = self._ack
        a.timestamp = self.now_us
        a.command = cmd.command
        a.result = result
        a.target_system = cmd.source_system
        a.target_component = cmd.source_component
        a.from_external = cmd.from_external
        self._pub_ack.publish(a)

    def status_lines(self) -> list[str]:
        c = self.triplet.current
        active = self.active.name if self.active else "none"
        out = [f"mode: {active} (nav_state {self.nav_state})"]
        if c.valid:
            out.append(f"current: type {c.type} at {c.lat:.7f}, {c.lon:.7f}, {c.alt:.1f} m")
        m = self.mission
        out.append(f"mission: {len(m.items)} items, current {m.index}, reached "
                   f"{m.seq_reached}, finished {m.finished}")
        return out
