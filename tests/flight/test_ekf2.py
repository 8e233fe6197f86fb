"""ekf2 on the emulated FMUv2: alignment on the turntable, a scripted flight against world truth,
innovation checks (GPS jump, magnetic disturbance), status flags, and the host cost.

The flight (``hil.sil``: JSBSim F450 + FMU board, direct ESC drive) is open loop as far as the
flight stack is concerned: no controller of ours runs. The script sets differential PWM steps on
top of a *test-harness* leveller that reads world truth (a stand-in for a test gimbal: without
it an open-loop quad tumbles within a second and the run would test nothing), so the vehicle
takes off, tilts by ~15 deg, translates at up to ~5 m/s, yaws and climbs.
"""

from __future__ import annotations

import math
import time
from typing import ClassVar

import pytest

from fmu.board import FmuV2Board
from firmware.modules.ekf2 import PARAMS as EKF_PARAMS
from firmware.modules.ekf2 import Ekf2Module
from firmware.modules.ekf2.gps import LocalProjection
from common.quaternion import q_mul, q_to_euler
from firmware.modules.sensors import PARAMS as SENSORS_PARAMS
from firmware.modules.sensors import SensorsModule
from firmware.platform.params import Params
from firmware.platform.uorb import Subscription
from firmware.system import System
from hil.sil import Sil
from hil.turntable import Turntable

S = 1_000_000_000
HOVER_US = 1507
CS_TILT, CS_YAW, CS_GPS, CS_MAG_HDG, CS_BARO = 1, 2, 4, 16, 128
INNOV_POS_NE, INNOV_YAW = 4, 128


def _start(fmu: FmuV2Board, **params: float) -> tuple[System, SensorsModule, Ekf2Module]:
    p = fmu.platform
    ps = Params(p, list(SENSORS_PARAMS) + list(EKF_PARAMS))
    ps.set("EKF2_MAG_DECL", 2.6, notify=False)  # the world's site (Zurich), WMM
    for name, value in params.items():
        ps.set(name, value, notify=False)
    system = System(p, ps, host_clock=time.perf_counter)
    sensors = SensorsModule(system)
    sensors.start()
    ekf = Ekf2Module(system)
    ekf.start()
    system.profiler.attach(p)
    return system, sensors, ekf


def _att_err_deg(q_est: tuple, q_true: tuple) -> float:
    dq = q_mul((q_true[0], -q_true[1], -q_true[2], -q_true[3]), q_est)
    return 2.0 * math.degrees(math.acos(min(1.0, abs(dq[0]))))


def _euler_deg(q: tuple) -> list[float]:
    return [math.degrees(v) for v in q_to_euler(q)]


def _wrap180(a: float) -> float:
    return (a + 180.0) % 360.0 - 180.0


# -- turntable --------------------------------------------------------------------------------


@pytest.mark.parametrize("roll, pitch, yaw", [(12.0, -8.0, -120.0), (-25.0, 15.0, 75.0)])
def test_still_board_attitude_converges(roll: float, pitch: float, yaw: float) -> None:
    fmu = FmuV2Board(seed=11, firmware="sensors")
    Turntable(fmu.kernel, fmu.env, roll_deg=roll, pitch_deg=pitch, yaw_deg=yaw)
    _system, _sensors, ekf = _start(fmu)
    fmu.kernel.run(3 * S)  # drivers start at 0.3 s, alignment 0.5 s later
    att = fmu.platform.orb.node("vehicle_attitude").last
    r, p, y = _euler_deg(tuple(att.q))
    assert abs(r - roll) < 1.0 and abs(p - pitch) < 1.0, (r, p)
    assert abs(_wrap180(y - yaw)) < 5.0, y
    st = fmu.platform.orb.node("estimator_status").last
    assert st.control_mode_flags & (CS_TILT | CS_YAW | CS_MAG_HDG | CS_BARO) == \
        CS_TILT | CS_YAW | CS_MAG_HDG | CS_BARO
    assert st.filter_fault_flags == 0 and st.innovation_check_flags == 0
    assert st.reset_count_quat == 1
    assert not st.pre_flt_fail_innov_heading and not st.pre_flt_fail_mag_field_disturbed
    lpos = fmu.platform.orb.node("vehicle_local_position").last
    assert lpos.z_valid and abs(lpos.z) < 0.5 and math.hypot(lpos.vx, lpos.vy) < 0.2
    assert ekf.tilt_aligned and ekf.yaw_aligned
    # the learnt gyro bias goes back to sensors, which removes it for the rate controller
    bias = fmu.platform.orb.node("estimator_sensor_bias").last
    assert bias.gyro_bias_valid and bias.gyro_device_id == fmu.platform.orb.node(
        "sensor_gyro").last.device_id
    sub = Subscription(fmu.platform.orb, "vehicle_angular_velocity")
    sub.copy()
    raw = Subscription(fmu.platform.orb, "sensor_gyro")
    raw.copy()
    acc, acc_raw = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
    for _ in range(500):
        fmu.kernel.run(fmu.kernel.now_ns + 1_000_000)
        m, r = sub.update(), raw.update()
        if m is not None and r is not None:
            acc = [a + v for a, v in zip(acc, m.xyz)]
            acc_raw = [a + v for a, v in zip(acc_raw, (r.x, r.y, r.z))]
    assert math.hypot(*acc) < 0.5 * math.hypot(*acc_raw), (acc, acc_raw)


