"""Multicopter control: rate, attitude and position control flying the JSBSim F450 in the Sil.

The estimator is the test-only truth estimator and a test-side stub plays commander and
navigator (arming, control mode, position setpoint triplet, sticks). One mission is flown once
per module (takeoff to 10 m, 20 m north, 20 m east, a position-mode stick push, land) and the
tests check its phases; an attitude step in stabilized mode is flown separately. The pure parts
(attitude error, thrust to attitude, trajectory, hover thrust filter) have unit tests.
"""

from __future__ import annotations

import math
import time

import pytest

from firmware.modules.mc_att_control.mc_att_control import attitude_error_rates
from common.quaternion import q_from_euler, q_to_euler
from firmware.modules.mc_pos_control.flight_tasks import (
    SP_LAND,
    SP_POSITION,
    SP_TAKEOFF,
    LineTrajectory,
)
from firmware.modules.mc_pos_control.hover_thrust_estimator import HoverThrustEstimator
from firmware.modules.mc_pos_control.position_control import PositionControl, attitude_from_thrust
from tests.flight.truth_estimator import FlightRig
from common.units import G0_M_S2

#: F450 tuning (JSBSim model: 1.4 kg, hover throttle ~0.51, ESC + rotor lag ~70 ms). Measured
#: open loop: 295 rad/s^2 per unit roll/pitch control, 38 rad/s^2 per unit yaw control,
#: thrust ~ 42 N * (throttle - 0.18) (affine, not quadratic: THR_MDL_FAC 0). The rest of the
#: parameters keep their PX4 defaults.
F450_PARAMS: dict[str, float] = {
    "MC_ROLLRATE_P": 0.1, "MC_ROLLRATE_I": 0.08, "MC_ROLLRATE_D": 0.008,
    "MC_PITCHRATE_P": 0.1, "MC_PITCHRATE_I": 0.08, "MC_PITCHRATE_D": 0.008,
    "MC_YAWRATE_P": 0.3, "MC_YAWRATE_I": 0.1,
    "MC_ROLL_P": 5.5, "MC_PITCH_P": 5.5,
    "MPC_TKO_RAMP_T": 1.5,
}



# -- the mission ------------------------------------------------------------------------------


class Recorder:
    """Checks every world step for bad outputs; logs the state at 100 Hz."""

    def __init__(self, rig: FlightRig) -> None:
        self.rig = rig
        self.rows: list[dict[str, float]] = []
        self.bad: list[str] = []
        self.n = 0
        rig.sil.hooks.append(self.step)

    def step(self, sil) -> None:
        c = self.rig.topic("actuator_controls_0")
        if c is not None:
            r, p, y, t = c.control[:4]
            if not (all(math.isfinite(v) and -1.0 <= v <= 1.0 for v in (r, p, y))
                    and math.isfinite(t) and 0.0 <= t <= 1.0):
                self.bad.append(f"t={sil.t_ns / 1e9:.3f} controls {c.control[:4]}")
        for us in sil.pwm_us[:4]:
            if not (900 <= us <= 2000):
                self.bad.append(f"t={sil.t_ns / 1e9:.3f} pwm {sil.pwm_us[:4]}")
        self.n += 1
        if self.n % 10:
            return
        tr = sil.world.truth()
        ld = self.rig.topic("vehicle_land_detected")
        self.rows.append({
            "t": tr.t_ns / 1e9, "x": tr.pos_ned_m[0], "y": tr.pos_ned_m[1],
            "z": tr.pos_ned_m[2], "vx": tr.vel_ned_m_s[0], "vy": tr.vel_ned_m_s[1],
            "vz": tr.vel_ned_m_s[2], "agl": tr.agl_m, "landed": float(ld.landed),
            "lx": self.rig.topic("vehicle_local_position").x,
            "ly": self.rig.topic("vehicle_local_position").y,
        })

    def window(self, t0: float, t1: float) -> list[dict[str, float]]:
        return [r for r in self.rows if t0 <= r["t"] < t1]


@pytest.fixture(scope="module")
def mission():
    """Fly the whole mission once; returns (rig, recorder, phase start times, host seconds)."""
    rig = FlightRig(F450_PARAMS, host_clock=time.perf_counter)
    rec = Recorder(rig)
    phases: dict[str, float] = {}

    def mark(name: str) -> None:
        phases[name] = rig.sil.t_ns / 1e9

    rig.set_mode("auto")
    rig.run(0.3)                      # disarmed: the ESCs arm on low pulses
    rig.arm()
    mark("takeoff")
    rig.set_setpoint(SP_TAKEOFF, 0.0, 0.0, 10.0)
    rig.run(14.0)
    mark("north")
    rig.set_setpoint(SP_POSITION, 20.0, 0.0, 10.0)
    rig.run(10.0)
    mark("east")
    rig.set_setpoint(SP_POSITION, 20.0, 20.0, 10.0)
    rig.run(10.0)
    mark("posctl")
    rig.set_sticks()
    rig.set_mode("position")
    rig.set_sticks(pitch=0.5)
    rig.run(2.0)
    mark("posctl_release")
    rig.set_sticks()
    rig.run(6.0)
    mark("land")
    lp = rig.topic("vehicle_local_position")
    rig.set_mode("auto")
    rig.set_setpoint(SP_LAND, lp.x, lp.y, 0.0)
    rig.run(19.0)
    mark("end")
    host = rig.host_seconds()
    return rig, rec, phases, host


