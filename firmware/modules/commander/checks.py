"""What the commander knows about the vehicle, and the preflight checks built on it.

:class:`VehicleData` reads the latest message of each input topic straight from its uORB node
(no copies: the commander runs at 100 Hz) and answers the questions the state machine asks:
is the local position valid, is there a 3D fix, is RC present. Ages come from the time a topic
was last published, not from the message's own timestamp, so a publisher with a wrong clock
cannot make stale data look fresh.

:func:`preflight_failures` returns PX4-style reasons ("Preflight Fail: ..."), each tagged hard
(the vehicle is broken: STANDBY_ERROR) or soft (this mode, this environment: try again later).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Final, NamedTuple

from firmware.modules.commander import modes
from firmware.modules.commander.params import CBRK_IO_SAFETY_KEY

if TYPE_CHECKING:
    from firmware.modules.commander.commander import CommanderModule

__all__ = ["Failure", "VehicleData", "preflight_failures"]

POS_TIMEOUT_US: Final = 1_000_000      # an estimate older than this is not valid
GPS_TIMEOUT_US: Final = 1_000_000
TELEMETRY_INSTANCES: Final = 4


class Failure(NamedTuple):
    """One reason not to arm; hard failures put the vehicle in STANDBY_ERROR.

    ``at_arming`` marks a check made only when arming is requested, not part of being ready:
    the safety switch. The IO accepts the button only once the FMU says it is ready to arm
    (IO_ARM_OK), so counting the switch against readiness would lock both out.
    """

    hard: bool
    text: str
    at_arming: bool = False


class VehicleData:
    """Latest inputs of the commander, read from uORB nodes without copying."""

    def __init__(self, module: CommanderModule) -> None:
        sub = module.subscribe
        self.hrt = module.platform.hrt
        self.lpos = sub("vehicle_local_position")
        self.gpos = sub("vehicle_global_position")
        self.gps = sub("sensor_gps")
        self.land = sub("vehicle_land_detected")
        self.estimator = sub("estimator_status")
        self.imu = sub("sensors_status_imu")            # instance 0: the gyros
        self.imu_accel = sub("sensors_status_imu", 1)   # instance 1: the accelerometers
        self.attitude = sub("vehicle_attitude")
        self.baro = sub("sensors_status_baro")
        self.mag = sub("sensors_status_mag")
        self.io = sub("px4io_status")
        self.battery = sub("battery_status")
        self.manual = sub("manual_control_setpoint")
        self.telemetry = [sub("telemetry_status", i) for i in range(TELEMETRY_INSTANCES)]
        self.offboard = sub("offboard_control_mode")
        self.rc_seen = False
        self.gcs_seen = False

    @staticmethod
    def last(sub: Any) -> Any:
        return sub.node.last

    def age_us(self, sub: Any, now_us: int) -> int:
        node = sub.node
        if node.last is None:
            return 1 << 62
        return now_us - node.last_publish_ns // 1000

    # -- estimates --------------------------------------------------------------------------

    def landed(self) -> bool:
        m = self.land.node.last
        return True if m is None else bool(m.landed)

    def alt_valid(self, now: int) -> bool:
        m = self.lpos.node.last
        return m is not None and m.z_valid and self.age_us(self.lpos, now) < POS_TIMEOUT_US

    def lpos_valid(self, now: int, eph_max: float) -> bool:
        m = self.lpos.node.last
        return (m is not None and m.xy_valid and m.v_xy_valid
                and self.age_us(self.lpos, now) < POS_TIMEOUT_US
                and (eph_max < 0 or m.eph <= eph_max))

    def gpos_valid(self, now: int, eph_max: float) -> bool:
        m = self.gpos.node.last
        return (m is not None and self.age_us(self.gpos, now) < POS_TIMEOUT_US
                and (eph_max < 0 or m.eph <= eph_max))

    def gps_fix(self, now: int) -> int:
        m = self.gps.node.last
        if m is None or self.age_us(self.gps, now) >= GPS_TIMEOUT_US:
            return 0
        return int(m.fix_type)

    # -- links ------------------------------------------------------------------------------

    def rc_present(self, now: int, timeout_us: int) -> bool:
        m = self.manual.node.last
        ok = m is not None and m.valid and self.age_us(self.manual, now) <= timeout_us
        if ok:
            self.rc_seen = True
        return ok

    def offboard_ok(self, now: int, timeout_us: int, eph_max: float) -> bool:
        """Is there an offboard signal Offboard mode can fly on (PX4's OffboardChecks)? The
        last offboard_control_mode arrived within ``timeout_us`` (COM_OF_LOSS_T: setpoints
        streamed faster than that) and says something is controlled, and the estimate that
        needs has not gone invalid (position: local position; velocity: local velocity)."""
        m = self.offboard.node.last
        if m is None or self.age_us(self.offboard, now) >= timeout_us:
            return False
        if not (m.position or m.velocity or m.acceleration or m.attitude or m.body_rate):
            return False
        if m.position:
            return self.lpos_valid(now, eph_max)
        if m.velocity:
            lp = self.lpos.node.last
            return (lp is not None and lp.v_xy_valid and lp.v_z_valid
                    and self.age_us(self.lpos, now) < POS_TIMEOUT_US)
        if m.acceleration:
            return self.attitude.node.last is not None
        return True

    def gcs_present(self, now: int, timeout_us: int) -> bool:
        newest = 0
        for sub in self.telemetry:
            m = sub.node.last
            if m is not None and m.heartbeat_gcs_timestamp > newest:
                newest = m.heartbeat_gcs_timestamp
        if newest:
            self.gcs_seen = True
        return newest > 0 and now - newest <= timeout_us


def _worst_inconsistency(m: Any) -> float:
    return max((m.inconsistency[i] for i in range(4) if m.device_ids[i] and m.enabled[i]),
               default=0.0)


def _sensor_failures(data: VehicleData, acc_max: float, gyr_max: float) -> list[Failure]:
    out: list[Failure] = []
    for sub, what in ((data.imu, "Accel/Gyro"), (data.baro, "Baro"), (data.mag, "Compass")):
        m = sub.node.last
        if m is None or m.device_id_primary == 0:
            out.append(Failure(True, f"Preflight Fail: {what} Sensor missing"))
            continue
        for i in range(4):
            if m.device_ids[i] == m.device_id_primary:
                if not m.healthy[i]:
                    out.append(Failure(True, f"Preflight Fail: {what} Sensor {i} unhealthy"))
                break
    # PX4's consistency checks between redundant IMUs: the voter's inconsistency of each
    # unit against the selected one, accels against COM_ARM_IMU_ACC, gyros COM_ARM_IMU_GYR.
    accels = data.imu_accel.node.last
    if accels is not None:
        worst = _worst_inconsistency(accels)
        if worst > acc_max:
            out.append(Failure(True, f"Preflight Fail: Accels inconsistent ({worst:.2f} m/s^2)"
                                     f" - Check Cal"))
    gyros = data.imu.node.last
    if gyros is not None and gyros.device_id_primary:
        worst = _worst_inconsistency(gyros)
        if worst > gyr_max:
            out.append(Failure(True, f"Preflight Fail: Gyros inconsistent ({worst:.2f} rad/s)"
                                     f" - Check Cal"))
    return out


def _estimator_failures(data: VehicleData) -> list[Failure]:
    m = data.estimator.node.last
    if m is None:
        return [Failure(True, "Preflight Fail: estimator not running")]
    out = []
    if m.filter_fault_flags:
        out.append(Failure(True, "Preflight Fail: estimator numerical fault"))
    for flag, text in (("pre_flt_fail_innov_heading", "heading estimate not stable"),
                       ("pre_flt_fail_innov_vel_horiz", "horizontal velocity unstable"),
                       ("pre_flt_fail_innov_vel_vert", "vertical velocity unstable"),
                       ("pre_flt_fail_innov_height", "height estimate not stable"),
                       ("pre_flt_fail_mag_field_disturbed", "strong magnetic interference")):
        if getattr(m, flag):
            out.append(Failure(False, f"Preflight Fail: {text}"))
    return out


def preflight_failures(cmd: CommanderModule, nav_state: int, now: int) -> list[Failure]:
    """Every reason arming in ``nav_state`` would be refused now (empty: ready to arm)."""
    data, p = cmd.data, cmd.p
    out = _sensor_failures(data, p["COM_ARM_IMU_ACC"], p["COM_ARM_IMU_GYR"])
    out += _estimator_failures(data)
    req = modes.REQUIREMENTS.get(nav_state, frozenset())
    mode = modes.NAV_NAMES.get(nav_state, str(nav_state))
    if nav_state in modes.NO_ARMING:
        out.append(Failure(False, f"Preflight Fail: arming not possible in {mode} mode"))
    if "never" in req:
        out.append(Failure(False, f"Preflight Fail: {mode} mode not supported"))
    if "offboard" in req and not data.offboard_ok(now, cmd.of_loss_us, p["COM_POS_FS_EPH"]):
        out.append(Failure(False, "Preflight Fail: Offboard mode requires an offboard signal "
                                  "(setpoints streamed at more than 2 Hz)"))
    eph = p["COM_POS_FS_EPH"]
    if "alt" in req and not data.alt_valid(now):
        out.append(Failure(False, f"Preflight Fail: {mode} mode requires altitude estimate"))
    if "lpos" in req and not data.lpos_valid(now, eph):
        out.append(Failure(False, f"Preflight Fail: {mode} mode requires local position"))
    need_gps = p["COM_ARM_WO_GPS"] == 0 or "gpos" in req
    if "gpos" in req and not data.gpos_valid(now, eph):
        out.append(Failure(False, f"Preflight Fail: {mode} mode requires global position"))
    if need_gps:
        fix = data.gps_fix(now)
        if fix < 3:
            out.append(Failure(False, "Preflight Fail: GPS fix too low" if fix else
                               "Preflight Fail: no GPS"))
        est = data.estimator.node.last
        if est is not None and est.gps_check_fail_flags:
            out.append(Failure(False, "Preflight Fail: GPS quality checks failing"))
    if "mission" in req and cmd.mission_count() == 0:
        out.append(Failure(False, "Preflight Fail: no valid mission"))
    rc_mode = p["COM_RC_IN_MODE"]
    rc_needed = rc_mode in (0, 2) or (rc_mode != 4 and "manual" in req)
    if rc_needed and not data.rc_present(now, cmd.rc_loss_us):
        out.append(Failure(False, "Preflight Fail: No manual control input"))
    io = data.io.node.last
    if io is not None and not io.status_safety_off and p["CBRK_IO_SAFETY"] != CBRK_IO_SAFETY_KEY:
        out.append(Failure(False, "Preflight Fail: safety switch engaged, press it first",
                           at_arming=True))
    bat = data.battery.node.last
    if bat is not None:
        if not bat.connected:
            out.append(Failure(False, "Preflight Fail: battery not connected"))
        elif bat.warning >= 1:
            out.append(Failure(False, f"Preflight Fail: low battery "
                                      f"({bat.remaining * 100:.0f} % remaining)"))
    if cmd.kill_engaged:
        out.append(Failure(False, "Preflight Fail: kill switch engaged"))
    return out
