"""TECS (firmware/lib/tecs.py) on a point-mass energy model of a small electric plane.

Model (2 kg, thrust 20 N at full throttle, drag 0.03 V^2 + 731 / V^2 N: 10 N at 15 m/s, so the
cruise throttle is 0.5): flight path angle gamma = pitch - alpha with the angle of attack for
level lift growing as (V_trim / V)^2, pitch following its setpoint with a 0.3 s lag (the
attitude loop). Energy balance: m dV/dt = T - D - m g sin(gamma), dh/dt = V sin(gamma).
"""

from __future__ import annotations

import math

import pytest

from firmware.lib.tecs import TAS_GATE_TIMEOUT_S, Tecs, TecsParams
from common.units import G0_M_S2

MASS_KG = 2.0
THRUST_MAX_N = 20.0


class PointMass:
    def __init__(self, h: float = 0.0, v: float = 15.0) -> None:
        self.h, self.v, self.pitch, self.vz_up = h, v, self.alpha(v), 0.0
        self.accel_x = 0.0

    @staticmethod
    def alpha(v: float) -> float:
        return math.radians(4.0) * (15.0 / max(v, 5.0)) ** 2

    def step(self, throttle: float, pitch_sp: float, dt: float) -> None:
        self.pitch += (pitch_sp - self.pitch) * dt / 0.3
        gamma = self.pitch - self.alpha(self.v)
        drag = 0.03 * self.v ** 2 + 731.0 / max(self.v, 5.0) ** 2
        self.accel_x = (THRUST_MAX_N * throttle - drag) / MASS_KG
        dv = self.accel_x - G0_M_S2 * math.sin(gamma)
        self.v = max(self.v + dv * dt, 1.0)
        self.vz_up = self.v * math.sin(gamma)
        self.h += self.vz_up * dt


def _fly(tecs: Tecs, pm: PointMass, seconds: float, h_sp: float, v_sp: float, dt: float = 0.02,
         airspeed_valid: bool = True, log: list | None = None, climbout: bool = False,
         thr_max: float = 1.0) -> None:
    for _ in range(round(seconds / dt)):
        tecs.update(dt, altitude_m=pm.h, height_rate_m_s=pm.vz_up, tas_m_s=pm.v,
                    airspeed_valid=airspeed_valid, accel_x_m_s2=pm.accel_x, pitch_rad=pm.pitch,
                    roll_rad=0.0, hgt_sp_m=h_sp, tas_sp_m_s=v_sp, throttle_min=0.0,
                    throttle_max=thr_max, throttle_cruise=0.5,
                    pitch_min_rad=math.radians(-30),
                    pitch_max_rad=math.radians(30), climbout=climbout,
                    climbout_pitch_min_rad=math.radians(10.0))
        pm.step(tecs.throttle_sp, tecs.pitch_sp, dt)
        if log is not None:
            log.append((pm.h, pm.v, tecs.throttle_sp, tecs.pitch_sp))


def test_climbs_to_and_holds_altitude_and_airspeed():
    tecs, pm = Tecs(), PointMass()
    log: list = []
    _fly(tecs, pm, 80.0, 50.0, 15.0, log=log)
    hs = [r[0] for r in log]
    vs = [r[1] for r in log]
    # the climb is flown at about the climb limit (5 m/s) and never overshoots much
    t_45 = next(i for i, h in enumerate(hs) if h > 45.0) * 0.02
    assert 8.0 < t_45 < 20.0, t_45
    assert max(hs) < 53.0
    assert abs(hs[-1] - 50.0) < 0.5 and abs(vs[-1] - 15.0) < 0.3
    assert min(vs) > 12.0                       # never near the minimum airspeed
    assert log[-1][2] == pytest.approx(0.5, abs=0.05)   # cruise throttle in level flight


def test_speed_change_keeps_altitude_and_descent_is_limited():
    tecs, pm = Tecs(), PointMass(h=50.0)
    _fly(tecs, pm, 10.0, 50.0, 15.0)
    log: list = []
    _fly(tecs, pm, 40.0, 50.0, 19.0, log=log)
    assert abs(pm.v - 19.0) < 0.3
    assert max(abs(r[0] - 50.0) for r in log) < 3.0
    log = []
    _fly(tecs, pm, 60.0, 0.0, 15.0, log=log)
    rates = [(b[0] - a[0]) / 0.02 for a, b in zip(log, log[1:])]
    assert min(rates) > -(TecsParams().sink_max_m_s + 1.0)
    assert abs(pm.h) < 1.0