def test_outputs_never_nan_or_out_of_range(mission):
    _rig, rec, _phases, _host = mission
    assert rec.bad == []


def test_takeoff_reaches_10m_and_holds(mission):
    _rig, rec, ph, _host = mission
    climb = rec.window(ph["takeoff"], ph["north"])
    assert min(r["z"] for r in climb) > -10.3          # overshoot < 0.3 m
    hover = rec.window(ph["takeoff"] + 10.0, ph["north"])
    alt_err = max(abs(-r["z"] - 10.0) for r in hover)
    pos_err = max(math.hypot(r["lx"], r["ly"]) for r in hover)
    print(f"\nhover: altitude error max {alt_err:.3f} m, horizontal {pos_err:.3f} m")
    assert alt_err < 0.3
    assert pos_err < 0.5


def _leg(rec: Recorder, t0: float, t1: float, start: tuple[float, float],
         end: tuple[float, float]) -> tuple[float, float, float, float]:
    """Final error, overshoot along the leg, max cross-track and max altitude error."""
    rows = rec.window(t0, t1)
    dx, dy = end[0] - start[0], end[1] - start[1]
    n = math.hypot(dx, dy)
    ux, uy = dx / n, dy / n
    along = [(r["lx"] - start[0]) * ux + (r["ly"] - start[1]) * uy for r in rows]
    cross = [abs(-(r["lx"] - start[0]) * uy + (r["ly"] - start[1]) * ux) for r in rows]
    last = rows[-1]
    final = math.hypot(last["lx"] - end[0], last["ly"] - end[1])
    alt = max(abs(-r["z"] - 10.0) for r in rows)
    return final, max(along) - n, max(cross), alt


def test_fly_north_then_east(mission):
    _rig, rec, ph, _host = mission
    f1, o1, c1, a1 = _leg(rec, ph["north"], ph["east"], (0.0, 0.0), (20.0, 0.0))
    f2, o2, c2, a2 = _leg(rec, ph["east"], ph["posctl"], (20.0, 0.0), (20.0, 20.0))
    print(f"\nnorth leg: final {f1:.2f} m, overshoot {o1:.2f} m, cross-track {c1:.2f} m, "
          f"altitude {a1:.2f} m")
    print(f"east leg:  final {f2:.2f} m, overshoot {o2:.2f} m, cross-track {c2:.2f} m, "
          f"altitude {a2:.2f} m")
    for final, over, cross, alt in ((f1, o1, c1, a1), (f2, o2, c2, a2)):
        assert final < 1.0
        assert over < 1.0
        assert cross < 0.5
        assert alt < 0.5


def test_position_mode_stick_and_hold(mission):
    _rig, rec, ph, _host = mission
    push = rec.window(ph["posctl"], ph["posctl_release"])
    assert max(r["vx"] for r in push) > 2.0             # the stick flies it north
    hold = rec.window(ph["posctl_release"] + 3.5, ph["land"])
    xs = [r["lx"] for r in hold]
    assert max(xs) - min(xs) < 0.3                      # braked and holding
    assert max(abs(-r["z"] - 10.0) for r in rec.window(ph["posctl"], ph["land"])) < 0.5


def test_land_speed_and_detection(mission):
    rig, rec, ph, _host = mission
    rows = rec.window(ph["land"], ph["end"])
    v_land = F450_PARAMS.get("MPC_LAND_SPEED", 0.7)
    low = [r["vz"] for r in rows if 0.5 < -r["z"] < 4.0]
    assert low and all(abs(v - v_land) < 0.1 for v in low), (min(low), max(low))
    touch = next(r["t"] for r in rows if -r["z"] < 0.02)
    landed = next(r["t"] for r in rows if r["landed"] > 0.5)
    print(f"\nlanding: descent {min(low):.2f}..{max(low):.2f} m/s, landed detected "
          f"{landed - touch:.2f} s after touchdown")
    assert 0.0 < landed - touch < 4.0
    assert all(r["landed"] > 0.5 for r in rows if r["t"] > landed)
    assert rig.topic("actuator_controls_0").control[3] == 0.0   # motors idle on the ground


def test_hover_thrust_estimate_converges(mission):
    rig, _rec, _ph, _host = mission
    hte = rig.topic("hover_thrust_estimate")
    assert hte.valid
    assert 0.47 < hte.hover_thrust < 0.55               # the F450 hovers at ~0.51


