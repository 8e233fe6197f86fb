"""World model: JSBSim F450 at rest and in flight, truth conventions, ESC, battery, determinism."""

import math

import pytest

from hil.world import Battery, BatteryParams, Esc, EscParams, World
from hil.world.atmosphere import isa_pressure_pa
from common.units import G0_M_S2

MS = 1_000_000  # ns


def arm(world: World, n: int = 4) -> None:
    """Throttle-low pulses long enough for the ESCs to arm."""
    world.set_motor_pwm_us([1000.0] * n)
    world.step(int(0.15 * world.rate_hz))
    assert all(e.armed for e in world.escs[:n])


def norm(v):
    return math.sqrt(sum(x * x for x in v))


# -- at rest ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def rest():
    """A world resting 2 s on the ground, motors off: (truth at t=0, truth at 2 s)."""
    w = World()
    t0 = w.truth()
    w.step(2000)
    return t0, w.truth()


def test_rest_on_ground(rest):
    t0, t2 = rest
    assert t2.t_ns == 2_000_000_000
    assert abs(t2.alt_m - t0.alt_m) < 0.03
    assert abs(t2.vel_ned_m_s[2]) < 0.01
    assert norm(t2.vel_ned_m_s) < 0.01
    assert 0.10 < t2.agl_m < 0.16  # CG above the ground on its legs
    assert 488.0 < t2.alt_m < 488.2  # ground at PX4's home altitude


def test_rest_specific_force_points_up_in_frd(rest):
    for tr in rest:  # already valid at t = 0
        ax, ay, az = tr.accel_body_m_s2
        assert abs(norm(tr.accel_body_m_s2) - G0_M_S2) < 0.05
        assert az < -9.75  # accelerometer z reads -g when level at rest (PX4 FRD)
        assert abs(ax) < 0.01 and abs(ay) < 0.01
        assert norm(tr.gyro_rad_s) < 1e-3  # only the Earth's rotation (7.3e-5 rad/s)


def test_rest_attitude_level_heading_north(rest):
    _, tr = rest
    roll, pitch, yaw = tr.euler_rad
    assert abs(roll) < 1e-3 and abs(pitch) < 1e-3 and abs(yaw) < 1e-3
    w, x, y, z = tr.q_nb
    assert w > 0.999999 and abs(x) + abs(y) + abs(z) < 1e-3
    assert abs(tr.lat_deg - 47.397742) < 1e-6 and abs(tr.lon_deg - 8.545594) < 1e-6
    assert norm(tr.pos_ned_m) < 0.03


def test_magnetic_field_at_home(rest):
    _, tr = rest
    mx, my, mz = tr.mag_body_gauss  # level, heading north: body = NED
    incl = math.degrees(math.atan2(mz, math.hypot(mx, my)))
    decl = math.degrees(math.atan2(my, mx))
    assert abs(incl - 63.0) < 2.0
    assert abs(decl - 2.5) < 1.0
    assert 0.45 < norm(tr.mag_body_gauss) < 0.52
    assert abs(mx - 0.21) < 0.02 and abs(mz - 0.43) < 0.02


def test_heading_east_rotates_field_into_body():
    w = World(heading_deg=90.0)
    tr = w.truth()
    mn, me, md = w.mag_field_ned_gauss
    assert abs(tr.euler_rad[2] - math.pi / 2) < 1e-3
    bx, by, bz = tr.mag_body_gauss  # nose east: body x = east, body y = south
    assert abs(bx - me) < 1e-3 and abs(by + mn) < 1e-3 and abs(bz - md) < 1e-3
    qw, qx, qy, qz = tr.q_nb  # yaw 90 deg about down
    assert abs(qw - math.sqrt(0.5)) < 1e-3 and abs(qz - math.sqrt(0.5)) < 1e-3