class Still:
    """A still board with GPS in use after ~3 s, for the innovation-check tests."""

    def __init__(self) -> None:
        self.fmu = FmuV2Board(seed=12, firmware="sensors")
        Turntable(self.fmu.kernel, self.fmu.env, roll_deg=3.0, pitch_deg=2.0, yaw_deg=30.0)
        self.system, self.sensors, self.ekf = _start(self.fmu, EKF2_REQ_GPS_H=1.0)
        self.p = self.fmu.platform
        self.status = Subscription(self.p.orb, "estimator_status")
        self.run_s(4.0)

    def run_s(self, seconds: float) -> list:
        """Run; the estimator_status messages published meanwhile."""
        k = self.fmu.kernel
        out = []
        end = k.now_ns + int(seconds * S)
        while k.now_ns < end:
            k.run(min(end, k.now_ns + 50_000_000))
            msg = self.status.update()
            if msg is not None:
                out.append(msg)
        return out

    def lpos(self):
        return self.p.orb.node("vehicle_local_position").last

    def dmesg(self, since_us: int) -> list[str]:
        return [text for t, _s, m, text in self.p.dmesg if m == "ekf2" and t >= since_us]


@pytest.fixture(scope="module")
def still() -> Still:
    return Still()


def test_gps_used_after_quality_checks(still: Still) -> None:
    st = still.p.orb.node("estimator_status").last
    assert st.control_mode_flags & CS_GPS and st.gps_check_fail_flags == 0
    lpos = still.lpos()
    assert lpos.xy_valid and lpos.v_xy_valid and lpos.xy_global
    assert abs(lpos.ref_lat - 47.397742) < 1e-4 and abs(lpos.ref_lon - 8.545594) < 1e-4
    assert math.hypot(lpos.x, lpos.y) < 1.0
    gpos = still.p.orb.node("vehicle_global_position").last
    assert abs(gpos.alt - 488.0) < 3.0


def test_gps_jump_is_rejected_flagged_and_reported(still: Still) -> None:
    gps = still.fmu.devices["gps"]
    t0 = still.p.time_us()
    x0, y0 = still.lpos().x, still.lpos().y
    gps.jump(25.0, 0.0, 0.0)
    statuses = still.run_s(1.5)
    flagged = [m for m in statuses if m.innovation_check_flags & INNOV_POS_NE]
    assert flagged, "GPS jump not flagged"
    assert max(m.pos_test_ratio for m in statuses) > 1.0
    assert flagged[-1].health_flags & 2 and flagged[-1].solution_status_flags & 1024
    assert any(t.startswith("GPS position rejected") for t in still.dmesg(t0))
    lpos = still.lpos()
    assert math.hypot(lpos.x - x0, lpos.y - y0) < 1.5, "the jump leaked into the estimate"
    gps.jump(0.0, 0.0, 0.0)
    statuses = still.run_s(1.5)
    assert statuses[-1].innovation_check_flags & INNOV_POS_NE == 0
    assert statuses[-1].pos_test_ratio < 1.0


def test_persistent_gps_offset_resets_position_after_timeout(still: Still) -> None:
    gps = still.fmu.devices["gps"]
    t0 = still.p.time_us()
    resets = still.p.orb.node("estimator_status").last.reset_count_pos_ne
    gps.jump(0.0, 20.0, 0.0)
    still.run_s(6.0)  # EKF2_NOAID_TOUT 5 s
    st = still.p.orb.node("estimator_status").last
    assert st.reset_count_pos_ne == resets + 1
    assert any("position reset to GPS" in t for t in still.dmesg(t0))
    assert abs(still.lpos().y - 20.0) < 2.0  # it believes the GPS now
    gps.jump(0.0, 0.0, 0.0)
    still.run_s(6.0)
    assert abs(still.lpos().y) < 2.0


