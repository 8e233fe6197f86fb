"""The fixed-wing rate and attitude laws (firmware/modules/fw_att_control/ecl.py)."""

from __future__ import annotations

from common.units import G0_M_S2
import math

import pytest

from firmware.modules.fw_att_control.ecl import (
    RateLoop,
    coordinated_yaw_rate,
    euler_rates_to_body,
)


def test_rate_loop_scaling_ff_p_and_integrator_limit():
    rl = RateLoop()
    rl.set_gains(k_p=0.1, k_i=0.5, k_ff=0.4, i_max=0.05)
    # no error: only the feed-forward, scaled once by V_trim / V
    assert rl.control(0.5, 0.5, 2.0, 0.01, False) == pytest.approx(0.5 * 0.4 * 2.0)
    # an error: P scaled twice
    assert rl.control(0.5, 0.0, 2.0, 0.01, False) == pytest.approx(0.4 + 0.5 * 0.1 * 4.0)
    # the integrator grows with the error (scaled twice) and stops at its limit
    rl2 = RateLoop()
    rl2.set_gains(k_p=0.0, k_i=0.5, k_ff=0.0, i_max=0.05)
    rl2.control(0.2, 0.0, 1.0, 0.1, True)
    assert rl2.integrator == pytest.approx(0.2 * 0.1 * 0.5)
    for _ in range(100):
        rl2.control(0.2, 0.0, 1.0, 0.1, True)
    assert rl2.integrator == pytest.approx(0.05)
    rl2.reset()
    assert rl2.integrator == 0.0


def test_rate_loop_does_not_wind_up_into_saturation():
    rl = RateLoop()
    rl.set_gains(k_p=1.0, k_i=1.0, k_ff=0.0, i_max=0.5)
    assert rl.control(5.0, 0.0, 1.0, 0.01, True) == 1.0     # saturated positive
    i = rl.integrator
    rl.control(5.0, 0.0, 1.0, 0.01, True)
    assert rl.integrator == i                               # no further growth
    rl.control(-5.0, 0.0, 1.0, 0.01, True)
    assert rl.integrator < i                                # but it unwinds


def test_coordinated_turn_and_euler_to_body():
    roll = math.radians(30.0)
    r = coordinated_yaw_rate(roll, 0.0, 16.0)
    assert r == pytest.approx(G0_M_S2 * math.tan(roll) / 16.0)
    assert coordinated_yaw_rate(math.radians(89.0), 0.0, 16.0) == 0.0   # knife edge: none
    # level, wings level: Euler rates are body rates
    assert euler_rates_to_body(0.0, 0.0, 0.1, 0.2, 0.3) == pytest.approx((0.1, 0.2, 0.3))
    # banked 90 deg, a heading rate is a body pitch rate
    p, q, rr = euler_rates_to_body(math.pi / 2, 0.0, 0.0, 0.0, 0.3)
    assert (p, q, rr) == pytest.approx((0.0, 0.3, 0.0), abs=1e-12)