def test_pressure_and_temperature_isa(rest):
    _, tr = rest
    h = tr.alt_m
    # barometric formula, troposphere (geometric altitude; geopotential differs by 0.04 m)
    p_isa = 101325.0 * (1.0 - 0.0065 * h / 288.15) ** (G0_M_S2 * 0.0289644 / (8.3144598 * 0.0065))
    assert abs(tr.pressure_pa - p_isa) < 5.0
    assert abs(tr.pressure_pa - isa_pressure_pa(h)) < 2.0
    assert abs(tr.pressure_pa - 95600.0) < 50.0
    assert abs(tr.temperature_c - (15.0 - 0.0065 * h)) < 0.05
    assert tr.airspeed_m_s < 0.01 and tr.diff_pressure_pa < 0.01


# -- clock --------------------------------------------------------------------------------


def test_integer_clock():
    w = World(rate_hz=400, agl_m=5.0)
    assert w.dt_ns == 2_500_000
    w.step(400)
    assert w.t_ns == 1_000_000_000 and w.truth().t_ns == w.t_ns
    w.run_until(1_004_000_000)  # one whole step fits
    assert w.t_ns == 1_002_500_000
    with pytest.raises(ValueError):
        World(rate_hz=300)


# -- flight -------------------------------------------------------------------------------


def _vz_after(pwm_us: float, hold_s: float = 2.0):
    """Vertical speed samples (every 0.1 s) over hold_s at a constant PWM on all motors.

    Airborne start. While the motors spin up, a proportional loop on the vertical speed
    around pwm_us holds the vehicle (vertical damping of a quad is weak: without it the drop
    during spin-up would last for seconds); then the PWM is held constant at pwm_us.
    """
    w = World(agl_m=30.0)
    arm(w)
    k_us_per_m_s = 60.0
    for _ in range(300):  # 3 s
        vz = w.truth().vel_ned_m_s[2]
        w.set_motor_pwm_us([pwm_us + k_us_per_m_s * vz] * 4)
        w.step(10)
    w.set_motor_pwm_us([pwm_us] * 4)
    samples = []
    for _ in range(round(hold_s * 10)):
        w.step(100)
        samples.append(w.truth().vel_ned_m_s[2])
    return samples


def find_hover_pwm_us(lo: float = 1300.0, hi: float = 1800.0, tol_us: float = 0.25) -> float:
    """Bisection on a constant PWM (all motors) for zero vertical speed at the end."""
    while hi - lo > tol_us:
        mid = 0.5 * (lo + hi)
        if _vz_after(mid, hold_s=1.0)[-1] > 0.0:  # descending: more throttle
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def test_hover_throttle():
    pwm = find_hover_pwm_us()
    assert 1400.0 < pwm < 1650.0  # ~ 0.4 .. 0.65 throttle
    vz = _vz_after(pwm, hold_s=2.0)
    assert max(abs(v) for v in vz) < 0.2, (pwm, vz)


def test_motor_order_and_torques_match_px4_quad_x():
    """Engines 0..3 = PX4 motors 1..4: FR (CCW), RL (CCW), FL (CW), RR (CW)."""

    def rates_after(widths):
        w = World(agl_m=30.0)
        arm(w)
        w.set_motor_pwm_us([1530.0] * 4)
        w.step(300)
        w.set_motor_pwm_us(widths)
        w.step(150)
        return w.truth().gyro_rad_s

    base, up = 1530.0, 1580.0
    p, q, r = rates_after([base, up, up, base])  # left motors up: roll right
    assert p > 0.1 and abs(q) < 0.02
    p, q, r = rates_after([up, base, up, base])  # front motors up: pitch up
    assert q > 0.1 and abs(p) < 0.02
    p, q, r = rates_after([up, up, base, base])  # CCW motors up: yaw right
    assert r > 0.02 and abs(p) < 0.02 and abs(q) < 0.02