def test_magnetic_disturbance_is_rejected_and_flagged(still: Still) -> None:
    hmc = still.fmu.devices["hmc5883"]
    t0 = still.p.time_us()
    yaw0 = math.degrees(still.lpos().heading)
    hmc.faults.bias_step = (-0.2, 0.25, 0.0)  # turns the horizontal field by ~80 deg
    statuses = still.run_s(1.5)
    assert any(m.innovation_check_flags & INNOV_YAW for m in statuses)
    assert max(m.mag_test_ratio for m in statuses) > 1.0
    assert any(t.startswith("mag heading rejected") for t in still.dmesg(t0))
    assert abs(_wrap180(math.degrees(still.lpos().heading) - yaw0)) < 3.0
    # a field of the wrong strength (a magnet near the compass): fusion stops, pre-flight fail
    hmc.faults.bias_step = (0.0, 0.0, 0.35)
    statuses = still.run_s(1.0)
    assert statuses[-1].pre_flt_fail_mag_field_disturbed
    assert not statuses[-1].control_mode_flags & CS_MAG_HDG
    assert any(t.startswith("magnetic field disturbed") for t in still.dmesg(t0))
    hmc.faults.bias_step = (0.0, 0.0, 0.0)
    statuses = still.run_s(1.5)
    last = statuses[-1]
    assert not last.pre_flt_fail_mag_field_disturbed and last.control_mode_flags & CS_MAG_HDG
    assert last.innovation_check_flags == 0 and last.filter_fault_flags == 0


# -- the flight --------------------------------------------------------------------------------


class Flight:
    """Take-off, tilt/translate steps, a yaw turn and a climb, with truth compared every 50 ms."""

    STEP_US = 10.0  # differential PWM step, us
    SCRIPT: ClassVar[list[tuple[float, str, object]]] = [(4.0, "armed", True), (4.5, "fly", True),
              (9.0, "diff", (STEP_US, 0.0, 0.0)), (10.5, "diff", (-STEP_US, 0.0, 0.0)),
              (12.0, "diff", (0.0, 0.0, 0.0)),
              (13.0, "diff", (0.0, -STEP_US, 0.0)), (14.5, "diff", (0.0, STEP_US, 0.0)),
              (16.0, "diff", (0.0, 0.0, 0.0)),
              (17.0, "diff", (STEP_US, STEP_US, 8.0)), (18.5, "diff", (-STEP_US, -STEP_US, 8.0)),
              (20.0, "diff", (0.0, 0.0, -8.0)), (21.5, "diff", (0.0, 0.0, 0.0)),
              (22.0, "z_sp", -9.0)]
    END_S = 25.0

    def __init__(self) -> None:
        self.sil = Sil(seed=2, firmware="sensors")
        self.p = self.sil.fmu.platform
        self.system, self.sensors, self.ekf = _start(self.sil.fmu, EKF2_REQ_GPS_H=2.0)
        self.state = {"armed": False, "fly": False, "z_sp": -5.0, "diff": (0.0, 0.0, 0.0)}
        self.sil.hooks.append(self._esc)
        self.samples: list[tuple] = []
        self.statuses: list = []
        self.max_tilt_deg = 0.0
        self.max_speed = 0.0
        self._status_sub = Subscription(self.p.orb, "estimator_status")
        self._proj = LocalProjection()
        h0 = time.perf_counter()
        self._fly()
        self.host_s = time.perf_counter() - h0
        self.virtual_s = self.sil.world.t_ns / S
        prof = self.system.profiler
        self.host_ekf_s = prof.host_s(self.ekf.work_item) / self.virtual_s
        self.host_sensors_s = prof.host_s(self.sensors.work_item) / self.virtual_s

    def _esc(self, sil: Sil) -> None:
        """The harness leveller + scripted steps (quad X, PX4 motor order)."""
        w = sil.world
        st = self.state
        if not st["fly"]:
            w.set_motor_pwm_us([1000 if st["armed"] else 900] * 4)
            return
        tr = w.truth()
        roll, pitch, _yaw = tr.euler_rad
        p, q, r = tr.gyro_rad_s
        dr, dp, dy = st["diff"]
        u_r = -40.0 * roll - 12.0 * p + dr
        u_p = -40.0 * pitch - 12.0 * q + dp
        u_y = -40.0 * r + dy
        c = HOVER_US + 25.0 * (tr.pos_ned_m[2] - st["z_sp"]) + 35.0 * tr.vel_ned_m_s[2]
        c = 1000.0 + (c - 1000.0) / max(0.5, math.cos(roll) * math.cos(pitch)) ** 0.5
        m = (c - u_r + u_p + u_y, c + u_r - u_p + u_y, c + u_r + u_p - u_y, c - u_r - u_p - u_y)
        w.set_motor_pwm_us([max(1000.0, min(2000.0, v)) for v in m])

    def _fly(self) -> None:
        sil, orb = self.sil, self.p.orb
        script = list(self.SCRIPT)
        att_node = orb.node("vehicle_attitude")
        lpos_node = orb.node("vehicle_local_position")
        next_sample_ns = 0
        while sil.world.t_ns < self.END_S * S:
            t_ns = sil.world.t_ns
            while script and t_ns >= script[0][0] * S:
                _, key, value = script.pop(0)
                self.state[key] = value
            sil.step()
            msg = self._status_sub.update()
            if msg is not None:
                self.statuses.append((t_ns / S, msg))
            if t_ns < next_sample_ns:
                continue
            next_sample_ns += 50_000_000
            lp, att = lpos_node.last, att_node.last
            if lp is None or att is None or not lp.xy_valid:
                continue
            tr = sil.world.truth()
            if not self._proj.valid:
                self._proj.init(lp.ref_lat, lp.ref_lon)
            tn, te = self._proj.project(tr.lat_deg, tr.lon_deg)
            vn, ve, vd = tr.vel_ned_m_s
            self.samples.append((t_ns / S, _att_err_deg(tuple(att.q), tr.q_nb),
                                 math.sqrt((lp.vx - vn) ** 2 + (lp.vy - ve) ** 2
                                           + (lp.vz - vd) ** 2),
                                 math.hypot(lp.x - tn, lp.y - te), lp.z - tr.pos_ned_m[2]))
            self.max_tilt_deg = max(self.max_tilt_deg, math.degrees(max(
                abs(tr.euler_rad[0]), abs(tr.euler_rad[1]))))
            self.max_speed = max(self.max_speed, math.hypot(vn, ve))

    def rms(self, column: int, after_s: float = 7.0) -> float:
        xs = [s[column] for s in self.samples if s[0] >= after_s]
        return math.sqrt(sum(x * x for x in xs) / len(xs))


