"""Faults in the world's physics: motors, propellers, wind, battery, magnetic disturbance."""

from __future__ import annotations

import math

import pytest

from hil.world import World
from hil.world.world import NOLOAD_CURRENT_A

S = 1_000_000_000


def _airborne(seed: int = 1) -> World:
    """A vehicle 20 m up with its ESCs armed and all four motors near hover thrust."""
    w = World(seed=seed, agl_m=20.0)
    w.set_motor_pwm_us([900] * 4)
    w.run_until(w.t_ns + S // 5)          # ESCs arm on 0.1 s of low pulses
    w.set_motor_pwm_us([1540] * 4)
    w.run_until(w.t_ns + S // 2)
    return w


def test_motor_failure_cuts_its_thrust_and_current_and_the_vehicle_yaws_and_rolls():
    ref, w = _airborne(), _airborne()
    assert ref.truth() == w.truth()
    i_before = w.battery.current_a
    w.fail_motor(0)                       # front right, CCW
    for x in (ref, w):
        x.run_until(x.t_ns + S)
    assert w.motor_thrust_n(0) < 0.05 * ref.motor_thrust_n(0)
    assert w.escs[0].throttle > 0.4       # the ESC still drives what it is told
    # three motors left: about a quarter less current than before
    assert w.battery.current_a < 0.85 * i_before
    r, t = ref.truth(), w.truth()
    # the front-right thrust is gone: the vehicle rolls right-side down and pitches nose down
    # and the three remaining rotors' unbalanced torque yaws it
    assert abs(r.euler_rad[0]) < 0.01 and abs(r.gyro_rad_s[2]) < 0.01
    assert t.euler_rad[0] > 0.2 and t.euler_rad[1] < -0.1
    assert abs(t.gyro_rad_s[2]) > 0.2
    assert t.vel_ned_m_s[2] > r.vel_ned_m_s[2] + 1.0   # and it descends
    w.restore_motor(0)
    w.run_until(w.t_ns + S // 2)
    assert w.motor_thrust_n(0) > 1.0


def test_weak_motor_keeps_about_the_stated_fraction_of_thrust():
    ref, w = _airborne(), _airborne()
    w.fail_motor(2, thrust_fraction=0.5)
    for x in (ref, w):
        x.run_until(x.t_ns + S // 5)
    ratio = w.motor_thrust_n(2) / ref.motor_thrust_n(2)
    assert 0.35 < ratio < 0.65, ratio


def test_propeller_loss_leaves_the_no_load_current_only():
    ref, w = _airborne(), _airborne()
    w.fail_motor(1, kind="propeller")
    for x in (ref, w):
        x.run_until(x.t_ns + S // 2)
    assert w.motor_thrust_n(1) < 0.05 * ref.motor_thrust_n(1)
    # a loaded motor draws several amps; the free-running one a fraction of an amp
    per_motor = (ref.battery.current_a - ref.battery.params.avionics_a) / 4
    lost = ref.battery.current_a - w.battery.current_a
    assert per_motor > 3.0
    # the three others work harder as the vehicle tips, so compare with bounds
    assert 0.5 * per_motor < lost + NOLOAD_CURRENT_A
    assert w._extra_a == pytest.approx(NOLOAD_CURRENT_A * w.escs[1].throttle)


def test_bad_motor_index_and_kind_are_clear_errors():
    w = World(seed=1)
    with pytest.raises(ValueError, match="motor index"):
        w.fail_motor(4)
    with pytest.raises(ValueError, match="kind"):
        w.fail_motor(0, kind="rotor")


def test_steady_wind_pushes_the_vehicle_downwind_and_a_gust_comes_and_goes():
    ref, w = _airborne(), _airborne()
    w.set_wind(north_m_s=0.0, east_m_s=12.0)
    for x in (ref, w):
        x.run_until(x.t_ns + 2 * S)
    assert w.wind_ned_m_s()[1] == pytest.approx(12.0)
    dv = w.truth().vel_ned_m_s[1] - ref.truth().vel_ned_m_s[1]
    assert dv > 0.3                        # drifting east with the air
    g = _airborne()
    g.gust(north_m_s=8.0, east_m_s=0.0, rise_s=0.5, hold_s=0.5, fall_s=0.5)
    peak = 0.0
    for _ in range(25):
        g.run_until(g.t_ns + S // 10)
        peak = max(peak, g.wind_ned_m_s()[0])
    assert peak == pytest.approx(8.0, rel=0.05)
    assert abs(g.wind_ned_m_s()[0]) < 0.1   # over after 1.5 s


def test_turbulence_is_random_but_seeded():
    def run(seed):
        w = _airborne(seed)
        w.set_turbulence(8.0, severity=4)
        winds = []
        for _ in range(20):
            w.run_until(w.t_ns + S // 20)
            winds.append(w.wind_ned_m_s())
        return winds
    a, b, c = run(5), run(5), run(6)
    assert a == b
    assert a != c
    assert max(math.hypot(n, e) for n, e, _ in a) > 0.1


def test_battery_forced_low_and_collapsing_under_load():
    w = _airborne()
    v0, i0 = w.battery.voltage_v, w.battery.current_a
    w.battery.force_soc(0.05)
    w.run_until(w.t_ns + S // 10)
    assert w.battery.soc < 0.05
    assert w.battery.voltage_v < v0 - 1.0                   # 3.6 V per cell, loaded
    assert w.truth().battery_v == w.battery.voltage_v       # what the power module sees
    ref = _airborne()
    ref.battery.force_soc(0.05)
    w.battery.set_r0(0.15)                                  # a damaged cell, a bad connector
    for x in (ref, w):
        x.run_until(x.t_ns + S // 2)
    # the pack cannot hold its voltage under the load: the motors get less and lose thrust
    assert sum(map(w.motor_thrust_n, range(4))) < 0.9 * sum(map(ref.motor_thrust_n, range(4)))
    # the pack alone: at 15 A the healthy one sags 0.45 V, the damaged one 2.25 V
    from hil.world.battery import Battery
    b = Battery()
    b.step(15.0)
    healthy = b.ocv_v - b.voltage_v
    b.set_r0(0.15)
    b.step(15.0)
    assert b.ocv_v - b.voltage_v == pytest.approx(healthy + 15.0 * 0.12, abs=0.01)
    with pytest.raises(ValueError):
        w.battery.force_soc(1.5)


def test_magnetic_disturbance_adds_a_body_field_growing_with_current():
    w = _airborne()
    clean = w.truth().mag_body_gauss
    w.mag_disturbance = ((0.1, 0.0, 0.0), (0.0, 0.0, 0.01))
    w.run_until(w.t_ns + w.dt_ns)
    dist = w.truth().mag_body_gauss
    w.mag_disturbance = None
    w.run_until(w.t_ns + w.dt_ns)
    clean2 = w.truth().mag_body_gauss
    amps = w.battery.current_a
    assert dist[0] - (clean[0] + clean2[0]) / 2 == pytest.approx(0.1, abs=0.01)
    assert dist[2] - (clean[2] + clean2[2]) / 2 == pytest.approx(0.01 * amps, rel=0.1)
