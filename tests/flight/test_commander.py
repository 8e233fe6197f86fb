"""commander: arming and its preflight checks, auto-disarm, modes by command and RC switch,
failsafes (RC loss, data-link loss, low battery, position loss), shell commands.

The vehicle is a :class:`Rig`: the input topics published by hand at 20 Hz in virtual time,
healthy by default (sensors, estimator, 3D fix, position, RC, safety off, full battery, landed);
a test breaks one thing and watches the commander's outputs.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

from board.kernel import Kernel
from firmware.modules.battery import BatteryStatusModule
from firmware.modules.commander import CommanderModule
from firmware.modules.commander.commands import CMD
from firmware.modules.dataman import DatamanModule
from firmware.modules.mavlink.module import MavlinkModule
from firmware.modules.navigator import NavigatorModule
from firmware.modules.rc_update import RcUpdateModule
from firmware.modules.system_params import PARAMS as SYS_PARAMS
from firmware.platform import Platform
from firmware.platform.params import Params
from firmware.system import System

ACCEPTED, TEMPORARILY_REJECTED, DENIED, UNSUPPORTED = 0, 1, 2, 3
STANDBY, ARMED, STANDBY_ERROR = 1, 2, 3
MANUAL, ALTCTL, POSCTL, MISSION, LOITER, RTL, DESCEND = 0, 1, 2, 3, 4, 5, 12
STAB, TAKEOFF, LAND = 15, 17, 18
HOME = (47.397742, 8.545594, 488.0)

#: the mavlink module's MAV_TYPE, which the commander reads (the airframe sets it)
MAV_TYPE_DEF = next(d for d in MavlinkModule.PARAMS if d.name == "MAV_TYPE")
MODULES = {"commander": CommanderModule, "navigator": NavigatorModule,
           "dataman": DatamanModule, "rc_update": RcUpdateModule,
           "battery_status": BatteryStatusModule}


def _sensor(dev: int) -> dict[str, Any]:
    return {"device_id_primary": dev, "device_ids": [dev, 0, 0, 0],
            "healthy": [True, False, False, False], "enabled": [True, False, False, False],
            "inconsistency": [0.0] * 4}


def healthy_inputs() -> dict[str, dict[str, Any]]:
    return {
        "sensors_status_imu": _sensor(1), "sensors_status_imu#1": _sensor(1),
        "sensors_status_baro": _sensor(2),
        "sensors_status_mag": _sensor(3),
        "estimator_status": {},
        "vehicle_local_position": {"xy_valid": True, "z_valid": True, "v_xy_valid": True,
                                   "v_z_valid": True, "eph": 0.5, "epv": 0.5,
                                   "xy_global": True, "z_global": True},
        "vehicle_global_position": {"lat": HOME[0], "lon": HOME[1], "alt": HOME[2],
                                    "eph": 0.5, "epv": 0.5},
        "sensor_gps": {"fix_type": 3, "eph": 0.8},
        "vehicle_land_detected": {"landed": True},
        "px4io_status": {"status_safety_off": True},
        "manual_control_setpoint": {"valid": True, "data_source": 1, "throttle": -1.0},
        "battery_status": {"connected": True, "remaining": 0.9, "voltage_v": 12.0},
    }


class Rig:
    """A System with the given modules and hand-published inputs at 20 Hz."""

    def __init__(self, modules: tuple[str, ...] = ("commander",),
                 params: dict[str, float] | None = None, without: tuple[str, ...] = (),
                 inputs: dict[str, dict[str, Any]] | None = None) -> None:
        self.kernel = Kernel("fmu")
        self.platform = Platform(self.kernel)
        self.orb = self.platform.orb
        defs = list(SYS_PARAMS) + [MAV_TYPE_DEF]
        for cls in MODULES.values():
            defs += cls.PARAMS
        self.params = Params(self.platform, defs)
        for k, v in (params or {}).items():
            self.params.set(k, v)
        self.out: list[str] = []
        self.system = System(self.platform, self.params, modules=MODULES,
                             console=self.out.append)
        self.msgs: dict[str, Any] = {}
        self.pubs: dict[str, Any] = {}
        self.stopped: set[str] = set(without)
        for topic, fields in (inputs if inputs is not None else healthy_inputs()).items():
            self.set(topic, **fields)
        self._acks = None
        self.platform.hrt.call_every(50_000, 50_000, self._tick)
        self._tick()
        for name in modules:
            assert self.system.modules.start(name) == 0, self.out
        self._acks = self.sub("vehicle_command_ack")
        self._cmd_pub = self.orb.advertise("vehicle_command")

    def sub(self, topic: str) -> Any:
        from firmware.platform.uorb import Subscription
        return Subscription(self.orb, topic)

    def set(self, topic: str, **fields: Any) -> None:
        """Change fields of a published input (and resume publishing it)."""
        msg = self.msgs.get(topic)
        if msg is None:  # "topic#n": instance n
            name, _, inst = topic.partition("#")
            msg = self.msgs[topic] = self.orb.new(name)
            self.pubs[topic] = self.orb.advertise(name, int(inst or 0))
        for k, v in fields.items():
            setattr(msg, k, list(v) if isinstance(v, list) else v)
        self.stopped.discard(topic)

    def stop(self, topic: str) -> None:
        self.stopped.add(topic)

    def _tick(self) -> None:
        now = self.platform.time_us()
        for topic, msg in self.msgs.items():
            if topic not in self.stopped:
                msg.timestamp = now
                self.pubs[topic].publish(msg)

    def run(self, seconds: float) -> None:
        self.kernel.run(self.kernel.now_ns + int(seconds * 1e9))

    def last(self, topic: str) -> Any:
        return self.orb.node(topic).last

    @property
    def status(self) -> Any:
        return self.last("vehicle_status")

    def command(self, name: str, run_s: float = 0.05, **params: float) -> int:
        """Publish a vehicle_command, let the commander run, return its ack result."""
        fields = {"param5": math.nan, "param6": math.nan, "param7": math.nan, **params}
        cmd = self.orb.new("vehicle_command", command=CMD[name], from_external=True,
                           source_system=255, **fields)
        self._acks.copy()
        self._cmd_pub.publish(cmd)
        self.run(run_s)
        ack = self._acks.update()
        assert ack is not None and ack.command == CMD[name], "no ack"
        return ack.result

    def arm(self, force: bool = False) -> int:
        return self.command("COMPONENT_ARM_DISARM", param1=1.0,
                            param2=21196.0 if force else 0.0)

    def set_mode(self, main: int, sub: int = 0) -> int:
        return self.command("DO_SET_MODE", param1=1.0, param2=float(main), param3=float(sub))

    def dmesg(self) -> str:
        return "\n".join(text for _, _, _, text in self.platform.dmesg)

    def take_off(self, alt_m: float = 10.0) -> None:
        """Pretend the vehicle is flying ``alt_m`` above home."""
        self.set("vehicle_land_detected", landed=False)
        self.set("vehicle_global_position", alt=HOME[2] + alt_m)
        self.set("vehicle_local_position", z=-alt_m)


@pytest.fixture
def rig() -> Rig:
    r = Rig()
    r.run(0.3)
    return r


# -- arming -------------------------------------------------------------------------------------

def test_boots_to_standby_and_arms_when_every_check_passes(rig: Rig) -> None:
    st = rig.status
    assert st.arming_state == STANDBY and st.pre_flight_checks_pass
    assert st.system_type == 2 and st.vehicle_type == st.VEHICLE_TYPE_ROTARY_WING
    assert rig.last("actuator_armed").ready_to_arm
    assert rig.arm() == ACCEPTED
    st = rig.status
    assert st.arming_state == ARMED and st.armed_time > 0 and st.latest_arming_reason == 4
    assert rig.last("actuator_armed").armed and rig.last("vehicle_control_mode").flag_armed
    home = rig.last("home_position")
    assert home.valid_hpos and home.lat == pytest.approx(HOME[0]) and home.alt == HOME[2]


def _break(rig: Rig, what: str) -> None:
    if what == "imu_missing":
        rig.orb.node("sensors_status_imu").last = None
        rig.stop("sensors_status_imu")
    elif what == "accel_inconsistent":  # instance 1 of sensors_status_imu: the accels
        rig.set("sensors_status_imu#1", device_ids=[1, 5, 0, 0],
                enabled=[True, True, False, False], inconsistency=[0.1, 1.5, 0.0, 0.0])
    elif what == "gyro_inconsistent":  # instance 0: the gyros, against COM_ARM_IMU_GYR
        rig.set("sensors_status_imu", device_ids=[1, 5, 0, 0],
                enabled=[True, True, False, False], inconsistency=[0.01, 0.3, 0.0, 0.0])
    elif what == "baro_unhealthy":
        rig.set("sensors_status_baro", healthy=[False, False, False, False])
    elif what == "estimator_fault":
        rig.set("estimator_status", filter_fault_flags=4)
    elif what == "no_gps":
        rig.params.set("COM_ARM_WO_GPS", 0)
        rig.set("sensor_gps", fix_type=0)
    elif what == "gps_2d":
        rig.params.set("COM_ARM_WO_GPS", 0)
        rig.set("sensor_gps", fix_type=2)
    elif what == "no_local_position":
        assert rig.set_mode(3) == ACCEPTED  # position mode
        rig.set("vehicle_local_position", xy_valid=False)
    elif what == "no_rc":
        rig.params.set("COM_RC_IN_MODE", 0)
        rig.stop("manual_control_setpoint")
    elif what == "safety_on":
        rig.set("px4io_status", status_safety_off=False)
    elif what == "low_battery":
        rig.set("battery_status", warning=1, remaining=0.12)


@pytest.mark.parametrize("what, reason", [
    ("imu_missing", "Accel/Gyro Sensor missing"),
    ("accel_inconsistent", "Accels inconsistent"),
    ("gyro_inconsistent", "Gyros inconsistent"),
    ("baro_unhealthy", "Baro Sensor 0 unhealthy"),
    ("estimator_fault", "estimator numerical fault"),
    ("no_gps", "no GPS"),
    ("gps_2d", "GPS fix too low"),
    ("no_local_position", "Position mode requires local position"),
    ("no_rc", "No manual control input"),
    ("safety_on", "safety switch engaged"),
    ("low_battery", "low battery"),
])
def test_arming_refused_with_the_failing_check_reported(rig: Rig, what: str,
                                                        reason: str) -> None:
    _break(rig, what)
    rig.run(1.0)
    assert not rig.status.pre_flight_checks_pass
    # The safety switch is checked at arming only: the IO takes the button press only while
    # the FMU reports ready to arm (IO_ARM_OK).
    assert rig.last("actuator_armed").ready_to_arm == (what == "safety_on")
    assert rig.arm() == TEMPORARILY_REJECTED
    assert rig.status.arming_state != ARMED
    errors = [t for _, sev, mod, t in rig.platform.dmesg if sev == 3 and mod == "commander"]
    assert any(t.startswith("Preflight Fail:") and reason in t for t in errors), errors
    log = rig.last("log_message")
    assert log.text.startswith("[commander] Preflight Fail:")


def test_hard_failures_give_standby_error_until_fixed(rig: Rig) -> None:
    rig.set("estimator_status", filter_fault_flags=1)
    rig.run(0.5)
    assert rig.status.arming_state == STANDBY_ERROR
    rig.set("estimator_status", filter_fault_flags=0)
    rig.run(0.5)
    assert rig.status.arming_state == STANDBY


def test_force_arm_skips_the_checks_and_circuit_breaker_skips_safety(rig: Rig) -> None:
    rig.set("px4io_status", status_safety_off=False)
    rig.run(0.2)
    assert rig.arm(force=True) == ACCEPTED
    assert rig.command("COMPONENT_ARM_DISARM", param1=0.0) == ACCEPTED
    rig.params.set("CBRK_IO_SAFETY", 22027)
    rig.run(0.2)
    assert rig.arm() == ACCEPTED


# -- auto-disarm ---------------------------------------------------------------------------------

def test_auto_disarm_after_landing_and_before_takeoff() -> None:
    rig = Rig(params={"COM_DISARM_LAND": 2.0, "COM_DISARM_PRFLT": 3.0})
    rig.run(0.3)
    assert rig.arm() == ACCEPTED
    rig.run(2.5)
    assert rig.status.arming_state == ARMED
    rig.run(1.0)   # 3 s without taking off
    assert rig.status.arming_state == STANDBY and rig.status.latest_disarming_reason == 8
    assert rig.arm() == ACCEPTED
    rig.take_off()
    rig.run(5.0)
    assert rig.status.arming_state == ARMED and rig.status.takeoff_time > 0
    rig.set("vehicle_land_detected", landed=True)
    rig.run(1.5)
    assert rig.status.arming_state == ARMED
    rig.run(1.0)
    assert rig.status.arming_state == STANDBY and rig.status.latest_disarming_reason == 7


@pytest.mark.parametrize("mode", [(4, 6), (4, 5), (4, 4)])  # Land, Return, Mission
def test_disarmed_in_an_auto_mode_returns_to_hold_and_arms_again(mode: tuple[int, int]
                                                                 ) -> None:
    """Issue 21, a second flight: PX4's commander switches back to Hold after an autonomous
    landing, so the vehicle can be armed again (Land and Return refuse arming)."""
    rig = Rig(params={"COM_DISARM_LAND": 1.0})
    rig.run(0.3)
    if mode == (4, 4):
        rig.set("mission", count=3)
    assert rig.arm() == ACCEPTED
    rig.take_off()
    rig.run(0.5)
    assert rig.set_mode(*mode) == ACCEPTED
    rig.set("vehicle_land_detected", landed=True)
    rig.run(1.5)
    st = rig.status
    assert st.arming_state == STANDBY and st.latest_disarming_reason == 7
    assert st.nav_state == LOITER and st.nav_state_user_intention == LOITER
    assert rig.arm() == ACCEPTED
    assert rig.command("NAV_TAKEOFF") == ACCEPTED and rig.status.nav_state == TAKEOFF


def test_disarmed_in_a_manual_mode_stays_in_it(rig: Rig) -> None:
    assert rig.set_mode(3) == ACCEPTED and rig.arm() == ACCEPTED
    assert rig.command("COMPONENT_ARM_DISARM", param1=0.0) == ACCEPTED
    assert rig.status.arming_state == STANDBY and rig.status.nav_state == POSCTL


def test_disarm_in_the_air_needs_force(rig: Rig) -> None:
    assert rig.arm() == ACCEPTED
    rig.take_off()
    rig.run(0.2)
    assert rig.command("COMPONENT_ARM_DISARM", param1=0.0) == TEMPORARILY_REJECTED
    assert rig.command("COMPONENT_ARM_DISARM", param1=0.0, param2=21196.0) == ACCEPTED
    assert rig.status.arming_state == STANDBY


# -- modes ---------------------------------------------------------------------------------------

def test_mode_changes_by_command_are_acked(rig: Rig) -> None:
    assert rig.set_mode(3) == ACCEPTED and rig.status.nav_state == POSCTL
    flags = rig.last("vehicle_control_mode")
    assert flags.flag_control_position_enabled and flags.flag_control_manual_enabled
    assert rig.set_mode(7) == ACCEPTED and rig.status.nav_state == STAB
    assert rig.set_mode(4, 4) == TEMPORARILY_REJECTED       # mission, but none uploaded
    assert rig.set_mode(9) == UNSUPPORTED
    assert rig.command("NAV_TAKEOFF") == ACCEPTED and rig.status.nav_state == TAKEOFF
    assert rig.last("vehicle_control_mode").flag_control_auto_enabled
    assert rig.command("NAV_LAND") == ACCEPTED and rig.status.nav_state == LAND
    assert rig.command("NAV_RETURN_TO_LAUNCH") == ACCEPTED and rig.status.nav_state == RTL
    assert rig.arm() == TEMPORARILY_REJECTED                 # not from Return
    assert "arming not possible in Return mode" in rig.dmesg()
    ack_all = rig.command("DO_FLIGHTTERMINATION", param1=0.0)
    assert ack_all == ACCEPTED


def test_armed_mode_change_needs_what_the_mode_needs(rig: Rig) -> None:
    assert rig.set_mode(2) == ACCEPTED  # altitude
    assert rig.arm() == ACCEPTED
    rig.set("vehicle_local_position", xy_valid=False)
    rig.run(0.2)
    assert rig.set_mode(3) == TEMPORARILY_REJECTED
    assert rig.status.nav_state == ALTCTL
    assert "Switching to Position is currently not possible" in rig.dmesg()


def test_rc_mode_switch_and_return_switch() -> None:
    rig = Rig(params={"COM_FLTMODE1": 8, "COM_FLTMODE4": 2, "COM_FLTMODE6": 1})
    sw = {"mode_slot": 1, "return_switch": 3, "kill_switch": 3, "arm_switch": 0}
    rig.set("manual_control_switches", **sw)
    rig.run(0.3)
    assert rig.status.nav_state == STAB
    rig.set("manual_control_switches", mode_slot=4)
    rig.run(0.2)
    assert rig.status.nav_state == POSCTL
    rig.set("manual_control_switches", return_switch=1)
    rig.run(0.2)
    assert rig.status.nav_state == RTL
    rig.set("manual_control_switches", return_switch=3)
    rig.run(0.2)
    assert rig.status.nav_state == POSCTL
    rig.set("manual_control_switches", kill_switch=1)
    rig.run(0.2)
    assert rig.last("actuator_armed").manual_lockdown
    assert rig.arm() == TEMPORARILY_REJECTED
    rig.set("manual_control_switches", kill_switch=3)
    rig.run(0.2)
    assert not rig.last("actuator_armed").manual_lockdown


def test_arm_and_disarm_by_stick_gesture(rig: Rig) -> None:
    rig.set("manual_control_setpoint", throttle=-1.0, yaw=1.0)
    rig.run(0.5)
    assert rig.status.arming_state == STANDBY
    rig.run(0.7)
    assert rig.status.arming_state == ARMED and rig.status.latest_arming_reason == 1
    rig.set("manual_control_setpoint", yaw=-1.0)
    rig.run(1.2)
    assert rig.status.arming_state == STANDBY


# -- failsafes -----------------------------------------------------------------------------------

def _fly_in(rig: Rig, mode: tuple[int, int]) -> None:
    assert rig.set_mode(*mode) == ACCEPTED
    assert rig.arm() == ACCEPTED
    rig.take_off()
    rig.run(0.5)


def test_rc_loss_triggers_nav_rcl_act_after_the_hold_delay() -> None:
    rig = Rig(params={"NAV_RCL_ACT": 2, "COM_FAIL_ACT_T": 1.0, "COM_RC_LOSS_T": 0.5})
    rig.run(0.3)
    _fly_in(rig, (3, 0))
    rig.stop("manual_control_setpoint")
    rig.run(0.35)
    assert not rig.status.rc_signal_lost
    rig.run(0.4)
    st = rig.status
    assert st.rc_signal_lost and st.failsafe and st.nav_state == LOITER   # holding first
    rig.run(1.0)
    st = rig.status
    assert st.nav_state == RTL and st.failsafe_action == st.FAILSAFE_ACTION_RTL
    assert "Failsafe: manual control lost, return" in rig.dmesg()
    rig.set("manual_control_setpoint", valid=True)       # RC back: still returning ...
    rig.run(0.5)
    assert not rig.status.rc_signal_lost and rig.status.nav_state == RTL
    assert rig.set_mode(3) == ACCEPTED                   # ... until the pilot takes over
    rig.run(0.1)
    assert rig.status.nav_state == POSCTL and not rig.status.failsafe


@pytest.mark.parametrize("act, nav", [(1, LOITER), (3, LAND)])
def test_rc_loss_action_follows_nav_rcl_act(act: int, nav: int) -> None:
    rig = Rig(params={"NAV_RCL_ACT": act, "COM_FAIL_ACT_T": 0.0})
    rig.run(0.3)
    _fly_in(rig, (3, 0))
    rig.stop("manual_control_setpoint")
    rig.run(1.0)
    assert rig.status.nav_state == nav and rig.status.failsafe


def test_low_battery_warns_then_returns_then_lands() -> None:
    rig = Rig(params={"COM_LOW_BAT_ACT": 3, "COM_FAIL_ACT_T": 0.0})
    rig.run(0.3)
    _fly_in(rig, (3, 0))
    rig.set("battery_status", warning=1, remaining=0.14)
    rig.run(0.3)
    st = rig.status
    assert st.battery_low and not st.battery_critical and st.nav_state == POSCTL
    assert "Low battery level! Return advised" in rig.dmesg()
    rig.set("battery_status", warning=2, remaining=0.06)
    rig.run(0.3)
    assert rig.status.battery_critical and rig.status.nav_state == RTL
    rig.set("battery_status", warning=3, remaining=0.04)
    rig.run(0.3)
    assert rig.status.nav_state == LAND and rig.status.failsafe


def test_low_battery_warning_only_by_default(rig: Rig) -> None:
    _fly_in(rig, (3, 0))
    rig.set("battery_status", warning=2, remaining=0.06)
    rig.run(0.3)
    assert rig.status.battery_critical and rig.status.nav_state == POSCTL
    assert "Critical battery level!" in rig.dmesg()


def test_data_link_loss_action() -> None:
    rig = Rig(params={"NAV_DLL_ACT": 3, "COM_DL_LOSS_T": 5, "COM_FAIL_ACT_T": 0.0})
    rig.run(0.3)
    _fly_in(rig, (4, 3))   # hold
    link = rig.orb.advertise("telemetry_status")
    hb = rig.orb.new("telemetry_status", heartbeat_type_gcs=True,
                     heartbeat_gcs_timestamp=rig.platform.time_us())
    link.publish(hb)
    rig.run(4.0)
    assert not rig.status.data_link_lost and rig.status.nav_state == LOITER
    rig.run(1.5)
    st = rig.status
    assert st.data_link_lost and st.data_link_lost_counter == 1 and st.nav_state == LAND


def test_position_loss_falls_back_to_altitude_then_descend(rig: Rig) -> None:
    _fly_in(rig, (3, 0))
    rig.set("vehicle_local_position", xy_valid=False)
    rig.run(0.3)
    assert rig.status.nav_state == ALTCTL and rig.status.failsafe
    rig.set("vehicle_local_position", xy_valid=True)
    rig.run(0.3)
    assert rig.status.nav_state == POSCTL and not rig.status.failsafe
    rig.set_mode(4, 3)
    rig.set("vehicle_local_position", xy_valid=False, z_valid=False)
    rig.stop("vehicle_global_position")
    rig.run(1.5)
    assert rig.status.nav_state == DESCEND
    assert rig.last("vehicle_control_mode").flag_control_climb_rate_enabled
    assert not rig.last("vehicle_control_mode").flag_control_position_enabled


# -- shell ---------------------------------------------------------------------------------------

def test_shell_commands(rig: Rig) -> None:
    cmd = rig.system.modules.command
    assert cmd("commander", ["mode", "posctl"]) == 0
    rig.run(0.1)
    assert rig.status.nav_state == POSCTL
    assert cmd("commander", ["arm"]) == 0
    assert rig.system.modules.get("commander").arming_state == ARMED
    assert cmd("commander", ["disarm"]) == 0
    rig.set("px4io_status", status_safety_off=False)
    rig.run(0.2)
    assert cmd("commander", ["arm"]) == 1
    assert any("safety switch" in line for line in rig.out)
    assert cmd("commander", ["check"]) == 1
    assert cmd("commander", ["mode", "bogus"]) == 1
    assert cmd("commander", ["status"]) == 0
    assert any("arming state: STANDBY" in line for line in rig.out)
    rig.set("px4io_status", status_safety_off=True)
    rig.run(0.2)
    assert cmd("commander", ["takeoff"]) == 0
    rig.run(0.1)
    assert rig.status.nav_state == TAKEOFF and rig.status.arming_state == ARMED


def test_takeoff_finished_switches_to_hold() -> None:
    rig = Rig(modules=("dataman", "commander", "navigator"), params={"MIS_TAKEOFF_ALT": 5.0})
    rig.run(0.3)
    assert rig.command("NAV_TAKEOFF") == ACCEPTED and rig.arm() == ACCEPTED
    rig.run(0.2)
    sp = rig.last("position_setpoint_triplet").current
    assert sp.valid and sp.type == sp.SETPOINT_TYPE_TAKEOFF and sp.alt == HOME[2] + 5.0
    rig.take_off(4.9)
    rig.run(0.5)
    assert rig.status.nav_state == LOITER
    assert math.isclose(rig.last("position_setpoint_triplet").current.alt, HOME[2] + 5.0)


# -- failure detector -----------------------------------------------------------------------


def _tilt(rig: Rig, roll_deg: float = 0.0, pitch_deg: float = 0.0) -> None:
    r, p = math.radians(roll_deg) / 2, math.radians(pitch_deg) / 2
    q = [math.cos(r) * math.cos(p), math.sin(r) * math.cos(p), math.cos(r) * math.sin(p),
         -math.sin(r) * math.sin(p)]
    rig.set("vehicle_attitude", q=q)


def _flying(rig: Rig, seconds: float = 5.0) -> None:
    _tilt(rig)
    assert rig.arm() == ACCEPTED
    rig.set("vehicle_land_detected", landed=False)
    rig.run(seconds)


def test_failure_detector_flags_a_roll_held_past_fd_fail_r_for_its_trigger_time(rig: Rig):
    _flying(rig)
    _tilt(rig, roll_deg=70)
    rig.run(0.2)                       # FD_FAIL_R_TTRI 0.3 s: not yet
    assert rig.status.failure_detector_status == 0
    rig.run(0.25)
    assert rig.status.failure_detector_status & 1       # roll
    assert not rig.status.failure_detector_status & 2
    # CBRK_FLIGHTTERM at PX4's default 121212: flags only, the vehicle stays armed and flying
    armed = rig.last("actuator_armed")
    assert armed.armed and not armed.force_failsafe and not armed.lockdown
    assert "Critical failure" not in rig.dmesg()
    _tilt(rig, pitch_deg=-65)
    rig.run(0.5)
    assert rig.status.failure_detector_status == 2     # pitch only now


def test_failure_detector_terminates_the_flight_without_the_circuit_breaker():
    rig = Rig(params={"CBRK_FLIGHTTERM": 0})
    _flying(rig)
    _tilt(rig, roll_deg=100)
    rig.run(0.5)
    armed = rig.last("actuator_armed")
    assert armed.force_failsafe and not armed.lockdown  # the IO's failsafe outputs
    assert "Critical failure detected: terminate flight" in rig.dmesg()
    assert any(sev == 0 for _, sev, mod, _ in rig.platform.dmesg if mod == "commander")


def test_failure_detector_locks_the_motors_down_right_after_takeoff():
    rig = Rig(params={"CBRK_FLIGHTTERM": 0})
    _flying(rig, seconds=1.0)          # within COM_LKDOWN_TKO (3 s) of takeoff
    _tilt(rig, pitch_deg=80)
    rig.run(0.5)
    armed = rig.last("actuator_armed")
    assert armed.lockdown and not armed.force_failsafe
    assert "Critical failure detected: lockdown" in rig.dmesg()


def test_failure_detector_off_with_fd_fail_r_zero_and_on_the_ground():
    rig = Rig(params={"FD_FAIL_R": 0, "CBRK_FLIGHTTERM": 0})
    _flying(rig)
    _tilt(rig, roll_deg=120)
    rig.run(1.0)
    assert rig.status.failure_detector_status == 0
    assert not rig.last("actuator_armed").force_failsafe
    disarmed = Rig(params={"CBRK_FLIGHTTERM": 0})
    _tilt(disarmed, roll_deg=120)      # not armed: nothing is watched
    disarmed.run(1.0)
    assert disarmed.status.failure_detector_status == 0
