"""commander: arming, flight modes and failsafes (PX4's commander, behaviour not code).

One 100 Hz work item. Each run it reads the latest inputs (see :class:`VehicleData`), handles
queued ``vehicle_command`` messages and RC switches/gestures, keeps the arming state machine
(INIT -> STANDBY / STANDBY_ERROR -> ARMED), decides the navigation state (the pilot's intention,
overridden by failsafe reactions and by fallbacks when a mode cannot run), auto-disarms, sets
home, and publishes ``vehicle_status``, ``vehicle_control_mode``, ``actuator_armed`` (on change
and at 2 Hz) and ``home_position``.

Preflight checks cost more than the rest of the loop, so while disarmed they run at 10 Hz and on
every arming request; their reasons go to dmesg/log_message ("Preflight Fail: ...") when they
first appear and again on each refused arming request, as PX4 reports them to the GCS.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from firmware.modules.commander import failsafe as fs
from firmware.modules.commander import modes
from firmware.modules.commander.checks import Failure, VehicleData, preflight_failures
from firmware.modules.commander.commands import CommandHandler
from firmware.modules.commander.esc_check import EscCheck
from firmware.modules.commander.failure_detector import FAILURE_DETECTOR_PARAMS, FailureDetector
from firmware.modules.commander.geofence import GEOFENCE_PARAMS, Geofence
from firmware.modules.commander.params import PARAMS
from firmware.modules.commander.vehicle_type import (
    MAV_TYPE_QUADROTOR,
    VEHICLE_TYPE_FIXED_WING,
    classify,
    vtol_type,
)
from firmware.platform.module import WorkItemModule

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["CommanderModule"]

# vehicle_status.ARMING_STATE_*
INIT, STANDBY, ARMED, STANDBY_ERROR = 0, 1, 2, 3
# PX4's arm_disarm_reason_t
R_STANDBY, R_RC_STICK, R_RC_SWITCH, R_CMD_INTERNAL, R_CMD_EXTERNAL, R_MISSION_START = range(6)
R_AUTO_DISARM_LAND, R_AUTO_DISARM_PREFLIGHT, R_KILL_SWITCH, R_FAILSAFE = 7, 8, 9, 15
CHECK_EVERY = 10                 # loops between preflight checks while disarmed (10 Hz)
PUBLISH_INTERVAL_US = 500_000
_BAT_TEXT = {1: "Low battery level! Return advised", 2: "Critical battery level!",
             3: "Emergency battery level! Land now"}


# MAV_SYS_STATUS_SENSOR bits (MAVLink common.xml)
_S_GYRO, _S_ACCEL, _S_MAG, _S_BARO, _S_GPS = 0x1, 0x2, 0x4, 0x8, 0x20
_S_RATE, _S_ATT, _S_YAW, _S_ALT, _S_XY = 0x400, 0x800, 0x1000, 0x2000, 0x4000
_S_MOTORS, _S_RC, _S_AHRS, _S_BATTERY, _S_PREARM = 0x8000, 0x10000, 0x200000, 0x2000000, \
    0x10000000
_S_GEOFENCE = 0x100000  # MAV_SYS_STATUS_GEOFENCE


class CommanderModule(CommandHandler, WorkItemModule):
    NAME = "commander"
    DESCRIPTION = "vehicle state: arming, flight modes, failsafes"
    USAGE = ("arm [-f]          arm (-f: skip the preflight checks)",
             "disarm [-f]       disarm (-f: even in the air)",
             "takeoff           switch to Takeoff and arm",
             "land              switch to Land",
             "transition        a VTOL: transition to the other flight mode",
             ("mode <name>       manual|stabilized|altctl|posctl|auto:mission|auto:loiter|"
              "auto:rtl|auto:takeoff|auto:land"),
             "check             run the preflight checks and print the result")
    WQ = "wq:hp_default"
    INTERVAL_US = 10_000
    CPU_COST_NS = 150_000
    PARAMS = PARAMS + GEOFENCE_PARAMS + FAILURE_DETECTOR_PARAMS

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.arming_state = INIT
        self.user_nav = modes.MANUAL
        self.nav_state = modes.MANUAL
        self.failsafe = fs.Failsafe()
        self.failsafe_active = False
        self.failsafe_action = fs.A_NONE
        self.failures: list[Failure] = []
        self.kill_engaged = False
        self.terminated = False
        self.armed_time_us = 0
        self.takeoff_time_us = 0
        self.have_taken_off = False
        self.landed_since_us: int | None = None
        self.arm_reason = R_STANDBY
        self.disarm_reason = R_STANDBY
        self.rc_ok = False
        self.rc_lost = False
        self.dl_lost = False
        self.dl_lost_count = 0
        self.battery_warning = 0
        self.home_valid = False
        self.offboard_lost = False
        self.offboard_lost_us = 0
        self.offboard_mode = modes.offboard_flags(True, False, False, False, False)
        self.geofence = Geofence(self)
        self.failure_detector = FailureDetector(self)
        self.mav_type = MAV_TYPE_QUADROTOR
        self.vehicle_type, self.is_vtol = classify(self.mav_type)
        self.in_transition = False
        self.quad_chute = False

    # -- life cycle ---------------------------------------------------------------------------

    def _start(self) -> None:
        orb = self.platform.orb
        self.data = VehicleData(self)
        self._sub_cmd = self.subscribe("vehicle_command")
        self._sub_sw = self.subscribe("manual_control_switches")
        self._sub_result = self.subscribe("mission_result")
        self._sub_mission = self.subscribe("mission")
        self._sub_param = self.subscribe("parameter_update")
        self._sub_vtol = self.subscribe("vtol_vehicle_status")
        self.esc_check = EscCheck(self)
        self._pub_status = self.advertise("vehicle_status")
        self._pub_mode = self.advertise("vehicle_control_mode")
        self._pub_armed = self.advertise("actuator_armed")
        self._pub_home = self.advertise("home_position")
        self._pub_ack = self.advertise("vehicle_command_ack")
        self._status = orb.new("vehicle_status")
        self._mode = orb.new("vehicle_control_mode")
        self._armed = orb.new("actuator_armed")
        self._home = orb.new("home_position")
        self._ack = orb.new("vehicle_command_ack")
        self._cmd_cls = orb.registry.cls("vehicle_command")
        self._loop = 0
        self._last_pub_us = -PUBLISH_INTERVAL_US
        self._last_sig: tuple | None = None
        self._reported: set[str] = set()
        self._gesture_since: int | None = None
        self._gesture_done = False
        self._sw_last: dict[str, int] = {}
        self._load_params()

    def _load_params(self) -> None:
        self.p: dict[str, int | float] = {d.name: self.param(d.name) for d in self.PARAMS}
        self.rc_loss_us = int(self.p["COM_RC_LOSS_T"] * 1e6)
        self.dl_loss_us = int(self.p["COM_DL_LOSS_T"]) * 1_000_000
        self.of_loss_us = int(self.p["COM_OF_LOSS_T"] * 1e6)
        params = self.system.params
        self.sys_id = int(params.get("MAV_SYS_ID", 1) or 1) if params is not None else 1
        # MAV_TYPE (the mavlink module's parameter, set by the airframe file): the vehicle's
        # type, and with it the control flags of every mode
        mav_type = params.get("MAV_TYPE", MAV_TYPE_QUADROTOR) if params is not None else None
        self.mav_type = int(mav_type) if mav_type is not None else MAV_TYPE_QUADROTOR
        self.vehicle_type, self.is_vtol = classify(self.mav_type)
        self._update_flags()

    def _update_flags(self) -> None:
        fixed_wing = self.vehicle_type == VEHICLE_TYPE_FIXED_WING
        self._flags = {nav: modes.control_flags(nav, fixed_wing=fixed_wing)
                       for nav in modes.NAV_NAMES}

    def mission_count(self) -> int:
        m = self._sub_mission.node.last
        return int(m.count) if m is not None else 0

    # -- the loop -----------------------------------------------------------------------------

    def run(self) -> None:
        now = self.platform.time_us()
        if self._sub_param.updated():
            self._sub_param.copy()
            self._load_params()
        self._loop += 1
        self._update_links(now)
        self._update_vtol()
        while True:
            cmd = self._sub_cmd.update()
            if cmd is None:
                break
            self.handle_command(cmd)
        sw = self._sub_sw.update()
        if sw is not None:
            self._handle_switches(sw)
        self._handle_gestures(now)
        res = self._sub_result.update()
        if (res is not None and res.finished and self.user_nav == modes.AUTO_TAKEOFF
                and self.nav_state == modes.AUTO_TAKEOFF):
            self.user_nav = modes.AUTO_LOITER   # takeoff done: hold there
        self._update_battery()
        self.esc_check.update()
        if self.arming_state == ARMED:
            self._update_in_air(now)
            fd = self.failure_detector
            fd.update(now, self._flags.get(self.nav_state, self._flags[modes.MANUAL])
                      ["flag_control_attitude_enabled"])
            if fd.terminated and not self.terminated:
                self.terminated = True  # flight termination: the IO's failsafe outputs
        elif self._loop % CHECK_EVERY == 1 or self.arming_state == INIT:
            self.run_checks(now)
            if not self.home_valid:
                self.set_home(now, quiet=True)
        self._update_nav(now)
        self._publish(now)

    def _update_links(self, now: int) -> None:
        d, p = self.data, self.p
        rc_ok = d.rc_present(now, self.rc_loss_us)
        rc_lost = d.rc_seen and not rc_ok and p["COM_RC_IN_MODE"] != 4
        if rc_lost != self.rc_lost:
            (self.warn if rc_lost else self.info)(
                "Manual control lost" if rc_lost else "Manual control regained")
            self.rc_lost = rc_lost
        self.rc_ok = rc_ok
        gcs_ok = d.gcs_present(now, self.dl_loss_us)
        dl_lost = d.gcs_seen and not gcs_ok
        if dl_lost != self.dl_lost:
            if dl_lost:
                self.dl_lost_count = (self.dl_lost_count + 1) & 0xFF
            (self.warn if dl_lost else self.info)(
                "Connection to ground station lost" if dl_lost else
                "Data link regained")
            self.dl_lost = dl_lost

    def _update_vtol(self) -> None:
        """A VTOL's type and transition from vtol_att_control (PX4: vtol_vehicle_status);
        its quad-chute (fixed_wing_system_failure) is a failsafe cause with Return."""
        m = self._sub_vtol.update()
        if m is None or not self.is_vtol:
            return
        vtype, self.in_transition = vtol_type(int(m.vehicle_vtol_state))
        if vtype != self.vehicle_type:
            self.vehicle_type = vtype
            self._update_flags()
        self.quad_chute = bool(m.fixed_wing_system_failure)

    def _update_battery(self) -> None:
        bat = self.data.battery.node.last
        level = int(bat.warning) if bat is not None and bat.connected else 0
        if level > self.battery_warning and level in _BAT_TEXT:
            (self.warn if level == 1 else self.error)(_BAT_TEXT[level])
        self.battery_warning = level

    # -- checks and arming ----------------------------------------------------------------------

    def run_checks(self, now: int, nav: int | None = None) -> list[Failure]:
        """Evaluate the preflight checks; update STANDBY/STANDBY_ERROR; report new reasons."""
        failures = preflight_failures(self, self.user_nav if nav is None else nav, now)
        self.failures = failures
        if self.arming_state != ARMED:
            hard = any(f.hard for f in failures)
            self.arming_state = STANDBY_ERROR if hard else STANDBY
        texts = {f.text for f in failures}
        for text in sorted(texts - self._reported):
            self.warn(text)
        self._reported = texts
        return failures

    def arm(self, reason: int, force: bool = False) -> tuple[bool, str]:
        """Arm unless a check fails (``force`` skips them); (accepted, why not)."""
        if self.arming_state == ARMED:
            return True, "already armed"
        now = self.platform.time_us()
        if not force:
            failures = self.run_checks(now)
            if failures:
                for f in failures:
                    self.error(f.text)
                return False, failures[0].text
        self.arming_state = ARMED
        self.armed_time_us = now
        self.arm_reason = reason
        self.have_taken_off = False
        self.takeoff_time_us = 0
        self.landed_since_us = None
        self.failsafe.clear()
        self.failure_detector.reset()
        self.set_home(now, quiet=True)
        self.info("Armed" + (" (forced)" if force else ""))
        return True, ""

    def disarm(self, reason: int, force: bool = False) -> tuple[bool, str]:
        """Disarm; refused in the air unless forced or for a failsafe/kill."""
        if self.arming_state != ARMED:
            return True, "already disarmed"
        if not force and not self.data.landed() and reason in (
                R_RC_STICK, R_RC_SWITCH, R_CMD_INTERNAL, R_CMD_EXTERNAL):
            self.warn("Disarming denied: not landed")
            return False, "Disarming denied: not landed"
        self.arming_state = STANDBY
        self.armed_time_us = 0
        self.disarm_reason = reason
        if self._flags[self.user_nav]["flag_control_auto_enabled"] and \
                self.user_nav != modes.AUTO_LOITER:
            # PX4's commander: "switch back to Hold mode after autonomous landing". Land,
            # Return and Descend refuse arming, so staying in them made a second flight
            # impossible; Hold arms, and a takeoff or mission command starts from it.
            self.user_nav = modes.AUTO_LOITER
            self.info("Mode Hold (disarmed in an auto mode)")
        self.failsafe.clear()
        self.terminated = False
        self.info("Disarmed" + {R_AUTO_DISARM_LAND: " by auto disarm on land",
                                R_AUTO_DISARM_PREFLIGHT: " by auto disarm (no takeoff)",
                                R_FAILSAFE: " by failsafe"}.get(reason, ""))
        self.run_checks(self.platform.time_us())
        return True, ""

    def _update_in_air(self, now: int) -> None:
        landed = self.data.landed()
        if not landed:
            if not self.have_taken_off:
                self.have_taken_off = True
                self.takeoff_time_us = now
            self.landed_since_us = None
            return
        if self.landed_since_us is None:
            self.landed_since_us = now
        p = self.p
        t = p["COM_DISARM_LAND"] if self.have_taken_off else p["COM_DISARM_PRFLT"]
        if t > 0 and now - self.landed_since_us >= t * 1e6:
            self.disarm(R_AUTO_DISARM_LAND if self.have_taken_off else R_AUTO_DISARM_PREFLIGHT)

    # -- modes --------------------------------------------------------------------------------

    def requirements_ok(self, now: int) -> dict[str, bool]:
        d, eph = self.data, self.p["COM_POS_FS_EPH"]
        return {"manual": self.rc_ok, "alt": d.alt_valid(now), "lpos": d.lpos_valid(now, eph),
                "gpos": d.gpos_valid(now, eph), "home": self.home_valid,
                "mission": self.mission_count() > 0, "never": False,
                "offboard": d.offboard_ok(now, self.of_loss_us, eph)}

    def set_user_mode(self, nav: int, why: str = "") -> tuple[bool, str]:
        """The pilot (or GCS) selects a mode. Armed, the mode must be able to run now;
        disarmed, only unsupported modes and Mission without a mission are refused (the
        preflight checks say what else is missing)."""
        name = modes.NAV_NAMES.get(nav, str(nav))
        req = modes.REQUIREMENTS.get(nav)
        if req is None:
            return False, f"mode {nav} unknown"
        now = self.platform.time_us()
        ok = self.requirements_ok(now)
        need = req if self.arming_state == ARMED else req & {"never", "mission"}
        missing = sorted(r for r in need if not ok.get(r, False))
        if missing:
            text = f"Switching to {name} is currently not possible ({', '.join(missing)})"
            self.warn(text)
            return False, text
        if nav != self.user_nav:
            self.info(f"Mode {name}" + (f" ({why})" if why else ""))
        self.user_nav = nav
        self.failsafe.user_mode_change({"rc": self.rc_lost, "datalink": self.dl_lost,
                                        "battery": True})
        return True, ""

    def _failsafe_triggers(self, now: int, in_air: bool) -> None:
        p, f = self.p, self.failsafe
        user = self.user_nav
        exc = int(p["COM_RCL_EXCEPT"])
        rc_ignored = (user in (modes.AUTO_RTL, modes.AUTO_LAND, modes.DESCEND)
                      or (exc & 1 and user == modes.AUTO_MISSION)
                      or (exc & 2 and user == modes.AUTO_LOITER)
                      or (exc & 4 and user == modes.OFFBOARD))
        if f.update("rc", self.rc_lost and not rc_ignored,
                    fs.action_from_param(int(p["NAV_RCL_ACT"])), now, in_air):
            self.error(f"Failsafe: manual control lost, "
                       f"{fs.ACTION_NAMES_LOWER[f.causes['rc'].action]}")
        if f.update("datalink", self.dl_lost, fs.action_from_param(int(p["NAV_DLL_ACT"])), now,
                    in_air):
            self.error(f"Failsafe: no connection to ground station, "
                       f"{fs.ACTION_NAMES_LOWER[f.causes['datalink'].action]}")
        self.geofence.update(now, in_air)
        if f.update("quad_chute", self.quad_chute, fs.A_RTL, now, in_air):
            self.error("Failsafe: VTOL quad-chute, return")
        level = self.battery_warning
        if f.update("battery", level >= 2, fs.battery_action(int(p["COM_LOW_BAT_ACT"]), level),
                    now, in_air, level):
            self.error(f"Failsafe: low battery, "
                       f"{fs.ACTION_NAMES_LOWER[f.causes['battery'].action]}")

    def _update_nav(self, now: int) -> None:
        if self.arming_state != ARMED:
            self.nav_state, self.failsafe_active, self.failsafe_action = \
                self.user_nav, False, fs.A_NONE
            self.offboard_lost = False
            return
        in_air = not self.data.landed()
        self._failsafe_triggers(now, in_air)
        action, delayed = self.failsafe.active(now, int(self.p["COM_FAIL_ACT_T"] * 1e6))
        if self.terminated:
            action, delayed = fs.A_TERMINATE, False
        if action == fs.A_DISARM:
            self.disarm(R_FAILSAFE, force=True)
            self._update_nav(now)
            return
        target = self.user_nav
        if action != fs.A_NONE:
            target = modes.AUTO_LOITER if delayed else (fs.action_nav(action) or target)
        elif self._offboard_lost(now):
            lost_nav = fs.offboard_loss_nav(int(self.p["COM_OBL_RC_ACT"]),
                                            self.requirements_ok(now))
            if lost_nav is None:
                self.disarm(R_FAILSAFE, force=True)
                self._update_nav(now)
                return
            # COM_FAIL_ACT_T: hold before a Return/Land/Descend reaction, as for every cause
            delay_us = int(self.p["COM_FAIL_ACT_T"] * 1e6)
            held = lost_nav in (modes.AUTO_RTL, modes.AUTO_LAND, modes.DESCEND) and \
                now - self.offboard_lost_us < delay_us
            target = modes.AUTO_LOITER if held else lost_nav
        nav = target if target == modes.TERMINATION else \
            fs.fallback(target, self.requirements_ok(now))
        if nav != self.nav_state and nav != target:
            self.warn(f"{modes.NAV_NAMES.get(target)} not possible, "
                      f"{modes.NAV_NAMES.get(nav)} instead")
        self.nav_state = nav
        self.failsafe_action = action if action != fs.A_NONE else (
            fs.A_NONE if nav == self.user_nav else fs.A_LAND if nav == modes.AUTO_LAND
            else fs.A_DESCEND if nav == modes.DESCEND else fs.A_HOLD)
        self.failsafe_active = nav != self.user_nav or action != fs.A_NONE

    def _offboard_lost(self, now: int) -> bool:
        """Offboard mode selected, armed, and its signal gone for COM_OF_LOSS_T (PX4's
        offboard_control_signal_lost as a mode fallback: not latched, so Offboard resumes
        when setpoints come back, unless the pilot picked another mode meanwhile)."""
        lost = self.user_nav == modes.OFFBOARD and not self.requirements_ok(now)["offboard"]
        if lost and not self.offboard_lost:
            self.offboard_lost_us = now
            act = int(self.p["COM_OBL_RC_ACT"])
            nav = fs.offboard_loss_nav(act, self.requirements_ok(now))
            what = "disarm" if nav is None else modes.NAV_NAMES.get(nav, str(nav)).lower()
            self.error(f"Failsafe: offboard control lost, {what}")
        elif not lost and self.offboard_lost and self.user_nav == modes.OFFBOARD:
            self.info("Offboard control regained")
        self.offboard_lost = lost
        return lost

    # -- home -----------------------------------------------------------------------------------

    def set_home(self, now: int, quiet: bool = False, lat: float | None = None,
                 lon: float | None = None, alt: float | None = None) -> bool:
        """Home at the current position (or the given one); False without a position."""
        d = self.data
        g, lp = d.gpos.node.last, d.lpos.node.last
        h = self._home
        if lat is None:
            if not d.gpos_valid(now, self.p["COM_POS_FS_EPH"]) or g is None:
                return False
            lat, lon, alt = g.lat, g.lon, g.alt
        h.timestamp = now
        h.lat, h.lon, h.alt = float(lat), float(lon), float(alt if alt is not None else 0.0)
        h.valid_alt = h.valid_hpos = True
        h.valid_lpos = lp is not None and bool(lp.xy_valid and lp.z_valid)
        if lp is not None:
            h.x, h.y, h.z, h.yaw = lp.x, lp.y, lp.z, lp.heading
        h.manual_home = not quiet
        self.home_valid = True
        self._pub_home.publish(h)
        if not quiet:
            self.info(f"Home set: {h.lat:.7f}, {h.lon:.7f}, {h.alt:.1f} m")
        return True

    # -- publication ------------------------------------------------------------------------------

    def _publish(self, now: int) -> None:
        armed = self.arming_state == ARMED
        ready = self.arming_state == STANDBY and not any(not f.at_arming for f in self.failures)
        bat = self.battery_warning
        ocm = self.data.offboard.node.last
        if ocm is not None:
            self.offboard_mode = modes.offboard_flags(
                bool(ocm.position), bool(ocm.velocity), bool(ocm.acceleration),
                bool(ocm.attitude), bool(ocm.body_rate))
        sig = (self.offboard_mode, self.arming_state, self.nav_state, self.user_nav,
               self.failsafe_active,
               self.failsafe_action, self.rc_lost, self.dl_lost, ready, bat, self.kill_engaged,
               self.have_taken_off, self.failure_detector.status, self.failure_detector.lockdown,
               self.mav_type, self.vehicle_type, self.in_transition)
        if sig == self._last_sig and now - self._last_pub_us < PUBLISH_INTERVAL_US:
            return
        self._last_sig, self._last_pub_us = sig, now
        s = self._status
        s.timestamp = now
        s.arming_state = self.arming_state
        s.armed_time = self.armed_time_us if armed else 0
        s.takeoff_time = self.takeoff_time_us
        s.failure_detector_status = self.failure_detector.status
        s.latest_arming_reason = self.arm_reason
        s.latest_disarming_reason = self.disarm_reason
        s.nav_state = self.nav_state
        s.nav_state_user_intention = self.user_nav
        s.vehicle_type = self.vehicle_type
        s.is_vtol = self.is_vtol
        s.in_transition_mode = self.in_transition
        s.system_type = self.mav_type
        s.system_id = self.sys_id
        s.component_id = 1
        s.failsafe = self.failsafe_active
        s.failsafe_action = self.failsafe_action
        s.failsafe_and_user_took_over = self.failsafe.user_took_over
        s.rc_signal_lost = (not self.rc_ok) and self.p["COM_RC_IN_MODE"] != 4
        s.data_link_lost = self.dl_lost
        s.data_link_lost_counter = self.dl_lost_count
        s.pre_flight_checks_pass = not self.failures
        s.battery_low = bat >= 1
        s.battery_critical = bat >= 2
        (s.onboard_control_sensors_present, s.onboard_control_sensors_enabled,
         s.onboard_control_sensors_health) = self._sensor_bits(armed, bat)
        self._pub_status.publish(s)

        m = self._mode
        m.timestamp = now
        flags = modes.control_flags(modes.OFFBOARD, self.offboard_mode,
                                    self.vehicle_type == VEHICLE_TYPE_FIXED_WING) \
            if self.nav_state == modes.OFFBOARD else \
            self._flags.get(self.nav_state, self._flags[modes.MANUAL])
        for k, v in flags.items():
            setattr(m, k, v)
        m.flag_armed = armed
        self._pub_mode.publish(m)

        a = self._armed
        a.timestamp = now
        a.armed = armed
        prearm = int(self.p["COM_PREARM_MODE"])
        io = self.data.io.node.last
        safety_off = io is not None and io.status_safety_off
        a.prearmed = armed or prearm == 2 or (prearm == 1 and safety_off)
        a.ready_to_arm = ready or armed
        a.lockdown = armed and self.failure_detector.lockdown
        a.manual_lockdown = self.kill_engaged
        a.force_failsafe = self.nav_state == modes.TERMINATION
        self._pub_armed.publish(a)

    def _sensor_bits(self, armed: bool, bat: int) -> tuple[int, int, int]:
        """MAV_SYS_STATUS_SENSOR present/enabled/health bits, as PX4 reports them in SYS_STATUS
        (ground stations and MAVSDK's health checks read them)."""
        d = self.data
        present = enabled = health = 0

        def put(bit: int, is_present: bool, ok: bool, on: bool = True) -> None:
            nonlocal present, enabled, health
            if is_present:
                present |= bit
                if on:
                    enabled |= bit
                if ok:
                    health |= bit

        imu, baro, mag = d.imu.node.last, d.baro.node.last, d.mag.node.last
        imu_ok = imu is not None and any(imu.healthy)
        put(_S_GYRO | _S_ACCEL, imu is not None, imu_ok)
        put(_S_MAG, mag is not None, mag is not None and any(mag.healthy))
        put(_S_BARO, baro is not None, baro is not None and any(baro.healthy))
        gps = d.gps.node.last
        put(_S_GPS, gps is not None, gps is not None and gps.fix_type >= 3)
        est = d.estimator.node.last
        put(_S_AHRS, est is not None, est is not None and not est.filter_fault_flags)
        put(_S_RC, d.rc_seen, self.rc_ok)
        put(_S_RATE | _S_ATT | _S_YAW, True, True, armed)
        put(_S_ALT | _S_XY, True, True, armed)
        put(_S_MOTORS, True, True, armed)
        put(_S_BATTERY, d.battery.node.last is not None, bat < 2)
        put(_S_PREARM, True, not self.failures)
        gf_present, gf_enabled, gf_ok = self.geofence.sensor_bits()
        put(_S_GEOFENCE, gf_present, gf_ok, gf_enabled)
        if gf_ok:  # healthy even when no fence is set: MAVProxy reads a clear bit as a breach
            health |= _S_GEOFENCE
        return present, enabled, health

    def status_lines(self) -> list[str]:
        state = {INIT: "INIT", STANDBY: "STANDBY", ARMED: "ARMED",
                 STANDBY_ERROR: "STANDBY_ERROR"}[self.arming_state]
        vtype = {VEHICLE_TYPE_FIXED_WING: "fixed wing", 1: "rotary wing"}.get(
            self.vehicle_type, "unknown")
        out = [f"arming state: {state}",
               f"vehicle type: {vtype}{' (VTOL)' if self.is_vtol else ''}, MAV_TYPE "
               f"{self.mav_type}",
               (f"navigation state: {modes.NAV_NAMES.get(self.nav_state)} "
                f"(user: {modes.NAV_NAMES.get(self.user_nav)})"),
               f"failsafe: {fs.ACTION_NAMES_LOWER[self.failsafe_action]}"
               + (f" ({', '.join(self.failsafe.active_causes())})" if self.failsafe_active
                  else ""),
               (f"rc lost: {self.rc_lost}, data link lost: {self.dl_lost}, battery warning: "
                f"{self.battery_warning}, home: {'set' if self.home_valid else 'not set'}")]
        out += [f.text for f in self.failures]
        return out

    def ack(self, cmd: Any, result: int, param1: int = 0) -> None:
        """Answer a vehicle_command (every command the commander handles gets one)."""
        a = self._ack
        a.timestamp = self.platform.time_us()
        a.command = cmd.command
        a.result = result
        a.result_param1 = param1
        a.target_system = cmd.source_system
        a.target_component = cmd.source_component
        a.from_external = cmd.from_external
        self._pub_ack.publish(a)
        self.last_ack = (cmd.command, result)