def test_airspeed_less_mode_holds_altitude_on_trim_throttle():
    tecs, pm = Tecs(), PointMass(h=30.0)
    log: list = []
    # the sensor says nonsense: the airspeed must not be used at all
    pm_v_before = pm.v
    _fly(tecs, pm, 60.0, 40.0, 15.0, airspeed_valid=False, log=log)
    assert tecs.status.airspeed_valid is False
    assert tecs.status.tas_filtered_m_s == TecsParams().airspeed_trim_m_s
    assert abs(pm.h - 40.0) < 1.0
    assert 11.0 < pm.v < 19.0, (pm_v_before, pm.v)


def test_underspeed_gives_full_throttle_and_trades_height_for_speed():
    tecs, pm = Tecs(), PointMass(h=100.0, v=15.0)
    _fly(tecs, pm, 5.0, 100.0, 15.0)
    # a stall approach TECS watches but does not fly: pitch up on little throttle
    for _ in range(200):
        _fly(tecs, pm, 0.0, 100.0, 15.0)
        tecs.update(0.02, altitude_m=pm.h, height_rate_m_s=pm.vz_up, tas_m_s=pm.v,
                    airspeed_valid=True, accel_x_m_s2=pm.accel_x, pitch_rad=pm.pitch,
                    roll_rad=0.0, hgt_sp_m=100.0, tas_sp_m_s=15.0, throttle_min=0.0,
                    throttle_max=1.0, throttle_cruise=0.5, pitch_min_rad=-0.5,
                    pitch_max_rad=0.5)
        pm.step(0.2, math.radians(25.0), 0.02)
    assert pm.v < 8.5
    tecs.last_throttle = 1.0            # as if TECS had been at full throttle
    log: list = []
    _fly(tecs, pm, 0.04, 100.0, 15.0, log=log)
    assert tecs.underspeed and tecs.throttle_sp == 1.0
    _fly(tecs, pm, 10.0, 100.0, 15.0, log=log)
    assert not tecs.underspeed and pm.v > 12.0


def test_climbout_flies_minimum_airspeed_full_throttle_and_minimum_pitch():
    tecs, pm = Tecs(), PointMass(h=0.0, v=12.0)
    log: list = []
    # FW_THR_MAX 0.7: at full power this model climbs faster than 30 deg of pitch allows
    _fly(tecs, pm, 40.0, 300.0, 15.0, log=log, climbout=True, thr_max=0.7)
    assert all(r[2] == 0.7 for r in log)
    assert all(r[3] >= math.radians(10.0) - 1e-9 for r in log[100:])
    assert abs(pm.v - TecsParams().airspeed_min_m_s) < 1.0
    assert pm.vz_up > 2.0


def test_reset_clears_integrators():
    tecs, pm = Tecs(), PointMass()
    _fly(tecs, pm, 20.0, 30.0, 15.0)
    assert tecs.initialised
    tecs.reset()
    assert not tecs.initialised and tecs.throttle_integ == 0.0 and tecs.pitch_integ == 0.0


def test_airspeed_setpoint_and_limits_are_equivalent_airspeeds():
    """At altitude the same indicated (equivalent) airspeed is a higher true airspeed: TECS
    flies the setpoint times eas2tas in true airspeed."""
    tecs, pm = Tecs(), PointMass(h=50.0)
    for _ in range(round(40.0 / 0.02)):
        tecs.update(0.02, altitude_m=pm.h, height_rate_m_s=pm.vz_up, tas_m_s=pm.v,
                    airspeed_valid=True, accel_x_m_s2=pm.accel_x, pitch_rad=pm.pitch,
                    roll_rad=0.0, hgt_sp_m=50.0, tas_sp_m_s=15.0, throttle_min=0.0,
                    throttle_max=1.0, throttle_cruise=0.5, pitch_min_rad=-0.5,
                    pitch_max_rad=0.5, eas2tas=1.1)
        pm.step(tecs.throttle_sp, tecs.pitch_sp, 0.02)
    assert pm.v == pytest.approx(16.5, abs=0.3)
    assert tecs.status.tas_sp_m_s == pytest.approx(16.5)


def _step(tecs: Tecs, pm: PointMass, tas: float, valid: bool, h_sp: float = 100.0,
          dt: float = 0.02) -> None:
    """One TECS step fed ``tas`` as the measured airspeed (a sensor fault), then the model."""
    tecs.update(dt, altitude_m=pm.h, height_rate_m_s=pm.vz_up, tas_m_s=tas,
                airspeed_valid=valid, accel_x_m_s2=pm.accel_x, pitch_rad=pm.pitch,
                roll_rad=0.0, hgt_sp_m=h_sp, tas_sp_m_s=15.0, throttle_min=0.0,
                throttle_max=1.0, throttle_cruise=0.5, pitch_min_rad=math.radians(-45),
                pitch_max_rad=math.radians(30), climbout_pitch_min_rad=0.0)
    pm.step(tecs.throttle_sp, tecs.pitch_sp, dt)


