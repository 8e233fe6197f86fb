"""The fixed-wing world (issue 23): the StickPlane trims, flies straight and level on fixed
commands, answers each surface with the contract's sign, and loses lift past its stall.

In-process World only, short virtual times (~1 s of CPU for the file).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.world import EscParams, World
from hil.world.fdm import AIRFRAMES, FT, Fdm, Motor, Servo
from hil.world.trim import TrimPoint, trim_climb, trim_level
from hil.world.world import PX4_HOME
from hil.worldlink import truth_record

CRUISE_M_S = 16.0
SERVO_PERIOD_NS = 20_000_000  # 50 Hz, PX4's PWM_RATE for servos
AIL, ELEV, THR, RUD = range(4)  # MAIN1..4, PX4's AETR order


@pytest.fixture(scope="module")
def trim() -> TrimPoint:
    return trim_level("plane", CRUISE_M_S)


def trimmed_world(trim: TrimPoint) -> World:
    """The plane at 50 m in straight and level flight on the trim commands (ESC armed at
    once so that the start is not a 0.1 s glide)."""
    w = World(airframe="plane", agl_m=50.0, airspeed_m_s=trim.airspeed_m_s,
              pitch_deg=trim.pitch_deg, esc_params=EscParams(arm_low_s=0.0))
    pwm = list(trim.pwm_us())
    low = pwm.copy()
    low[THR] = 1000.0
    w.set_motor_pwm_us(low, SERVO_PERIOD_NS)
    w.step(1)
    w.set_motor_pwm_us(pwm, SERVO_PERIOD_NS)
    return w


@pytest.fixture(scope="module")
def cruise(trim: TrimPoint) -> list:
    """Truth every 0.5 s over 20 s of flight on the fixed trim commands."""
    w = trimmed_world(trim)
    out = [w.truth()]
    for _ in range(40):
        w.step(500)
        out.append(w.truth())
    return out


def test_channel_map_is_aetr_and_f450_unchanged() -> None:
    plane = AIRFRAMES["plane"]
    assert [type(o) for o in plane.outputs[:4]] == [Servo, Servo, Motor, Servo]
    assert plane.outputs[AIL].prop == "fcs/aileron-cmd-norm"
    assert plane.outputs[ELEV].prop == "fcs/elevator-cmd-norm"
    assert plane.outputs[RUD].prop == "fcs/rudder-cmd-norm"
    assert plane.motor_channels == (THR,) and plane.servo_channels == (0, 1, 3)
    assert all(o is None for o in plane.outputs[4:]) and len(plane.outputs) == 14
    f450 = AIRFRAMES["f450"]
    assert f450.motor_channels == (0, 1, 2, 3) and f450.servo_channels == ()
    assert plane.stall_aoa_rad == pytest.approx(math.radians(12.0), abs=1e-3)
    assert plane.battery.cells == 4


def test_trim_is_a_plausible_cruise(trim: TrimPoint) -> None:
    assert trim.residual < 1e-3
    assert math.radians(2.0) < trim.aoa_rad < math.radians(6.0)
    assert 0.3 < trim.throttle < 0.8
    assert 0.05 < trim.elevator < 0.5  # nose-up elevator holds the nose against Cm0, Cma
    assert abs(trim.aileron) < 0.1 and abs(trim.rudder) < 0.1  # only the propeller's torque
    assert 3.0 < trim.battery_current_a < 10.0  # ~90 W at 16 m/s
    ail, elev, thr, rud = trim.pwm_us()
    assert ail == pytest.approx(1500 + 500 * trim.aileron)
    assert thr == pytest.approx(1000 + 1000 * trim.throttle)


def test_slower_trim_needs_more_angle_of_attack(trim: TrimPoint) -> None:
    slow = trim_level("plane", 12.0)
    assert slow.aoa_rad > trim.aoa_rad + math.radians(2.0)
    assert slow.aoa_rad < AIRFRAMES["plane"].stall_aoa_rad
    with pytest.raises(RuntimeError):
        trim_level("plane", 8.0)  # below the 1 g stall speed (10.3 m/s)
    with pytest.raises(ValueError):
        trim_level("f450", 10.0)


def test_full_throttle_climbs_and_idle_glides(trim: TrimPoint) -> None:
    climb = trim_climb("plane", CRUISE_M_S, esc_throttle=1.0)
    assert 4.0 < climb.climb_rate_m_s < 10.0  # 2.7 kg on ~23 N of static thrust
    assert climb.battery_current_a > 3 * trim.battery_current_a
    glide = trim_climb("plane", CRUISE_M_S, esc_throttle=0.0)
    assert -3.0 < glide.climb_rate_m_s < -1.0  # L/D ~ 7 with a windmilling propeller
    assert glide.pitch_deg < trim.pitch_deg


def test_flies_straight_and_level_for_20_s_on_fixed_commands(trim, cruise) -> None:
    h0 = cruise[0].alt_m
    for t in cruise:
        assert abs(t.alt_m - h0) < 1.5, (t.t_ns, t.alt_m - h0)
        assert abs(t.airspeed_m_s - CRUISE_M_S) < 0.5
        assert abs(t.euler_rad[0]) < math.radians(5.0)  # spin-up kick of the propeller ~2 deg
        assert abs(t.euler_rad[1] - trim.aoa_rad) < math.radians(1.5)
        assert abs(t.aoa_rad - trim.aoa_rad) < math.radians(0.5)
        assert abs(t.sideslip_rad) < math.radians(1.0)
    last = cruise[-1]
    assert last.t_ns >= 20_000_000_000
    assert last.pos_ned_m[0] > 0.9 * CRUISE_M_S * 20  # flew north (heading 0) all along
    assert last.diff_pressure_pa == pytest.approx(0.5 * 1.2 * CRUISE_M_S ** 2, rel=0.1)


@pytest.mark.parametrize("channel, axis", [(AIL, 0), (ELEV, 1), (RUD, 2)],
                         ids=["aileron-roll-right", "elevator-nose-up", "rudder-yaw-right"])
def test_positive_surface_gives_positive_px4_rate(trim, channel, axis) -> None:
    """+1 on a surface gives the positive PX4 moment (contract): a 0.3 s step of +0.3 of
    throw raises the body rate about its axis; -0.3 lowers it."""
    rates = {}
    for sign in (1, -1):
        w = trimmed_world(trim)
        w.step(500)
        before = w.truth().gyro_rad_s[axis]
        pwm = list(trim.pwm_us())
        pwm[channel] += sign * 150.0
        w.set_motor_pwm_us(pwm, SERVO_PERIOD_NS)
        w.step(300)
        rates[sign] = w.truth().gyro_rad_s[axis] - before
    assert rates[1] > 0.1 and rates[-1] < -0.1, rates


def test_servo_holds_its_position_when_the_pulses_stop(trim) -> None:
    w = trimmed_world(trim)
    pwm = list(trim.pwm_us())
    pwm[ELEV] = 1700.0
    w.set_motor_pwm_us(pwm, SERVO_PERIOD_NS)
    w.step(400)
    held = w.fdm["fcs/elevator-pos-norm"]
    assert held == pytest.approx(0.4, abs=1e-3)
    w.set_pwm(ELEV, w.t_ns, 0, SERVO_PERIOD_NS)  # line held low (a dead IO)
    w.step(500)
    assert w.fdm["fcs/elevator-pos-norm"] == pytest.approx(held, abs=1e-6)
    assert w.escs[ELEV].pulse_us == 0.0 and not w.escs[ELEV].signal_valid


def test_servo_is_rate_limited_like_a_hobby_servo(trim) -> None:
    w = trimmed_world(trim)
    w.step(200)
    pwm = list(trim.pwm_us())
    pwm[AIL] = 2000.0
    w.set_motor_pwm_us(pwm, SERVO_PERIOD_NS)
    start = w.fdm["fcs/aileron-pos-norm"]
    w.step(50)  # 150 deg/s over 25 deg of throw: 6 /s, so 0.3 in 50 ms at most
    moved = w.fdm["fcs/aileron-pos-norm"] - start
    assert 0.2 < moved <= 0.3 + 1e-6
    w.step(400)
    assert w.fdm["fcs/aileron-pos-norm"] == pytest.approx(1.0, abs=1e-3)


def _lift_coefficient(fdm: Fdm, alpha_rad: float) -> float:
    """Lift coefficient of the wing at this angle of attack (state frozen: JSBSim's
    integrators off, as in hil.world.trim)."""
    x = fdm.exec
    x["ic/vt-fps"] = CRUISE_M_S / FT
    x["ic/alpha-rad"] = alpha_rad
    x["ic/gamma-rad"] = 0.0
    x.run_ic()
    for k in ("rate/rotational", "rate/translational", "position/rotational",
              "position/translational"):
        x["simulation/integrator/" + k] = 0
    x.run()
    return x["aero/force/lift_alpha"] / (x["aero/qbar-psf"] * x["metrics/Sw-sqft"])


def test_lift_falls_past_the_stall_angle() -> None:
    af = AIRFRAMES["plane"]
    lat, lon, alt = PX4_HOME
    fdm = Fdm(af, 0.001, lat, lon, alt, 0.0, 50.0, airspeed_m_s=CRUISE_M_S)
    alphas = np.radians(np.arange(0.0, 20.5, 0.5))
    cl = np.array([_lift_coefficient(fdm, a) for a in alphas])
    peak = alphas[int(np.argmax(cl))]
    assert peak == pytest.approx(af.stall_aoa_rad, abs=math.radians(0.5))
    assert np.all(np.diff(cl[alphas <= math.radians(11.0)]) > 0)  # attached flow
    assert cl.max() == pytest.approx(0.95, abs=0.03)
    assert _lift_coefficient(fdm, math.radians(16.0)) < 0.6 * cl.max()
    assert _lift_coefficient(fdm, math.radians(0.0)) == pytest.approx(0.1086, abs=1e-3)


def test_takes_off_from_the_runway() -> None:
    """Tricycle gear: at full throttle the plane rolls, rotates on a little up elevator and
    climbs away within a 60 m ground roll."""
    w = World(airframe="plane")
    w.set_motor_pwm_us([1500.0, 1500.0, 1000.0, 1500.0], SERVO_PERIOD_NS)
    w.step(200)
    rest = w.truth()
    assert rest.agl_m == pytest.approx(AIRFRAMES["plane"].gear_height_m, abs=0.01)
    w.set_motor_pwm_us([1500.0, 1600.0, 2000.0, 1500.0], SERVO_PERIOD_NS)
    airborne_at = None
    for _ in range(60):
        w.step(100)
        t = w.truth()
        if airborne_at is None and t.agl_m > rest.agl_m + 0.5:
            airborne_at = t.pos_ned_m[0]
    assert airborne_at is not None and 10.0 < airborne_at < 60.0
    assert w.truth().agl_m > 2.0 and w.truth().vel_ned_m_s[2] < -1.0  # climbing


def test_same_inputs_give_identical_truth(trim) -> None:
    def run() -> list:
        w = trimmed_world(trim)
        w.set_turbulence(3.0, 3)  # JSBSim's Dryden turbulence, seeded from the world's seed
        out = []
        for _ in range(5):
            w.step(200)
            out.append(truth_record(w.truth()))
        return out

    assert run() == run()


@pytest.mark.parametrize("rudder_us, sign", [(2000.0, 1), (1000.0, -1)])
def test_rudder_steers_the_nose_wheel(rudder_us, sign) -> None:
    """On the runway, +rudder turns right (yaw rate positive), as in the air."""
    w = World(airframe="plane")
    w.set_motor_pwm_us([1500.0, 1500.0, 1000.0, 1500.0], SERVO_PERIOD_NS)
    w.step(200)
    w.set_motor_pwm_us([1500.0, 1500.0, 1400.0, rudder_us], SERVO_PERIOD_NS)
    w.step(1000)
    assert sign * w.truth().gyro_rad_s[2] > 0.5
    assert w.truth().agl_m == pytest.approx(AIRFRAMES["plane"].gear_height_m, abs=0.02)
