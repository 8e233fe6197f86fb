"""The RateControl library alone (firmware/lib/rate_control.py): gains, integrator, anti-windup.

No board: the library takes vectors and returns a torque, as PX4's src/lib/rate_control does,
so each property is checked with hand-computed numbers.
"""

from __future__ import annotations

import math

import pytest

from firmware.lib.rate_control import RateControl
from firmware.lib.vector3 import Vector3

ZERO = Vector3()


def _controller(p: float = 0.1, i: float = 0.0, d: float = 0.0, ff: float = 0.0,
                lim: float = 0.3) -> RateControl:
    rc = RateControl()
    rc.set_pid_gains(Vector3(p, 2 * p, 3 * p), Vector3(i, i, i), Vector3(d, d, d))
    rc.set_feed_forward_gain(Vector3(ff, ff, ff))
    rc.set_integrator_limit(Vector3(lim, lim, lim))
    return rc


def test_each_gain_acts_on_its_own_term_per_axis() -> None:
    rc = _controller(p=0.1, d=0.01, ff=0.5)
    rate, sp, accel = Vector3(0.1, -0.2, 0.0), Vector3(0.3, 0.2, -0.5), Vector3(2.0, 0.0, -1.0)
    u = rc.update(rate, sp, accel, 0.0025, landed=True)
    # P on the error (per-axis gains 0.1, 0.2, 0.3), D on the measured acceleration, FF on sp
    assert u.x == pytest.approx(0.1 * 0.2 - 0.01 * 2.0 + 0.5 * 0.3)
    assert u.y == pytest.approx(0.2 * 0.4 + 0.5 * 0.2)
    assert u.z == pytest.approx(0.3 * -0.5 + 0.01 * 1.0 + 0.5 * -0.5)
    # a setpoint step gives no derivative kick: D sees the measurement only
    u2 = rc.update(rate, Vector3(3.0, 0.2, -0.5), accel, 0.0025, landed=True)
    assert u2.x - u.x == pytest.approx((0.1 + 0.5) * 2.7)


def test_integrator_accumulates_in_flight_is_limited_and_frozen_when_landed() -> None:
    rc = _controller(p=0.0, i=2.0, lim=0.3)
    err = Vector3(0.5, -0.5, 0.0)
    rc.update(ZERO, err, ZERO, 0.01, landed=True)
    assert rc.rate_int.xyz() == (0.0, 0.0, 0.0)
    rc.update(ZERO, err, ZERO, 0.01, landed=False)
    assert rc.rate_int.xyz() == pytest.approx((0.01, -0.01, 0.0))
    # the torque of a call uses the integrator as it was before the call (PX4's order)
    u = rc.update(ZERO, err, ZERO, 0.01, landed=False)
    assert u.x == pytest.approx(0.01)
    for _ in range(100):
        rc.update(ZERO, err, ZERO, 0.01, landed=False)
    assert rc.rate_int.xyz() == pytest.approx((0.3, -0.3, 0.0))


def test_anti_windup_stops_growth_only_in_the_saturated_direction() -> None:
    rc = _controller(p=0.0, i=1.0, lim=1.0)
    rc.set_saturation_status((True, False, False), (False, True, False))
    # roll: saturated positive, positive error -> frozen; pitch: saturated negative,
    # negative error -> frozen; yaw: not saturated -> integrates
    rc.update(ZERO, Vector3(0.5, -0.5, 0.5), ZERO, 0.1, landed=False)
    assert rc.rate_int.xyz() == pytest.approx((0.0, 0.0, 0.05))
    # errors that unwind the saturation still integrate
    rc.update(ZERO, Vector3(-0.5, 0.5, 0.0), ZERO, 0.1, landed=False)
    assert rc.rate_int.xyz() == pytest.approx((-0.05, 0.05, 0.05))


def test_reset_integral_and_status() -> None:
    rc = _controller(p=0.0, i=1.0)
    rc.update(ZERO, Vector3(0.2, 0.1, -0.1), ZERO, 0.1, landed=False)
    status = type("Status", (), {})()
    rc.get_rate_control_status(status)
    assert (status.rollspeed_integ, status.pitchspeed_integ, status.yawspeed_integ) == \
        pytest.approx((0.02, 0.01, -0.01))
    rc.reset_integral()
    assert rc.rate_int.xyz() == (0.0, 0.0, 0.0)
    assert rc.update(ZERO, ZERO, ZERO, 0.1, landed=False).xyz() == (0.0, 0.0, 0.0)


def test_a_non_finite_step_does_not_poison_the_integrator() -> None:
    rc = _controller(p=0.0, i=1.0)
    rc.update(ZERO, Vector3(0.1, 0.1, 0.1), ZERO, 0.1, landed=False)
    rc.update(ZERO, Vector3(math.nan, math.inf, 0.1), ZERO, 0.1, landed=False)
    assert rc.rate_int.xyz() == pytest.approx((0.01, 0.01, 0.02))


def test_vector3_operations_match_the_scalar_form_bit_for_bit() -> None:
    a, b, c = Vector3(0.1, 0.2, 0.3), Vector3(1e-3, 7.0, -2.5), Vector3(3.3, -1.1, 0.7)
    r = a.emult(b) + c - b * 0.37
    assert r.xyz() == (0.1 * 1e-3 + 3.3 - 1e-3 * 0.37, 0.2 * 7.0 + -1.1 - 7.0 * 0.37,
                       0.3 * -2.5 + 0.7 - -2.5 * 0.37)
    assert Vector3(-2.0, 0.5, 9.0).constrain(-1.0, 1.0).xyz() == (-1.0, 0.5, 1.0)
