"""The standard VTOL's transition logic (firmware/modules/vtol_att_control/standard.py):
shares of rotors and surfaces, the pusher's ramp, completion on airspeed, and PX4's quad-chute."""

import math

from firmware.modules.vtol_att_control.standard import (
    Mode,
    StandardVtol,
    VtolInputs,
    VtolParams,
)

NAN = math.nan


def _at(t, airspeed=NAN, height=30.0, roll=0.0, pitch=0.0):
    return VtolInputs(t, airspeed, height, roll, pitch)


def test_front_transition_blends_on_airspeed_and_ends_at_the_transition_airspeed():
    v = StandardVtol(VtolParams(arsp_blend_m_s=8.0, arsp_trans_m_s=12.0, psher_rmp_dt_s=2.0,
                                trans_min_tm_s=3.0))
    assert v.update(_at(0.0)).mode is Mode.MC
    assert v.request(True)
    out = v.update(_at(1.0, airspeed=1.0))
    assert out.mode is Mode.TRANSITION_TO_FW and out.pusher == 0.0 and out.mc_weight == 1.0
    assert out.fw_weight == 1.0                               # surfaces live from the start
    out = v.update(_at(2.0, airspeed=5.0))
    assert out.pusher == 0.5 and out.mc_weight == 1.0        # ramping, below the blend speed
    out = v.update(_at(3.0, airspeed=10.0))
    assert out.pusher == 1.0 and math.isclose(out.mc_weight, 0.5)  # half way 8 -> 12 m/s
    assert out.fw_weight == 1.0
    out = v.update(_at(3.5, airspeed=12.5))
    assert out.mode is Mode.TRANSITION_TO_FW                  # fast, but not VT_TRANS_MIN_TM yet
    out = v.update(_at(4.1, airspeed=12.5))
    assert out.mode is Mode.FW and (out.mc_weight, out.fw_weight, out.pusher) == (0.0, 1.0, None)


def test_without_airspeed_the_transition_runs_on_time():
    v = StandardVtol(VtolParams(f_trans_dur_s=5.0, trans_min_tm_s=1.0))
    v.update(_at(0.0))
    v.request(True)
    v.update(_at(10.0))
    assert math.isclose(v.update(_at(12.5)).mc_weight, 0.5)
    assert v.update(_at(15.0)).mode is Mode.FW


def test_a_transition_that_never_reaches_airspeed_quad_chutes_and_latches():
    v = StandardVtol(VtolParams(trans_timeout_s=15.0, b_trans_dur_s=4.0))
    v.update(_at(0.0))
    v.request(True)
    v.update(_at(1.0, airspeed=3.0))
    out = v.update(_at(15.9, airspeed=6.0))
    assert out.mode is Mode.TRANSITION_TO_FW and not out.quad_chute
    out = v.update(_at(16.1, airspeed=6.0))
    assert out.mode is Mode.TRANSITION_TO_MC and "timeout" in out.quad_chute
    assert out.mc_weight == 1.0 and out.pusher == 0.0          # rotors take over at once
    assert not v.request(True)                                 # refused while latched
    assert v.update(_at(20.2)).mode is Mode.MC
    v.reset_failure()                                          # landed and disarmed
    assert v.request(True)


def test_fixed_wing_flight_below_the_minimum_height_quad_chutes():
    v = StandardVtol(VtolParams(fw_min_alt_m=10.0, trans_min_tm_s=0.0))
    v.update(_at(0.0))
    v.request(True)
    v.update(_at(1.0, airspeed=20.0))
    assert v.update(_at(1.1, airspeed=20.0, height=25.0)).mode is Mode.FW
    out = v.update(_at(2.0, airspeed=20.0, height=9.0))
    assert out.mode is Mode.TRANSITION_TO_MC and "VT_FW_MIN_ALT" in out.quad_chute


def test_back_transition_brings_the_rotors_back_and_cuts_the_pusher():
    v = StandardVtol(VtolParams(trans_min_tm_s=0.0, b_trans_ramp_s=2.0, b_trans_dur_s=4.0))
    v.update(_at(0.0))
    v.request(True)
    v.update(_at(1.0, airspeed=20.0))
    assert v.update(_at(1.1, airspeed=20.0)).mode is Mode.FW
    v.request(False)
    out = v.update(_at(2.0, airspeed=18.0))
    assert out.mode is Mode.TRANSITION_TO_MC and out.mc_weight == 0.0 and out.pusher == 0.0
    assert math.isclose(v.update(_at(3.0)).mc_weight, 0.5)
    assert v.update(_at(5.0)).mc_weight == 1.0
    assert v.update(_at(6.1)).mode is Mode.MC
