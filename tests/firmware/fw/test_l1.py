"""L1 guidance (firmware/lib/l1.py) on a kinematic plane: constant speed, roll with a lag, a
coordinated turn (turn rate g tan(roll) / V). Converges onto lines and circles from far off,
the right way round; the switch distance and the roll limit are what the navigator and the
attitude controller rely on."""

from __future__ import annotations

import math

import pytest

from firmware.lib.l1 import L1Control, wrap_pi
from common.units import G0_M_S2


class KinematicPlane:
    """Point in the north-east plane at constant ground speed; roll follows its setpoint with
    a first-order lag (the attitude loop), heading follows the coordinated-turn rate."""

    def __init__(self, n: float, e: float, psi: float, v: float = 15.0) -> None:
        self.n, self.e, self.psi, self.v, self.roll = n, e, psi, v, 0.0

    @property
    def vel(self) -> tuple[float, float]:
        return self.v * math.cos(self.psi), self.v * math.sin(self.psi)

    def step(self, roll_sp: float, dt: float, wind_ne: tuple[float, float] = (0.0, 0.0)
             ) -> None:
        self.roll += (roll_sp - self.roll) * dt / 0.4
        self.psi = wrap_pi(self.psi + G0_M_S2 * math.tan(self.roll) / self.v * dt)
        vn, ve = self.vel
        self.n += (vn + wind_ne[0]) * dt
        self.e += (ve + wind_ne[1]) * dt


def _fly_line(l1: L1Control, plane: KinematicPlane, a, b, seconds: float, dt: float = 0.02,
              wind=(0.0, 0.0)) -> list[float]:
    xt = []
    for _ in range(round(seconds / dt)):
        vn, ve = plane.vel
        l1.navigate_waypoints(a, b, (plane.n, plane.e), (vn + wind[0], ve + wind[1]), plane.psi)
        plane.step(l1.nav_roll(), dt, wind)
        xt.append(l1.crosstrack_error_m)
    return xt


def test_converges_onto_a_line_from_far_off():
    l1 = L1Control()
    l1.set_period(20.0)
    l1.set_damping(0.75)
    # 150 m west of a line running north, flying east (across it)
    plane = KinematicPlane(0.0, -150.0, math.radians(90.0))
    xt = _fly_line(l1, plane, (0.0, 0.0), (5000.0, 0.0), 90.0)
    assert abs(xt[-1]) < 0.5, xt[-1]
    # settles without large overshoot: never more than 30 m on the far side of the line
    assert min(xt) > -30.0
    assert abs(wrap_pi(plane.psi)) < math.radians(3.0)


def test_tracks_a_line_in_crosswind():
    l1 = L1Control()
    plane = KinematicPlane(0.0, 40.0, 0.0)
    xt = _fly_line(l1, plane, (0.0, 0.0), (8000.0, 0.0), 120.0, wind=(0.0, 4.0))
    # a steady crosswind leaves no steady error: the ground velocity is tracked, not the nose
    assert max(abs(x) for x in xt[-500:]) < 1.0


def test_shorter_period_converges_faster():
    def time_to_5m(period: float) -> float:
        l1 = L1Control()
        l1.set_period(period)
        plane = KinematicPlane(0.0, -100.0, 0.0)
        xt = _fly_line(l1, plane, (0.0, 0.0), (9000.0, 0.0), 80.0)
        return next(i for i, x in enumerate(xt) if abs(x) < 5.0) * 0.02

    assert time_to_5m(12.0) < time_to_5m(25.0)


def test_heads_for_b_once_past_it_and_switch_distance():
    l1 = L1Control()
    plane = KinematicPlane(200.0, 0.0, 0.0)        # 100 m beyond B, flying away from it
    l1.navigate_waypoints((0.0, 0.0), (100.0, 0.0), (plane.n, plane.e), plane.vel, plane.psi)
    assert abs(wrap_pi(l1.nav_bearing_rad - math.pi)) < 1e-6   # back south to B
    # turning as hard as L1 asks at all (eta limited to 90 deg): K V^2 / L1
    a_max = 4.0 * 0.75 ** 2 * 15.0 ** 2 / l1.l1_distance_m
    assert abs(l1.lateral_accel_m_s2) == pytest.approx(a_max)
    # the L1 distance at 15 m/s is damping * period / pi * V = 71.6 m
    assert l1.l1_distance_m == pytest.approx(0.75 * 20.0 / math.pi * 15.0)
    assert l1.switch_distance(200.0) == pytest.approx(l1.l1_distance_m)
    assert l1.switch_distance(10.0) == 10.0


@pytest.mark.parametrize("direction", [1, -1])
@pytest.mark.parametrize("start", [(-400.0, 0.0, 0.0), (10.0, 5.0, 2.0)])
def test_converges_onto_a_circle_the_right_way_round(direction, start):
    l1 = L1Control()
    l1.set_period(15.0)
    radius = 80.0
    plane = KinematicPlane(*start)
    dt = 0.02
    radii, turn = [], []
    for _ in range(round(150.0 / dt)):
        l1.navigate_loiter((0.0, 0.0), (plane.n, plane.e), radius, direction, plane.vel,
                           plane.psi)
        plane.step(l1.nav_roll(), dt)
        radii.append(math.hypot(plane.n, plane.e))
        turn.append(plane.roll)
    tail = radii[-1500:]
    assert max(abs(r - radius) for r in tail) < 2.0, (min(tail), max(tail))
    # steady bank of the circle, on the side of the loiter direction
    expect = math.atan(plane.v ** 2 / radius / G0_M_S2)
    assert turn[-1] * direction == pytest.approx(expect, abs=math.radians(3.0))
    assert l1.circle_mode


def test_roll_limit_and_heading_and_level():
    l1 = L1Control()
    l1.set_roll_limit(math.radians(30.0))
    l1.navigate_heading(math.radians(90.0), 0.0, (15.0, 0.0))
    assert l1.nav_roll() == pytest.approx(math.radians(30.0))   # right turn, limited
    l1.navigate_heading(math.radians(-5.0), 0.0, (15.0, 0.0))
    assert -math.radians(30.0) < l1.nav_roll() < 0.0
    l1.navigate_level_flight(1.0)
    assert l1.nav_roll() == 0.0 and l1.nav_bearing_rad == pytest.approx(1.0)
    # standing still on the runway: guidance from the heading, no division by zero
    l1.navigate_waypoints((0.0, 0.0), (100.0, 0.0), (0.0, 0.0), (0.0, 0.0), 0.3)
    assert math.isfinite(l1.lateral_accel_m_s2) and l1.nav_roll() < 0.0