def test_motors_off_in_air_falls_then_rests():
    w = World(agl_m=2.0)
    alt0 = w.truth().alt_m
    w.step(300)
    tr = w.truth()
    assert tr.vel_ned_m_s[2] > 2.0  # falling (down is positive)
    assert norm(tr.accel_body_m_s2) < 1.0  # free fall: the accelerometer reads ~0
    w.step(2700)
    tr = w.truth()
    assert abs(tr.vel_ned_m_s[2]) < 0.02
    assert 0.10 < tr.agl_m < 0.16 and abs(alt0 - tr.alt_m - 2.0) < 0.05
    assert abs(norm(tr.accel_body_m_s2) - G0_M_S2) < 0.05


def test_signal_loss_in_flight_stops_motors():
    w = World(agl_m=30.0)
    arm(w)
    w.set_motor_pwm_us([1530.0] * 4)
    w.step(500)
    t_loss = w.t_ns
    for ch in range(4):
        w.set_pwm(ch, t_loss, 0, 2_500_000)  # dead IO: line low
    w.step(450)  # ESCs hold the last throttle until the 0.5 s timeout
    assert all(e.throttle > 0.4 for e in w.escs[:4])
    w.step(100)
    assert all(e.throttle == 0.0 and not e.armed for e in w.escs[:4])
    w.step(500)
    assert w.truth().vel_ned_m_s[2] > 2.0
    assert w.motor_rpm(0) < 3000.0


def test_battery_in_world():
    w = World(agl_m=30.0)
    v_rest = w.truth().battery_v
    arm(w)
    w.set_motor_pwm_us([1530.0] * 4)
    w.step(1000)
    tr = w.truth()
    assert 8.0 < tr.battery_a < 40.0  # F450 hover on 3S: ~10-25 A
    assert tr.battery_v < v_rest - 0.3
    assert w.battery.used_mah > 0.5 * tr.battery_a / 3.6


def test_determinism():
    def run():
        w = World(seed=7, agl_m=10.0)
        w.set_motor_pwm_us([1000.0] * 4)
        w.step(200)
        w.set_motor_pwm_us([1520.0, 1540.0, 1530.0, 1525.0])
        w.step(800)
        return w.truth(), w.rng.random()

    a, b = run(), run()
    assert a == b


# -- ESC ----------------------------------------------------------------------------------


def _esc(**kw):
    return Esc(MS, EscParams(**kw))


def _feed(esc, t0_ns, width_us, dur_s, period_ns=2_500_000):
    """Pulses of width_us from t0 on; update once per ms for dur_s; returns the next time."""
    esc.set_signal(t0_ns, round(width_us * 1000), period_ns)
    t = t0_ns
    for _ in range(round(dur_s * 1000)):
        esc.update(t)
        t += MS
    return t


def test_esc_throttle_mapping():
    esc = _esc(tau_s=0.0)
    t = _feed(esc, 0, 1000.0, 0.2)
    assert esc.armed and esc.throttle == 0.0
    t = _feed(esc, t, 2000.0, 0.01)
    assert esc.throttle == 1.0
    t = _feed(esc, t, 1500.0, 0.01)
    assert esc.throttle == pytest.approx(0.5)
    t = _feed(esc, t, 1050.0, 0.01)  # below the start threshold: motor does not turn
    assert esc.throttle == 0.0
    t = _feed(esc, t, 1100.0, 0.01)
    assert esc.throttle == pytest.approx(0.1)


def test_esc_lag_time_constant():
    tau = 0.03
    esc = _esc(tau_s=tau)
    t = _feed(esc, 0, 1000.0, 0.2)
    esc.set_signal(t, 2_000_000, 2_500_000)
    out = []
    for k in range(100):
        out.append(esc.update(t + k * MS))
    # update(t0) applies the step and advances one dt: out[k] is the output after (k+1) ms
    assert out[round(tau * 1000) - 1] == pytest.approx(1.0 - math.exp(-1.0), abs=1e-9)
    assert out[-1] > 0.95


def test_esc_requires_arming_at_low_throttle():
    esc = _esc(tau_s=0.0)
    t = _feed(esc, 0, 1500.0, 0.5)  # powered up with the stick up: no spin
    assert not esc.armed and esc.throttle == 0.0
    t = _feed(esc, t, 1000.0, 0.05)  # not long enough yet
    assert not esc.armed
    t = _feed(esc, t, 1000.0, 0.06)
    assert esc.armed
    _feed(esc, t, 1500.0, 0.01)
    assert esc.throttle == pytest.approx(0.5)


