"""The FMU's own PWM outputs (``fmu``, PX4's mode_pwm): AUX1..AUX6 from TIM1/TIM4 at register
level, mixed on the FMU from control groups 0 and 1, through pwm_limit, seen on the board's
``aux`` ports as a servo would see them."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from firmware.romfs import ROMFS_ROOT
from tests.fuzzing import fuzz
from tests.helpers import booted_fmu, publish

MS = 1_000_000
S = 1_000_000_000


@pytest.fixture(scope="module")
def board():
    return booted_fmu({"SYS_AUTOSTART": 0, "SDLOG_MODE": -1})


def test_aux_outputs_follow_the_mixer_when_armed_and_stop_when_disarmed(board):
    b = board
    assert b.ctl_shell("fmu start")[0] == 0
    status, out = b.ctl_shell("mixer load /dev/pwm_output1 /etc/mixers/AETR.main.mix")
    assert status == 0, out
    b.kernel.run(b.kernel.now_ns + 50 * MS)
    # disarmed with PWM_AUX_DISARMED 0 the timers are stopped (PX4: up_pwm_servo_arm(false)):
    # each pin holds a level, no pulse train a servo or ESC would take
    assert all(h in (0, p) for h, p in b.ctl_aux_pwm())
    controls = [0.5, -0.25, 0.0, 0.6, 0, 0, 0, 0]
    publish(b, "actuator_controls_0", control=controls)
    publish(b, "actuator_armed", armed=True)
    b.kernel.run(b.kernel.now_ns + 700 * MS)  # pwm_limit: 500 ms INIT, then the ramp
    publish(b, "actuator_controls_0", control=controls)
    b.kernel.run(b.kernel.now_ns + 100 * MS)
    pwm = b.ctl_aux_pwm()
    # AETR: aileron 0.5 -> 1750 us, elevator -0.25 -> 1375, throttle 0.6 (0..1) -> 1600,
    # rudder 0 -> 1500; E14's timer layer is high one tick less (CCR = pulse - 1) and its
    # period one tick long (ARR = 1e6 / 50 = 20000 -> 20001 us)
    assert [h // 1000 for h, _ in pwm[:4]] == [1749, 1374, 1599, 1499]
    assert {p for _, p in pwm[:4]} == {20_001_000}
    assert [h for h, _ in pwm[4:]] == [0, 0]  # AUX5/6: no mixer output, no pulse
    assert b.port_levels["aux1"] == pwm[0]
    publish(b, "actuator_armed", armed=False)
    b.kernel.run(b.kernel.now_ns + 150 * MS)  # the 10 Hz backstop sees the disarm
    assert all(h in (0, p) for h, p in b.ctl_aux_pwm())
    status, out = b.ctl_shell("fmu status")
    assert status == 0 and "AETR.main.mix (4 outputs)" in out, out


def test_a_bad_mixer_file_is_one_line_and_keeps_the_loaded_mixer(board):
    b = board
    if not b.system.modules.is_running("fmu"):
        assert b.ctl_shell("fmu start")[0] == 0
        assert b.ctl_shell("mixer load /dev/pwm_output1 /etc/mixers/AETR.main.mix")[0] == 0
    status, out = b.ctl_shell("mixer load /dev/pwm_output1 /etc/init.d/rcS")
    assert status == 1 and "fmu: mixer /etc/init.d/rcS" in out and "no mixer" in out, out
    assert b.ctl_shell("mixer load /dev/pwm_output1 /etc/mixers/nope.mix")[0] == 1
    output = b.system.modules.get("fmu").output
    cut = b.system.resolve_path("/etc/mixers/AETR.main.mix").read_text().split("S: 0 1")[0]
    with pytest.raises(ValueError, match="line"):
        output.load_mixer(cut, "cut")  # a mixer cut after its O: line: the line is named
    status, out = b.ctl_shell("fmu status")
    assert b.system.modules.is_running("fmu") and "AETR.main.mix (4 outputs)" in out


_AETR = (ROMFS_ROOT / "mixers" / "AETR.main.mix").read_text()


@fuzz(examples=200)
@given(st.one_of(st.text(max_size=400),
                 st.tuples(st.integers(0, len(_AETR)), st.integers(0, 40), st.text(max_size=12))
                 .map(lambda t: _AETR[:t[0]] + t[2] + _AETR[t[0] + t[1]:])))
def test_any_mixer_text_loads_or_is_refused_and_the_old_mixer_stays(board, text):
    """What ``mixer load /dev/pwm_output1 FILE`` hands the FMU's outputs: random text and the
    AETR file with a span replaced. It loads (1..6 outputs) or is refused with a ValueError
    naming why, and a refused text leaves the mixer that was loaded."""
    if not board.system.modules.is_running("fmu"):
        assert board.ctl_shell("fmu start")[0] == 0
    output = board.system.modules.get("fmu").output
    output.load_mixer(_AETR, "AETR")
    try:
        n = output.load_mixer(text, "fuzz")
    except ValueError:
        assert output.mixer_path == "AETR" and output.group.output_count == 4
    else:
        assert 1 <= n <= output.n_outputs and output.mixer_path == "fuzz"
