"""rc_update's manual-control selector: PX4's COM_RC_IN_MODE rules, input by input."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from firmware.modules.rc_update.selector import ManualControlSelector

RC, JOY, JOY2 = 1, 3, 4


def _input(source: int, t_us: int, valid: bool = True) -> SimpleNamespace:
    return SimpleNamespace(data_source=source, timestamp_sample=t_us, valid=valid)


def _selector(mode: int) -> ManualControlSelector:
    s = ManualControlSelector()
    s.rc_in_mode, s.timeout_us = mode, 500_000
    return s


@pytest.mark.parametrize(("mode", "rc", "joy"), [(0, True, False), (1, False, True),
                                                 (2, True, True), (4, False, False)])
def test_which_sources_each_mode_takes(mode: int, rc: bool, joy: bool) -> None:
    assert _selector(mode).offer(_input(RC, 0), 0) is rc
    assert _selector(mode).offer(_input(JOY, 0), 0) is joy


def test_mode_2_keeps_the_chosen_input_and_falls_back_when_it_times_out() -> None:
    s = _selector(2)
    assert s.offer(_input(RC, 0), 0)
    assert not s.offer(_input(JOY, 100_000), 100_000)   # RC still valid: kept
    assert s.offer(_input(RC, 200_000), 200_000)
    assert s.offer(_input(JOY, 700_001), 700_001)       # RC silent for the timeout: joystick
    assert not s.offer(_input(RC, 800_000), 800_000)    # and the joystick is kept


def test_mode_3_keeps_the_first_source_ever() -> None:
    s = _selector(3)
    assert s.offer(_input(JOY, 0), 0)
    assert not s.offer(_input(RC, 2_000_000), 2_000_000)  # joystick gone, RC still refused
    assert s.offer(_input(JOY, 3_000_000), 3_000_000)
    assert not s.offer(_input(JOY2, 3_000_000), 3_000_000)  # another link is another source


def test_stale_future_or_invalid_samples_are_refused() -> None:
    s = _selector(2)
    assert not s.offer(_input(RC, 0), 600_000)           # older than COM_RC_LOSS_T
    assert not s.offer(_input(RC, 10), 0)                # from the future
    assert not s.offer(_input(RC, 0, valid=False), 0)
    assert s.source == 0
