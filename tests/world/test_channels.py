"""World channels (issue 23): servo inputs, AUX ports, and the truth record's new fields."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from hil.world import World
from hil.world.servo import ServoInput
from hil.worldlink import TRUTH_FIELDS, WorldPorts, truth_from_record, truth_record
from tests.fuzzing import fuzz

P = 20_000_000


def test_servo_maps_pulse_width_to_position_and_clamps() -> None:
    s = ServoInput()
    assert s.update(0) == 0.0 and not s.signal_valid  # centred before any pulse
    for t, us, want in ((1, 1500, 0.0), (2, 2000, 1.0), (3, 1000, -1.0), (4, 1750, 0.5),
                        (5, 2150, 1.0), (6, 850, -1.0)):
        s.set_signal(t, us * 1000, P)
        assert s.update(t) == pytest.approx(want)
        assert s.pulse_us == pytest.approx(us)


@pytest.mark.parametrize("high_ns, period_ns", [(0, P), (2_500_000, P), (500_000, P),
                                                (P, P), (1_500_000, 600_000_000)],
                         ids=["line-low", "too-wide", "too-narrow", "held-high", "too-slow"])
def test_servo_holds_last_position_on_a_bad_signal(high_ns, period_ns) -> None:
    s = ServoInput()
    s.set_signal(0, 1800_000, P)
    assert s.update(0) == pytest.approx(0.6)
    s.set_signal(10, high_ns, period_ns)
    assert s.update(10) == pytest.approx(0.6)
    assert not s.signal_valid and s.pulse_us == 0.0


def test_servo_applies_stamped_pulses_in_time_order() -> None:
    s = ServoInput()
    s.set_signal(200, 2000_000, P)
    s.set_signal(100, 1000_000, P)  # arrives late but stamped earlier
    assert s.update(150) == pytest.approx(-1.0)
    assert s.update(250) == pytest.approx(1.0)


def test_aux_ports_reach_world_channels_8_to_13() -> None:
    ports = WorldPorts(World(airframe="f450"))
    assert ports.ports[-6:] == tuple(f"aux{i}" for i in range(1, 7))
    ports.input("aux1", 0, (1200_000, P))
    ports.input("aux6", 0, (1900_000, P))
    w = ports.world
    assert w.escs[8].pulse_us == 1200.0 and w.escs[13].pulse_us == 1900.0
    assert w.escs[0].pulse_us == 0.0
    with pytest.raises(ValueError):
        ports.input("aux7", 0, (1500_000, P))


def test_truth_record_carries_aoa_and_sideslip_last() -> None:
    assert TRUTH_FIELDS[-2:] == ("aoa_rad", "sideslip_rad")
    w = World(airframe="plane", agl_m=30.0, airspeed_m_s=15.0, pitch_deg=5.0)
    t = w.truth()
    assert t.aoa_rad == pytest.approx(0.0873, abs=2e-3)  # level flight path: aoa = pitch
    assert t.sideslip_rad == pytest.approx(0.0, abs=1e-6)
    assert truth_from_record(truth_record(t)) == t


@fuzz(examples=300)
@given(st.lists(st.tuples(st.integers(-10**12, 10**12), st.integers(-10**9, 10**10),
                          st.integers(-10**9, 10**10)), max_size=30),
       st.integers(-10**12, 10**12))
def test_servo_input_takes_any_pulse_train(events, t_now) -> None:
    """Whatever the wire carries (the boards' timer outputs are outside input to the world):
    the command stays within the end stops and a valid train always sets it."""
    s = ServoInput()
    for t, high, period in events:
        s.set_signal(t, high, period)
    c = s.update(t_now)
    assert -1.0 <= c <= 1.0
    due = sorted((e for e in events if e[0] <= t_now), key=lambda e: e[0])
    if due and (len(due) == 1 or due[-2][0] < due[-1][0]):  # one last train, no tie
        t, high, period = due[-1]
        if 800_000 <= high < period <= 500_000_000 and high <= 2_200_000:
            assert s.signal_valid and s.pulse_us == pytest.approx(high * 1e-3)
