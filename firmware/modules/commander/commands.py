"""The commander's inputs that ask for something: vehicle_command, RC switches and gestures, and
the shell (``commander arm|disarm|takeoff|land|mode|check``).

A mixin of :class:`~firmware.modules.commander.commander.CommanderModule`, kept apart because
it is a dispatch table over MAVLink command numbers rather than vehicle logic. Every command the
commander handles is answered with ``vehicle_command_ack``. A command that a running module
answers itself (it lists it in its ``VEHICLE_COMMANDS``, as the navigator lists
DO_CHANGE_SPEED) is left to that module, and the ones the MAVLink link answers never get here;
anything else is acked UNSUPPORTED. PX4's commander leaves a fixed list of commands
unanswered for modules that may not even run, so a ground station waits for a time-out; here
every command gets exactly one ack (issue 21).
The shell builds the same vehicle_command and runs it synchronously, so a shell arm and a GCS
arm take the same path and both show up in the log as acks.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from firmware.modules.commander import modes
from firmware.modules.commander.params import FORCE_ARM_MAGIC
from firmware.platform.module import UsageError

__all__ = ["CMD", "RESULT", "CommandHandler"]

#: MAV_CMD ids the commander knows
CMD = {
    "NAV_RETURN_TO_LAUNCH": 20, "NAV_LAND": 21, "NAV_TAKEOFF": 22, "DO_SET_MODE": 176,
    "DO_SET_HOME": 179, "DO_FLIGHTTERMINATION": 185, "DO_REPOSITION": 192,
    "PREFLIGHT_REBOOT_SHUTDOWN": 246, "MISSION_START": 300, "COMPONENT_ARM_DISARM": 400,
    "PREFLIGHT_CALIBRATION": 241, "PREFLIGHT_STORAGE": 245, "RUN_PREARM_CHECKS": 401,
    "DO_MOTOR_TEST": 209, "ACTUATOR_TEST": 310,
}
ACCEPTED, TEMPORARILY_REJECTED, DENIED, UNSUPPORTED, FAILED = 0, 1, 2, 3, 4
RESULT = {ACCEPTED: "accepted", TEMPORARILY_REJECTED: "temporarily rejected", DENIED: "denied",
          UNSUPPORTED: "unsupported", FAILED: "failed"}
#: commands the MAVLink link answers itself (message requests and intervals, capabilities,
#: protocol version): they reach vehicle_command only from inside the FMU, never to be acked
LINK_COMMANDS = frozenset({511, 512, 519, 520})
SWITCH_NONE, SWITCH_ON, SWITCH_OFF = 0, 1, 3
_MAV_MODE_FLAG_CUSTOM, _FLAG_AUTO, _FLAG_GUIDED, _FLAG_STABILIZE, _FLAG_MANUAL = 1, 4, 8, 16, 64
_GESTURE_STICK = 0.8
_MANUAL_NAV = frozenset({modes.MANUAL, modes.STAB, modes.ACRO, modes.ALTCTL, modes.POSCTL})



def _param_int(value: float, default: int = 0) -> int:
    """A MAVLink command parameter as an integer; NaN (MAVLink's "unused") gives ``default``."""
    if value != value or value in (float("inf"), float("-inf")):
        return default
    return int(round(value))

class CommandHandler:
    """vehicle_command dispatch, RC switches and gestures, shell commands."""

    last_reason = ""
    # provided by CommanderModule
    arming_state: int
    user_nav: int
    p: dict[str, int | float]  # parameter values: int for INT32 parameters, else float
    _reported: set[str]

    # -- vehicle_command --------------------------------------------------------------------

    def handle_command(self, cmd: Any) -> int | None:
        """Execute one command and ack it; None if it is not for us (no ack).

        A command whose parameters make a handler fail (a ground station sending NaN where a
        number is needed) is acked FAILED with the reason; it never takes the commander down.
        """
        if cmd.target_system not in (0, self.sys_id):  # type: ignore[attr-defined]
            return None
        command = int(cmd.command)
        if command in LINK_COMMANDS or self._answered_elsewhere(command):
            return None
        handler: Callable[[Any], int] | None = self._handlers().get(command)
        self.last_reason = ""
        if handler is None:
            result = UNSUPPORTED
            self.last_reason = f"command {cmd.command} not supported"
        else:
            try:
                result = handler(cmd)
            except (ValueError, TypeError, OverflowError) as exc:
                result = FAILED
                self.last_reason = f"command {cmd.command}: bad parameter ({exc})"
                self.platform.error("commander", self.last_reason)  # type: ignore[attr-defined]
        self.ack(cmd, result)  # type: ignore[attr-defined]
        return result

    def _answered_elsewhere(self, command: int) -> bool:
        """True if a running module answers ``command`` with its own ack (its class lists it
        in ``VEHICLE_COMMANDS``): the commander must not answer it a second time."""
        modules = self.system.modules  # type: ignore[attr-defined]
        for name in modules.running():
            mod = modules.get(name)
            if mod is not None and command in getattr(mod, "VEHICLE_COMMANDS", ()):
                return True
        return False

    def _handlers(self) -> dict[int, Callable[[Any], int]]:
        return {CMD["COMPONENT_ARM_DISARM"]: self._cmd_arm, CMD["DO_SET_MODE"]: self._cmd_mode,
                CMD["NAV_TAKEOFF"]: self._mode_cmd(modes.AUTO_TAKEOFF),
                CMD["NAV_LAND"]: self._mode_cmd(modes.AUTO_LAND),
                CMD["NAV_RETURN_TO_LAUNCH"]: self._mode_cmd(modes.AUTO_RTL),
                CMD["MISSION_START"]: self._mode_cmd(modes.AUTO_MISSION),
                CMD["DO_REPOSITION"]: self._cmd_reposition,
                CMD["DO_SET_HOME"]: self._cmd_set_home,
                CMD["DO_FLIGHTTERMINATION"]: self._cmd_terminate,
                CMD["PREFLIGHT_REBOOT_SHUTDOWN"]: self._cmd_reboot,
                CMD["PREFLIGHT_CALIBRATION"]: self._cmd_calibration,
                CMD["PREFLIGHT_STORAGE"]: self._cmd_storage,
                CMD["RUN_PREARM_CHECKS"]: self._cmd_prearm_checks,
                CMD["DO_MOTOR_TEST"]: self._cmd_motor_test,
                CMD["ACTUATOR_TEST"]: self._cmd_actuator_test}

    # -- motor and actuator test (QGroundControl's Motors page) -------------------------------

    def _motor_test_refused(self) -> str:
        """Why a motor test may not run now ('' if it may): PX4's commander denies it when
        armed, while the safety switch is on, or with COM_MOT_TEST_EN not 1."""
        from firmware.modules.commander.params import CBRK_IO_SAFETY_KEY
        if self.arming_state == 2:  # ARMED
            return "motor test: not while armed"
        io = self.data.io.node.last  # type: ignore[attr-defined]
        if io is not None and not io.status_safety_off and \
                self.p["CBRK_IO_SAFETY"] != CBRK_IO_SAFETY_KEY:
            return "motor test: safety switch not off"
        if self.p["COM_MOT_TEST_EN"] != 1:
            return "motor test: disabled (COM_MOT_TEST_EN)"
        return ""

    def _publish_test_motor(self, motor: int, value: float, timeout_s: float) -> None:
        """``test_motor`` for the output driver (px4io); timeout in whole ms, at least 1."""
        timeout_ms = max(1, round(timeout_s * 1000)) if math.isfinite(timeout_s) else 1
        msg = self.platform.orb.new("test_motor")  # type: ignore[attr-defined]
        msg.timestamp = self.platform.time_us()  # type: ignore[attr-defined]
        msg.action = 0 if value != value else 1  # NaN: stop
        msg.motor_number = motor
        msg.value = 0.0 if value != value else min(1.0, max(0.0, value))
        msg.timeout_ms = min(timeout_ms, 3000)
        pub = getattr(self, "_pub_test_motor", None)
        if pub is None:
            pub = self._pub_test_motor = self.advertise("test_motor")  # type: ignore
        pub.publish(msg)

    def _cmd_motor_test(self, cmd: Any) -> int:
        """MAV_CMD_DO_MOTOR_TEST (209) as PX4's commander: param1 the motor (1-based), param2
        the throttle type (only MOTOR_TEST_THROTTLE_PERCENT, 0, else UNSUPPORTED), param3 the
        throttle in %, param4 the timeout in s (MAVLink's at most 3 s). DENIED when armed or
        with the safety on."""
        why = self._motor_test_refused()
        if why:
            self.last_reason = why
            self.warn(why)  # type: ignore[attr-defined]
            return DENIED
        motor = _param_int(cmd.param1, 0) - 1
        if _param_int(cmd.param2, -1) != 0:
            self.last_reason = "motor test: only a throttle in percent is supported"
            return UNSUPPORTED
        if not 0 <= motor < 8 or not math.isfinite(cmd.param3):
            self.last_reason = f"motor test: no motor {cmd.param1} or no throttle {cmd.param3}"
            return DENIED
        self._publish_test_motor(motor, float(cmd.param3) / 100.0, float(cmd.param4))
        return ACCEPTED

    def _cmd_actuator_test(self, cmd: Any) -> int:
        """MAV_CMD_ACTUATOR_TEST (310): param1 the value -1..1 (NaN: off), param2 the timeout
        in s (0..3), param5 the output function; motors (MOTOR1.., 101..) only, a motor's value
        taken as 0..1 of its range (below 0: its minimum). DENIED as DO_MOTOR_TEST."""
        why = self._motor_test_refused()
        if why:
            self.last_reason = why
            self.warn(why)  # type: ignore[attr-defined]
            return DENIED
        function = _param_int(cmd.param5, 0)
        if not 101 <= function <= 108:
            self.last_reason = f"actuator test: output function {cmd.param5} not on this vehicle"
            return UNSUPPORTED
        value = float(cmd.param1)
        if value in (float("inf"), float("-inf")):
            self.last_reason = "actuator test: value out of range"
            return DENIED
        self._publish_test_motor(function - 101, value, float(cmd.param2))
        return ACCEPTED

    def _cmd_prearm_checks(self, cmd: Any) -> int:
        """MAV_CMD_RUN_PREARM_CHECKS (401), QGroundControl's "run checks". PX4's commander
        runs its health and arming checks with forced reporting and answers ACCEPTED; the
        result is reported as it is for every check run: each failing check's STATUSTEXT
        ("Preflight Fail: ...", sent again even if reported before) and the SYS_STATUS and
        vehicle_status bits. MAVLink's definition: TEMPORARILY_REJECTED when armed."""
        if self.arming_state == 2:  # ARMED
            self.last_reason = "pre-arm checks: vehicle armed"
            return TEMPORARILY_REJECTED
        self._reported = set()  # forced reporting: every failure again
        self.run_checks(self.platform.time_us())  # type: ignore[attr-defined]
        return ACCEPTED

    def _cmd_arm(self, cmd: Any) -> int:
        from firmware.modules.commander.commander import R_CMD_EXTERNAL, R_CMD_INTERNAL
        force = _param_int(cmd.param2) == FORCE_ARM_MAGIC
        reason = R_CMD_EXTERNAL if cmd.from_external else R_CMD_INTERNAL
        if cmd.param1 == 1.0:
            ok, why = self.arm(reason, force)  # type: ignore[attr-defined]
        elif cmd.param1 == 0.0:
            ok, why = self.disarm(reason, force)  # type: ignore[attr-defined]
        else:
            self.last_reason = f"arm/disarm: param1 {cmd.param1} is neither 0 nor 1"
            return DENIED
        self.last_reason = why
        return ACCEPTED if ok else TEMPORARILY_REJECTED

    def _set_mode(self, nav: int, why: str) -> int:
        ok, text = self.set_user_mode(nav, why)  # type: ignore[attr-defined]
        self.last_reason = text
        return ACCEPTED if ok else TEMPORARILY_REJECTED

    def _mode_cmd(self, nav: int) -> Callable[[Any], int]:
        return lambda cmd: self._set_mode(nav, "command")

    def _cmd_mode(self, cmd: Any) -> int:
        base = _param_int(cmd.param1)
        if base & _MAV_MODE_FLAG_CUSTOM:
            nav = modes.custom_to_nav(_param_int(cmd.param2), _param_int(cmd.param3))
        elif base & _FLAG_AUTO:
            nav = modes.AUTO_MISSION
        elif base & _FLAG_MANUAL:
            nav = (modes.POSCTL if base & _FLAG_GUIDED else
                   modes.STAB if base & _FLAG_STABILIZE else modes.MANUAL)
        else:
            nav = None
        if nav is None:
            self.last_reason = (f"mode base {base} main {cmd.param2:g} sub {cmd.param3:g} "
                                "unknown")
            return UNSUPPORTED
        return self._set_mode(nav, "command")

    def _cmd_reposition(self, cmd: Any) -> int:
        if _param_int(cmd.param2) & 1 or self.user_nav == modes.AUTO_LOITER:
            return self._set_mode(modes.AUTO_LOITER, "reposition")
        self.last_reason = "reposition only in Hold mode"
        return TEMPORARILY_REJECTED

    def _cmd_set_home(self, cmd: Any) -> int:
        now = self.platform.time_us()  # type: ignore[attr-defined]
        if cmd.param1 == 1.0:
            ok = self.set_home(now)  # type: ignore[attr-defined]
        elif math.isfinite(cmd.param5) and math.isfinite(cmd.param6):
            ok = self.set_home(now, False, cmd.param5, cmd.param6,  # type: ignore[attr-defined]
                               cmd.param7 if math.isfinite(cmd.param7) else 0.0)
        else:
            ok = False
        self.last_reason = "" if ok else "no position for home"
        return ACCEPTED if ok else TEMPORARILY_REJECTED

    def _cmd_terminate(self, cmd: Any) -> int:
        if cmd.param1 > 0.5:
            self.terminated = True
            self.error("Flight termination active")  # type: ignore[attr-defined]
        return ACCEPTED

    def _cmd_reboot(self, cmd: Any) -> int:
        if _param_int(cmd.param1) not in (1, 3):
            return UNSUPPORTED
        if self.arming_state == 2:
            self.last_reason = "reboot refused while armed"
            return DENIED
        ok = self.system.reboot(_param_int(cmd.param1) == 3)  # type: ignore[attr-defined]
        return ACCEPTED if ok else FAILED

    def _cmd_calibration(self, cmd: Any) -> int:
        """MAV_CMD_PREFLIGHT_CALIBRATION: PX4's commander refuses it while armed
        (TEMPORARILY_REJECTED); otherwise the calibration package starts the routine (gyro,
        six-sided accelerometer, level horizon) on a work item of its own and answers ACCEPTED
        at once, reporting progress and result by STATUSTEXT; params 1-6 all 0 cancel a
        running one (or, with none running, are ACCEPTED: the end of an RC calibration); a
        calibration without a routine is UNSUPPORTED (see calibration/runner.py)."""
        if self.arming_state == 2:
            self.last_reason = "Calibration denied: system armed"
            self.warn(self.last_reason)  # type: ignore[attr-defined]
            return TEMPORARILY_REJECTED
        from firmware.modules.commander.calibration import request
        result, self.last_reason = request(self, cmd)
        return result

    def _cmd_storage(self, cmd: Any) -> int:
        """MAV_CMD_PREFLIGHT_STORAGE through the parameter store (PX4's commander): refused
        while armed (TEMPORARILY_REJECTED); param1 0 loads the parameters from FRAM, 1 saves
        them, 2 resets all but the calibration (``CAL_*``) to defaults, 3 resets only the
        calibration, 4 resets everything (MAVLink's PARAM_RESET_CONFIG/SENSOR/ALL_DEFAULT; the
        resets are saved by the store's autosave). A load or save that fails is FAILED;
        another action UNSUPPORTED."""
        if self.arming_state == 2:
            self.last_reason = "parameter storage refused while armed"
            return TEMPORARILY_REJECTED
        params = self.system.params  # type: ignore[attr-defined]
        action = _param_int(cmd.param1, -1)
        if params is None or (action in (0, 1) and params.storage is None):
            self.last_reason = "no parameter storage"
            return FAILED
        if action == 0:
            ok = bool(params.load())
            (self.info if ok else self.error)(  # type: ignore[attr-defined]
                "Settings loaded" if ok else "Error loading settings")
        elif action == 1:
            ok = bool(params.save())
            (self.info if ok else self.error)(  # type: ignore[attr-defined]
                "Settings saved" if ok else "Error saving settings")
        elif action in (2, 4):
            params.reset_all(exclude=("CAL_*",) if action == 2 else ())
            ok = True
        elif action == 3:
            for name in params.match("CAL_*"):
                params.reset(name)
            ok = True
        else:
            self.last_reason = f"storage action {cmd.param1} unknown"
            return UNSUPPORTED
        return ACCEPTED if ok else FAILED

    # -- RC ---------------------------------------------------------------------------------

    def _slot_nav(self, slot: int) -> int | None:
        if not 1 <= slot <= 6:
            return None
        return modes.FLTMODE_TO_NAV.get(int(self.p[f"COM_FLTMODE{slot}"]))

    def _handle_switches(self, sw: Any) -> None:
        """Act on switch *changes* (PX4: a switch already ON at boot does not arm)."""
        from firmware.modules.commander.commander import R_RC_SWITCH
        last: dict[str, int] = self._sw_last  # type: ignore[attr-defined]
        prev = dict(last)
        for name in ("mode_slot", "arm_switch", "return_switch", "loiter_switch",
                     "kill_switch"):
            last[name] = int(getattr(sw, name))
        if sw.kill_switch != SWITCH_NONE:
            engaged = sw.kill_switch == SWITCH_ON
            if engaged != self.kill_engaged:  # type: ignore[has-type]
                self.kill_engaged = engaged
                (self.warn if engaged else self.info)(  # type: ignore[attr-defined]
                    "Kill-switch engaged" if engaged else "Kill-switch disengaged")
        a, a0 = sw.arm_switch, prev.get("arm_switch")
        if a != SWITCH_NONE and a0 is not None and a != a0:
            if a == SWITCH_ON:
                self.arm(R_RC_SWITCH)  # type: ignore[attr-defined]
            elif a == SWITCH_OFF:
                self.disarm(R_RC_SWITCH)  # type: ignore[attr-defined]
        override = False
        for name, nav in (("return_switch", modes.AUTO_RTL), ("loiter_switch",
                                                               modes.AUTO_LOITER)):
            v, v0 = getattr(sw, name), prev.get(name)
            if v == SWITCH_ON:
                override = True
                if v0 != SWITCH_ON:
                    self._set_mode(nav, name.replace("_", " "))
            elif v == SWITCH_OFF and v0 == SWITCH_ON:
                slot_nav = self._slot_nav(sw.mode_slot)
                if slot_nav is not None:
                    self._set_mode(slot_nav, f"mode slot {sw.mode_slot}")
        slot = sw.mode_slot
        if not override and slot != prev.get("mode_slot"):
            slot_nav = self._slot_nav(slot)
            if slot_nav is not None:
                self._set_mode(slot_nav, f"mode slot {slot}")

    def _handle_gestures(self, now: int) -> None:
        """Throttle low + yaw right held COM_RC_ARM_HYST arms; yaw left disarms (landed)."""
        from firmware.modules.commander.commander import ARMED, R_RC_STICK
        m = self.data.manual.node.last  # type: ignore[attr-defined]
        usable = (self.rc_ok and m is not None and self.p["MAN_ARM_GESTURE"]  # type: ignore
                  and self._sw_last.get("arm_switch", SWITCH_NONE) == SWITCH_NONE)  # type: ignore
        gesture = None
        if usable and m.throttle < -_GESTURE_STICK:
            armed = self.arming_state == ARMED
            if m.yaw > _GESTURE_STICK and not armed:
                gesture = "arm"
            elif m.yaw < -_GESTURE_STICK and armed:
                gesture = "disarm"
        if gesture is None:
            self._gesture_since, self._gesture_done = None, False
            return
        if self._gesture_done:
            return
        if self._gesture_since is None:
            self._gesture_since = now
        if now - self._gesture_since < int(self.p["COM_RC_ARM_HYST"]) * 1000:
            return
        self._gesture_done = True
        if gesture == "arm":
            if self.user_nav not in _MANUAL_NAV:
                self.warn("Stick arming only in manual modes")  # type: ignore[attr-defined]
                return
            self.arm(R_RC_STICK)  # type: ignore[attr-defined]
        else:
            self.disarm(R_RC_STICK)  # type: ignore[attr-defined]

    # -- shell ------------------------------------------------------------------------------

    def _command(self, command: int, **params: float) -> Any:
        cmd = self._cmd_cls()  # type: ignore[attr-defined]
        cmd.timestamp = self.platform.time_us()  # type: ignore[attr-defined]
        cmd.command = command
        cmd.param5 = cmd.param6 = math.nan
        cmd.param7 = math.nan
        for k, v in params.items():
            setattr(cmd, k, v)
        cmd.target_system = self.sys_id  # type: ignore[attr-defined]
        cmd.source_system = self.sys_id  # type: ignore[attr-defined]
        return cmd

    def _run_shell(self, what: str, command: int, **params: float) -> int:
        result = self.handle_command(self._command(command, **params))
        text = f"{what}: {RESULT.get(result, result)}" if result is not None else what
        if self.last_reason and result != ACCEPTED:
            text += f" ({self.last_reason})"
        self.print(text)  # type: ignore[attr-defined]
        return 0 if result == ACCEPTED else 1

    def _shell_transition(self) -> int:
        """PX4's ``commander transition``: a VTOL is asked (vehicle_command
        DO_VTOL_TRANSITION, which vtol_att_control answers) to fly the other way than it
        flies now."""
        st: Any = getattr(self, "_status", None)
        if st is None or not st.is_vtol:
            self.print("transition: not a VTOL")  # type: ignore[attr-defined]
            return 1
        to_fw = st.vehicle_type != st.VEHICLE_TYPE_FIXED_WING
        pub = getattr(self, "_pub_transition", None)
        if pub is None:
            pub = self._pub_transition = self.advertise("vehicle_command")  # type: ignore
        pub.publish(self._command(3000, param1=4.0 if to_fw else 3.0))
        self.print(f"transition to {'fixed wing' if to_fw else 'multicopter'} "  # type: ignore
                   "requested")
        return 0

    def custom_command(self, args: list[str]) -> int:
        verb, rest = args[0], args[1:]
        force = float(FORCE_ARM_MAGIC) if "-f" in rest else 0.0
        arm = CMD["COMPONENT_ARM_DISARM"]
        if verb == "arm":
            return self._run_shell("arm", arm, param1=1.0, param2=force)
        if verb == "disarm":
            return self._run_shell("disarm", arm, param1=0.0, param2=force)
        if verb == "takeoff":
            rc = self._run_shell("takeoff", CMD["NAV_TAKEOFF"])
            return rc or self._run_shell("arm", arm, param1=1.0)
        if verb == "land":
            return self._run_shell("land", CMD["NAV_LAND"])
        if verb == "transition":
            return self._shell_transition()
        if verb == "mode":
            if not rest or rest[0] not in modes.MODE_NAMES:
                raise UsageError(f"mode: one of {', '.join(modes.MODE_NAMES)}")
            nav = modes.MODE_NAMES[rest[0]]
            main, sub = modes.nav_to_custom(nav)
            return self._run_shell(f"mode {rest[0]}", CMD["DO_SET_MODE"], param1=1.0,
                                   param2=float(main), param3=float(sub))
        if verb == "check":
            failures = self.run_checks(self.platform.time_us())  # type: ignore[attr-defined]
            for f in failures:
                self.print(f.text)  # type: ignore[attr-defined]
            self.print("Preflight check: " + ("OK" if not failures else "FAILED"))  # type: ignore
            return 0 if not failures else 1
        return super().custom_command(args)  # type: ignore[misc]