@pytest.fixture(scope="module")
def flight() -> Flight:
    return Flight()


def test_flight_estimate_matches_truth(flight: Flight) -> None:
    att, vel, pos, hgt = (flight.rms(i) for i in (1, 2, 3, 4))
    print(f"\nflight {flight.virtual_s:.0f} s (max tilt {flight.max_tilt_deg:.0f} deg, max speed "
          f"{flight.max_speed:.1f} m/s): attitude {att:.2f} deg rms, velocity {vel:.3f} m/s "
          f"rms, horizontal position {pos:.2f} m rms, height {hgt:.2f} m rms")
    assert flight.max_tilt_deg > 10.0 and flight.max_speed > 3.0  # the script did move it
    assert att < 2.0
    assert vel < 0.3
    assert pos < 1.5
    assert hgt < 1.0


def test_flight_status_flags_stay_clear(flight: Flight) -> None:
    after = [m for t, m in flight.statuses if t > 5.0]
    assert after
    for m in after:
        assert m.filter_fault_flags == 0
        assert m.innovation_check_flags == 0
        assert m.health_flags == 0 and m.timeout_flags == 0
        assert m.gps_check_fail_flags == 0
        assert m.control_mode_flags & (CS_TILT | CS_YAW | CS_GPS | CS_MAG_HDG | CS_BARO) == \
            CS_TILT | CS_YAW | CS_GPS | CS_MAG_HDG | CS_BARO
        assert not (m.pre_flt_fail_innov_heading or m.pre_flt_fail_innov_vel_horiz
                    or m.pre_flt_fail_innov_vel_vert or m.pre_flt_fail_innov_height
                    or m.pre_flt_fail_mag_field_disturbed)
    lpos = flight.p.orb.node("vehicle_local_position").last
    assert lpos.xy_valid and lpos.z_valid and lpos.v_xy_valid and lpos.v_z_valid
    assert not lpos.dead_reckoning
    tr = flight.sil.world.truth()
    assert abs(lpos.dist_bottom - tr.agl_m) < 1.0
    gpos = flight.p.orb.node("vehicle_global_position").last
    n, e = LocalProjection(), None
    n.init(tr.lat_deg, tr.lon_deg)
    e = n.project(gpos.lat, gpos.lon)
    assert math.hypot(*e) < 2.0 and abs(gpos.alt - tr.alt_m) < 1.5


def test_flight_host_cost(flight: Flight) -> None:
    """Not asserted: the host time of the two modules per virtual second, for the report."""
    print(f"\nhost cost per virtual second: ekf2 {flight.host_ekf_s * 1e3:.1f} ms, sensors "
          f"{flight.host_sensors_s * 1e3:.1f} ms (whole SIL: "
          f"{flight.host_s / flight.virtual_s:.2f} s/s)")
    assert flight.host_ekf_s > 0.0 and flight.host_sensors_s > 0.0
