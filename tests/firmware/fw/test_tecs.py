"""TECS (firmware/lib/tecs.py) on a point-mass energy model of a small electric plane.

Model (2 kg, thrust 20 N at full throttle, drag 0.03 V^2 + 731 / V^2 N: 10 N at 15 m/s, so the
cruise throttle is 0.5): flight path angle gamma = pitch - alpha with the angle of attack for
level lift growing as (V_trim / V)^2, pitch following its setpoint with a 0.3 s lag (the
attitude loop). Energy balance: m dV/dt = T - D - m g sin(gamma), dh/dt = V sin(gamma).
"""

from __future__ import annotations

import math

import pytest

from firmware.lib.tecs import G, Tecs, TecsParams

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
        dv = self.accel_x - G * math.sin(gamma)
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
