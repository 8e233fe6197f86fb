"""Fuzz targets for what the companion computer sends the FMU's attitude loop: its rate
setpoint (``companion_rates_setpoint``) is outside input, any float32 at all. Whatever it
holds, ``mc_att_companion`` must neither crash nor pass on a rate setpoint outside the
envelope (tests/fuzzing.py)."""

from __future__ import annotations

import math

from hypothesis import given
from hypothesis import strategies as st

from firmware.modules.mc_att_companion.envelope import (RATE_TOLERANCE, rates_violation,
                                                        tilt_error_rad)
from tests.fuzzing import fuzz
from tests.modules.test_mc_att_companion import (  # noqa: F401 - the fixture
    LEVEL, Q_SP, Rig, board, fmu_law)

#: MC_ROLLRATE_MAX, MC_PITCHRATE_MAX, MC_YAWRATE_MAX at their defaults (rad/s)
LIMITS = (math.radians(220.0), math.radians(220.0), math.radians(200.0))
F32 = st.floats(width=32, allow_nan=True, allow_infinity=True)
#: mostly plausible values, sometimes anything a float32 can hold
VALUE = st.one_of(st.floats(-5.0, 5.0, width=32), F32)


def _inside(rates, thrust) -> bool:
    return (all(math.isfinite(v) for v in (*rates, *thrust))
            and all(abs(v) <= lim * RATE_TOLERANCE for v, lim in zip(rates, LIMITS))
            and -1.0 <= thrust[2] <= 0.0 and abs(thrust[0]) <= 1.0 and abs(thrust[1]) <= 1.0)


@fuzz(examples=500)
@given(st.tuples(VALUE, VALUE, VALUE), st.tuples(VALUE, VALUE, VALUE))
def test_the_envelope_accepts_exactly_the_setpoints_inside_it(rates, thrust):
    why = rates_violation(rates, thrust, LIMITS)
    assert (why is None) == _inside(rates, thrust), (rates, thrust, why)
    assert why is None or why.strip()


@fuzz(examples=200)
@given(st.tuples(F32, F32, F32, F32))
def test_tilt_error_of_any_attitude_is_an_angle_or_nan(q):
    """An attitude message is the FMU's own, but the check must not raise on a broken one."""
    e = tilt_error_rad(q, Q_SP)
    assert math.isnan(e) or 0.0 <= e <= math.pi


@fuzz(examples=30)
@given(st.lists(st.tuples(VALUE, VALUE, VALUE, VALUE), min_size=1, max_size=4))
def test_whatever_the_companion_sends_the_rate_controller_gets_a_safe_setpoint(board, msgs):
    """In flight, the companion sends good setpoints, then ``msgs`` (one per attitude period):
    every rate setpoint the module publishes is finite, within the limits, thrust 0..1."""
    board.ctl_shell("mc_att_companion stop")
    board.standin.q = LEVEL
    r = Rig(board, board.standin)
    r.state(armed=False, landed=True)
    r.step(6)                           # the last example's companion is stale
    assert board.ctl_shell("mc_att_companion start")[0] == 0
    fmu_law(r)
    r.step(3, cmp=(0.3, -0.2, 0.1, -0.55))
    for m in msgs:
        r.step(1, cmp=m)
    assert r.rows
    for _t, rates, thrust_z in r.rows:
        assert _inside(rates, (0.0, 0.0, thrust_z)), (rates, thrust_z, msgs)