def test_blocked_pitot_still_valid_is_not_flown_into_an_underspeed_dive():
    """The fw_airspeed_blocked_cruise failure: the pitot reads 0 (through the sensor's filter,
    ~0.4 s) while still declared valid for ASPD_FS_T_STOP. Before the gate TECS saw an
    underspeed and dived at the pitch limit; now it rejects samples the airframe's
    acceleration cannot explain and holds its height until the validator fails the sensor."""
    tecs, pm = Tecs(), PointMass(h=100.0, v=15.0)
    _fly(tecs, pm, 20.0, 100.0, 15.0)
    pitches, gated = [], []
    for i in range(100):                      # 2 s "valid", the reading falls to 0 in 0.4 s
        _step(tecs, pm, max(15.0 * (1.0 - i / 20.0), 0.0), True)
        pitches.append(tecs.pitch_sp)
        gated.append(tecs.status.airspeed_gated)
        assert not tecs.underspeed
    assert any(gated) and gated[-1] and tecs.gated_samples == sum(gated)
    assert min(pitches) > math.radians(-5.0)
    assert abs(pm.h - 100.0) < 2.0 and pm.v > 13.0
    for _ in range(50):                       # the validator: invalid
        _step(tecs, pm, 0.0, False)
    assert not tecs.status.airspeed_gated and tecs.status.airspeed_valid is False


def test_airspeed_less_flight_does_not_wind_up_after_a_false_airspeed():
    """A throttle integrator wound negative against a false airspeed reading held the throttle
    below cruise after the switch; the pitch integrator then walked the nose up to the stall
    (the old fw_airspeed_blocked_cruise, ~20 s after). Without airspeed the integrator is
    frozen and a negative one dropped: minutes of airspeed-less flight hold height and speed."""
    tecs, pm = Tecs(), PointMass(h=100.0, v=15.0)
    _fly(tecs, pm, 20.0, 100.0, 15.0)
    tecs.throttle_integ = -0.4                 # wound up while the reading was too high
    _step(tecs, pm, pm.v, True)
    heights, speeds, integ = [], [], []
    for _ in range(round(300.0 / 0.02)):
        _step(tecs, pm, math.nan, False, h_sp=102.0)
        heights.append(pm.h)
        speeds.append(pm.v)
        integ.append(tecs.pitch_integ)
    assert tecs.throttle_integ == 0.0
    assert all(abs(h - 102.0) < 1.0 for h in heights[-10000:])   # the last 200 s
    assert min(speeds) > 12.0 and max(speeds) < 19.0
    # bounded and settled: the last 200 s move the pitch integrator by less than 2 %
    late = integ[-10000:]
    assert max(late) - min(late) < 0.02 * max(abs(x) for x in late) + 1.0


def test_pitch_integrator_alone_never_exceeds_the_pitch_limits():
    """An integrator carried from another speed or phase (its SEB units scale with the
    airspeed) is cut to what the pitch limits allow at the next step, not unwound slowly."""
    tecs = Tecs()
    kw = dict(altitude_m=100.0, height_rate_m_s=0.0, tas_m_s=15.0, airspeed_valid=False,
              accel_x_m_s2=0.0, pitch_rad=0.0, roll_rad=0.0, hgt_sp_m=100.0, tas_sp_m_s=15.0,
              throttle_min=0.0, throttle_max=1.0, throttle_cruise=0.5, pitch_min_rad=-0.3,
              pitch_max_rad=0.3)
    tecs.update(0.02, **kw)
    gain_inv = TecsParams().airspeed_trim_m_s * TecsParams().time_const_s * G0_M_S2
    tecs.pitch_integ = 10.0 * gain_inv          # ten radians' worth
    tecs.update(0.02, **kw)
    assert tecs.pitch_integ <= 0.3 * gain_inv + 1e-6
    tecs.pitch_integ = -10.0 * gain_inv
    tecs.update(0.02, **kw)
    assert tecs.pitch_integ >= -0.3 * gain_inv - 1e-6


def test_a_lasting_airspeed_difference_is_believed_after_the_gate_timeout():
    """The gate only bridges the validator's delay: a difference that lasts (a real step the
    acceleration missed) is taken after TAS_GATE_TIMEOUT_S, not ignored for ever."""
    tecs, pm = Tecs(), PointMass(h=100.0, v=15.0)
    _fly(tecs, pm, 10.0, 100.0, 15.0)
    flags = []
    for _ in range(round((TAS_GATE_TIMEOUT_S + 1.0) / 0.02)):
        _step(tecs, pm, pm.v + 8.0, True)
        flags.append(tecs.status.airspeed_gated)
    n_gated = round(TAS_GATE_TIMEOUT_S / 0.02)
    assert all(flags[:n_gated - 1]) and not any(flags[n_gated + 2:])
    assert abs(tecs.tas_state - (pm.v + 8.0)) < 1.0