@pytest.mark.parametrize("loss", ["low", "high", "out_of_range"])
def test_esc_signal_loss_stops_motor(loss):
    esc = _esc(tau_s=0.0)
    t = _feed(esc, 0, 1000.0, 0.2)
    t = _feed(esc, t, 1600.0, 0.1)
    assert esc.throttle == pytest.approx(0.6)
    high_ns, period_ns = {
        "low": (0, 2_500_000),  # line held low (dead IO)
        "high": (2_500_000, 2_500_000),  # line held high
        "out_of_range": (2_400_000, 2_500_000),  # 2400 us pulses: rejected
    }[loss]
    esc.set_signal(t, high_ns, period_ns)
    for _ in range(490):  # keeps the last throttle for the timeout
        esc.update(t)
        t += MS
    assert esc.throttle == pytest.approx(0.6) and esc.armed
    for _ in range(20):
        esc.update(t)
        t += MS
    assert esc.throttle == 0.0 and not esc.armed
    t = _feed(esc, t, 1600.0, 0.2)  # signal back at flight throttle: stays stopped
    assert esc.throttle == 0.0 and not esc.armed


def test_esc_short_dropout_keeps_running():
    esc = _esc(tau_s=0.0)
    t = _feed(esc, 0, 1000.0, 0.2)
    t = _feed(esc, t, 1600.0, 0.1)
    esc.set_signal(t, 0, 2_500_000)
    for _ in range(300):
        esc.update(t)
        t += MS
    t = _feed(esc, t, 1700.0, 0.5)  # back within the timeout
    assert esc.armed and esc.throttle == pytest.approx(0.7)


def test_esc_input_stamped_ahead_applies_at_its_time():
    esc = _esc(tau_s=0.0, arm_low_s=0.0)
    esc.set_signal(0, 1_000_000, 2_500_000)
    esc.update(0)
    assert esc.armed
    esc.set_signal(5 * MS + 300_000, 1_500_000, 2_500_000)
    for k in range(6):
        esc.update(k * MS)
        assert esc.throttle == 0.0
    esc.update(6 * MS)
    assert esc.throttle == pytest.approx(0.5)


# -- battery ------------------------------------------------------------------------------


def test_battery_sag_recovery_and_capacity():
    p = BatteryParams(avionics_a=0.0)
    b = Battery(p, dt_s=0.001)
    v_full = b.voltage_v
    assert v_full == pytest.approx(12.6)
    for _ in range(10_000):  # 20 A for 10 s
        b.step(20.0)
    v_load = b.voltage_v
    assert v_load < v_full - 20.0 * p.r0_ohm - 0.1  # ohmic plus polarisation sag
    assert b.used_mah == pytest.approx(20.0 * 10.0 / 3.6, rel=1e-6)
    b.step(0.0)
    v_instant = b.voltage_v
    assert v_instant > v_load + 20.0 * p.r0_ohm * 0.99  # ohmic part comes back at once
    for _ in range(30_000):  # rest 30 s
        b.step(0.0)
    v_rested = b.voltage_v
    assert v_rested > v_instant + 0.05  # polarisation relaxes
    assert v_rested < v_full  # charge is gone
    assert b.soc == pytest.approx(1.0 - 55.5556 / 5000.0, rel=1e-4)


def test_eight_channels_accepted_extra_channels_drive_nothing():
    w = World(agl_m=5.0)
    w.set_motor_pwm_us([1000.0] * 8)
    w.step(150)
    w.set_motor_pwm_us([1000.0] * 4 + [2000.0] * 4)
    w.step(100)
    assert all(e.throttle == 0.0 for e in w.escs[:4])
    assert w.escs[7].pulse_us == 2000.0
    assert w.truth().vel_ned_m_s[2] > 0.5  # motors 1..4 off: falling