def test_host_cost_printout(mission):
    """Host time per virtual second of each module (printed, never asserted)."""
    _rig, _rec, ph, host = mission
    span = ph["end"]
    print(f"\nhost cost per virtual second over {span:.0f} s of flight:")
    for name, s in sorted(host.items()):
        print(f"  {name:18s} {s / span * 1000:6.2f} ms/s")


# -- attitude step in stabilized mode ------------------------------------------------------


def test_stabilized_roll_step_response():
    rig = FlightRig(F450_PARAMS, agl_m=40.0,
                    modules=("mc_rate_control", "mc_att_control", "land_detector"))
    rig.set_mode("stabilized")
    rig.set_sticks(throttle=0.0)
    rig.run(0.2)
    rig.arm()
    rig.run(1.0)
    roll: list[float] = []
    rig.set_sticks(roll=0.5)
    rig.run(1.5, lambda r: roll.append(r.sil.world.truth().euler_rad[0]), every_n=1)
    target = 0.5 * math.radians(35.0)
    t10 = next(i for i, v in enumerate(roll) if v > 0.1 * target)
    t90 = next(i for i, v in enumerate(roll) if v > 0.9 * target)
    overshoot = (max(roll) - target) / target
    print(f"\nroll step 17.5 deg: rise {t90 - t10} ms, overshoot {overshoot * 100:.1f} %, "
          f"final error {math.degrees(abs(roll[-1] - target)):.2f} deg")
    assert t90 - t10 < 400
    assert overshoot < 0.25
    assert abs(roll[-1] - target) < math.radians(1.0)


# -- unit tests of the pure parts ------------------------------------------------------------


def test_attitude_error_is_tilt_first():
    q = q_from_euler(0.0, 0.0, 0.0)
    ex, ey, ez = attitude_error_rates(q, q_from_euler(0.2, 0.0, 0.0), 0.4)
    # the error is 2 sin(angle / 2) about the axis
    assert ex == pytest.approx(2.0 * math.sin(0.1), abs=1e-9) and abs(ey) < 1e-9 \
        and abs(ez) < 1e-9
    # a pure heading error is scaled by the yaw weight
    ex, ey, ez = attitude_error_rates(q, q_from_euler(0.0, 0.0, 0.5), 0.4)
    assert ez == pytest.approx(0.2, abs=1e-3) and abs(ex) < 1e-9
    # with both, the tilt part is the full tilt error whatever the heading error
    ex, ey, _ez = attitude_error_rates(q, q_from_euler(0.2, 0.0, 1.5), 0.4)
    assert math.hypot(ex, ey) == pytest.approx(2.0 * math.sin(0.1), abs=0.01)


def test_attitude_from_thrust():
    q = attitude_from_thrust(0.0, 0.0, -0.5, 0.3)
    r, p, y = q_to_euler(q)
    assert abs(r) < 1e-9 and abs(p) < 1e-9 and y == pytest.approx(0.3)
    # thrust tilted north at heading 0: nose down (negative pitch)
    r, p, y = q_to_euler(attitude_from_thrust(0.5 * math.tan(0.2), 0.0, -0.5, 0.0))
    assert p == pytest.approx(-0.2) and abs(r) < 1e-9


def test_position_control_hover_and_tilt_limit():
    pc = PositionControl()
    pc.hover = 0.5
    nan = math.nan
    pc.update(0.01, (0, 0, -10), (0, 0, 0), (0, 0, 0), [0, 0, -10], [nan] * 3, [nan] * 3)
    assert pc.thrust == pytest.approx([0.0, 0.0, -0.5])
    pc.update(0.01, (0, 0, -10), (0, 0, 0), (0, 0, 0), [100, 0, -10], [nan] * 3, [nan] * 3)
    tilt = math.atan2(math.hypot(pc.thrust[0], pc.thrust[1]), -pc.thrust[2])
    assert tilt <= pc.tilt_max + 1e-9


def test_line_trajectory_stops_at_the_end():
    tr = LineTrajectory()
    tr.plan((0, 0, -10), (20, 0, -10), (0, 0, 0), 5.0, 3.0, 1.5, 3.0, 4.0, 3.0, 4.0)
    v_max = 0.0
    xs = []
    for _ in range(2000):
        tr.update(0.01)
        xs.append(tr.position()[0])
        v_max = max(v_max, tr.v)
    assert tr.done and xs[-1] == pytest.approx(20.0)
    assert max(xs) <= 20.0 + 1e-9
    assert 4.9 < v_max <= 5.0


def test_hover_thrust_estimator_converges():
    hte = HoverThrustEstimator(hover=0.4)
    true_h = 0.55
    for i in range(3000):
        thrust = 0.55 + 0.05 * math.sin(i * 0.01)
        az = G0_M_S2 * (1.0 - thrust / true_h)
        hte.update(0.01, az, thrust)
    assert hte.valid and hte.hover == pytest.approx(true_h, abs=0.01)
