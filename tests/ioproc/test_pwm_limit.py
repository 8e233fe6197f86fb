"""PWM limit state machine, E14 timing (INIT 500 ms, RAMP 2.5 s)."""

from __future__ import annotations

import pytest

from ioproc.protocol import Era
from ioproc.pwm_limit import TIMING, LimitState, PwmLimit

DISARMED = [900, 0, 900, 1200]
MIN = [1000, 1000, 1075, 1000]
MAX = [2000, 2000, 1950, 2000]


def calc(limit: PwmLimit, armed: bool, t_us: int, outputs=(-1.0, -1.0, -1.0, -1.0), **kw):
    return limit.calc(armed, t_us, DISARMED, MIN, MAX, list(outputs), **kw)


def armed_limit(t0: int = 1_000_000) -> PwmLimit:
    """A limit that has passed INIT and entered RAMP at ``t0``."""
    limit = PwmLimit()
    calc(limit, True, t0 - 600_000)
    calc(limit, True, t0 - 100_000)  # INIT -> OFF
    assert limit.state is LimitState.OFF
    calc(limit, True, t0)  # OFF -> RAMP
    assert limit.state is LimitState.RAMP and limit.time_armed_us == t0
    return limit


def test_e14_timing() -> None:
    assert TIMING[Era.E14].init_time_us == 500_000
    assert TIMING[Era.E14].ramp_time_us == 2_500_000


def test_init_holds_disarmed_for_500ms() -> None:
    limit = PwmLimit()
    assert calc(limit, False, 10) == DISARMED and limit.state is LimitState.INIT
    assert calc(limit, True, 100_000, (1, 1, 1, 1)) == DISARMED
    assert calc(limit, True, 599_999, (1, 1, 1, 1)) == DISARMED
    assert limit.state is LimitState.INIT
    assert calc(limit, True, 600_000, (1, 1, 1, 1)) == DISARMED
    assert limit.state is LimitState.OFF
    calc(limit, True, 600_001, (1, 1, 1, 1))
    assert limit.state is LimitState.RAMP


def test_ramp_is_linear_from_disarmed_to_min() -> None:
    t0 = 1_000_000
    limit = armed_limit(t0)
    for frac in (0.0, 0.25, 0.5, 0.75):
        out = calc(limit, True, t0 + int(2_500_000 * frac))
        progress = int(frac * 10000)
        assert out[0] == 900 + 100 * progress // 10000
        assert out[1] == 1000  # no disarmed value: ramp starts at min
        assert out[2] == 900 + 175 * progress // 10000
        assert out[3] == 1000  # disarmed above min: d = min(disarmed, min)
    assert limit.state is LimitState.RAMP
    assert calc(limit, True, t0 + 2_500_000) == MIN
    assert limit.state is LimitState.ON


def test_ramp_full_output_reaches_max() -> None:
    limit = armed_limit()
    assert calc(limit, True, 1_000_001, (1, 1, 1, 1)) == MAX


def test_on_mapping_and_clamping() -> None:
    limit = armed_limit(0 + 1_000_000)
    calc(limit, True, 3_500_000)
    assert limit.state is LimitState.ON
    assert calc(limit, True, 3_600_000, (0.0, 0.5, 0.0, 2.0)) == [1500, 1750, 1512, 2000]
    assert calc(limit, True, 3_600_000, (-3.0, float("nan"), -0.999, 0.0)) == [1000, 1000,
                                                                              1075, 1500]


def test_reverse_mask() -> None:
    limit = armed_limit()
    calc(limit, True, 5_000_000)
    assert calc(limit, True, 5_000_001, (0.5, 0.5, 0.5, 0.5), reverse_mask=0b0010) == [
        1750, 1250, 1730, 1750]  # 0.5 * 875 / 2 + 3025 // 2 = 1730.75 -> 1730


def test_disarm_returns_to_off_and_rearm_ramps_again() -> None:
    limit = armed_limit()
    calc(limit, True, 4_000_000)
    assert limit.state is LimitState.ON
    assert calc(limit, False, 4_100_000, (1, 1, 1, 1)) == DISARMED
    assert limit.state is LimitState.OFF
    calc(limit, True, 5_000_000)
    assert limit.state is LimitState.RAMP and limit.time_armed_us == 5_000_000
    calc(limit, False, 5_100_000)
    assert limit.state is LimitState.OFF


@pytest.mark.parametrize("t_us", [0, 1, 1_250_000])
def test_outputs_always_within_bounds_when_armed(t_us: int) -> None:
    limit = armed_limit(2_000_000)
    for out in (-1.0, -0.3, 0.0, 0.7, 1.0):
        pwm = calc(limit, True, 2_000_000 + t_us, (out,) * 4)
        assert all(lo <= p <= hi for p, lo, hi in zip(pwm, [900, 1000, 900, 1000], MAX))
