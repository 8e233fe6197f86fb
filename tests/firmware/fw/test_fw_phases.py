"""The pure parts of fw_pos_control_l1's takeoff and landing (runway state machine, launch
detection, glide slope and flare geometry), and its altitude/position modes in closed loop."""

from __future__ import annotations

import math

import pytest

from firmware.modules.fw_pos_control_l1.landing import (
    FLARE_BELOW_GROUND_M,
    flare_time_constant,
    slope_aim_shift_m,
    slope_altitude,
)
from firmware.modules.fw_pos_control_l1.takeoff import (
    RW_CLAMPED,
    RW_CLIMBOUT,
    RW_FLY,
    RW_THROTTLE_RAMP,
    LaunchDetector,
    RunwayTakeoff,
)
from tests.firmware.fw.rig import FwRig


def test_runway_takeoff_states_and_throttle_ramp():
    rw = RunwayTakeoff()
    rw.init(1_000_000, 100.0, 0.3)
    assert rw.update(1_500_000, 0.0, 100.0, 17.0, 2.0, 5.0) == RW_THROTTLE_RAMP
    # half way through the 2 s ramp: half way from idle to the maximum
    assert rw.throttle(2_000_000, 2.0, 1.0, 0.2) == pytest.approx(0.6)
    assert rw.on_ground
    assert rw.update(3_000_000, 10.0, 100.0, 17.0, 2.0, 5.0) == RW_CLAMPED   # ramp done
    assert rw.throttle(3_000_000, 2.0, 0.9, 0.2) == 0.9
    assert rw.update(4_000_000, 16.9, 100.0, 17.0, 2.0, 5.0) == RW_CLAMPED   # not yet
    assert rw.update(4_100_000, 17.0, 100.5, 17.0, 2.0, 5.0) == RW_CLIMBOUT  # rotate
    assert not rw.on_ground
    assert rw.update(6_000_000, 17.0, 104.9, 17.0, 2.0, 5.0) == RW_CLIMBOUT
    assert rw.update(6_100_000, 17.0, 105.0, 17.0, 2.0, 5.0) == RW_FLY       # RWTO_NAV_ALT
    assert rw.heading_rad == 0.3


def test_launch_detection_needs_the_acceleration_for_long_enough():
    ld = LaunchDetector()
    # a 30 ms jolt above 30 m/s^2 is not a throw (LAUN_CAT_T 50 ms)
    t = 0
    for _ in range(3):
        t += 10_000
        assert not ld.update(t, 0.01, 40.0, 30.0, 0.05)
    assert not ld.update(t + 10_000, 0.01, 5.0, 30.0, 0.05)
    for i in range(5):
        detected = ld.update(t + 20_000 + i * 10_000, 0.01, 40.0, 30.0, 0.05)
    assert detected and ld.detected_us == t + 60_000
    # the motor waits LAUN_CAT_MDEL after the detection
    assert not ld.motor_on(ld.detected_us + 400_000, 0.5)
    assert ld.motor_on(ld.detected_us + 500_000, 0.5)
    # once detected, it stays detected whatever the accelerometer says
    assert ld.update(ld.detected_us + 1, 0.01, -50.0, 30.0, 0.05)


def test_glide_slope_flare_and_aim_point():
    slope = math.radians(5.0)
    # on the slope far out, never above the altitude at the start of the landing
    assert slope_altitude(100.0, 200.0, slope, 200.0) == pytest.approx(100 + 200 * math.tan(slope))
    assert slope_altitude(100.0, 5000.0, slope, 130.0) == 130.0
    assert slope_altitude(100.0, -20.0, slope, 130.0) == 100.0     # past the point: the ground
    # the flare's demanded sink at its start equals the approach's: (h_f + b) / tc = sink
    tc = flare_time_constant(3.0, 1.4)
    assert (3.0 + FLARE_BELOW_GROUND_M) / tc == pytest.approx(1.4)
    # the exponential flare is longer than the straight slope: aim short by the difference
    shift = slope_aim_shift_m(3.0, slope, 16.0)
    flare_len = 16.0 * flare_time_constant(3.0, 16.0 * math.tan(slope)) * math.log(4.0)
    assert shift == pytest.approx(flare_len - 3.0 / math.tan(slope))
    assert shift > 0.0
    assert slope_aim_shift_m(0.0, slope, 16.0) == 0.0


def test_position_mode_climbs_on_the_stick_then_holds_altitude_and_track():
    rig = FwRig(agl_m=100.0, airspeed_m_s=16.0)
    rig.set_landed(False)
    rig.arm(True)
    rig.set_mode("position")
    rig.set_sticks()
    rig.run(3.0)
    h0 = rig.local()[2]
    rig.set_sticks(pitch=-0.6)           # stick back: climb at 0.6 of FW_T_CLMB_MAX
    rig.run(6.0)
    h1 = rig.local()[2]
    assert h1 - h0 > 5.0
    rig.set_sticks()                     # centred: hold
    rig.run(4.0)
    rows: list[tuple[float, float, float]] = []
    rig.run(8.0, lambda r: rows.append(r.local()), every_n=100)
    hs = [r[2] for r in rows]
    es = [r[1] for r in rows]
    print(f"\nposition mode: climbed {h1 - h0:.1f} m in 6 s, then altitude "
          f"{min(hs):.2f}..{max(hs):.2f} m, east drift {max(es) - min(es):.2f} m")
    assert max(hs) - min(hs) < 1.5
    assert max(es) - min(es) < 3.0       # heading hold: still on the line it was flying
    # throttle stick full: the airspeed demand goes to FW_AIRSPD_MAX
    rig.set_sticks(throttle=1.0)
    rig.run(2.0)
    assert rig.topic("tecs_status").true_airspeed_sp > 17.0


def test_approach_repositions_when_the_landing_starts_past_the_point():
    from firmware.modules.fw_pos_control_l1.landing import (
        APP_JOIN,
        APP_ON_SLOPE,
        APP_REPOSITION,
        Approach,
    )

    ap = Approach()
    north = (1.0, 0.0)
    # 200 m past the touchdown point, flying north: go to the start of the 600 m final first
    assert ap.update((200.0, 50.0), (16.0, 0.0), (0.0, 0.0), north, 600.0, 60.0) \
        == APP_REPOSITION
    assert ap.line_a == ap.line_b == (-600.0, 0.0)
    # there: join the line, at the entry altitude, until on it and flying along it
    assert ap.update((-580.0, 30.0), (0.0, -16.0), (0.0, 0.0), north, 600.0, 60.0) == APP_JOIN
    assert ap.line_b == (0.0, 0.0) and ap.line_a[0] < -600.0
    assert ap.update((-560.0, 5.0), (0.0, -16.0), (0.0, 0.0), north, 600.0, 60.0) == APP_JOIN
    assert ap.update((-540.0, 5.0), (16.0, 0.5), (0.0, 0.0), north, 600.0, 60.0) \
        == APP_ON_SLOPE
    # latched: no going back once on the slope
    assert ap.update((-100.0, 40.0), (16.0, 0.0), (0.0, 0.0), north, 600.0, 60.0) \
        == APP_ON_SLOPE
    # a landing that starts far out beside the line joins it at once; on it, is on the slope
    # (whose altitude is then still the entry altitude)
    ap.reset()
    assert ap.update((-1500.0, 100.0), (16.0, 0.0), (0.0, 0.0), north, 600.0, 60.0) == APP_JOIN
    ap.reset()
    assert ap.update((-1500.0, 0.0), (16.0, 0.0), (0.0, 0.0), north, 600.0, 60.0) \
        == APP_ON_SLOPE


def test_nan_altitude_and_invalid_setpoints_hold_the_altitude():
    """A setpoint with a NaN altitude (PX4: keep the altitude) holds the one the plane had; an
    invalid current setpoint in the air holds altitude and heading on the motor, never a
    glide or a NaN control; a NaN landing altitude is not landed on."""
    rig = FwRig(agl_m=100.0, airspeed_m_s=16.0)
    rig.set_landed(False)
    rig.arm(True)
    rig.set_mode("auto")
    rig.set_setpoint(0, 2000.0, 0.0, math.nan, prev=(0.0, 0.0, 0.0))
    hs: list[float] = []
    rig.run(6.0, lambda r: hs.append(r.local()[2]), every_n=100)
    m = rig.trip_msg
    m.current.valid = False
    m.timestamp = m.current.timestamp = rig.now_us()
    rig.pub_trip.publish(m)
    rig.run(6.0, lambda r: hs.append(r.local()[2]), every_n=100)
    rig.set_setpoint(4, 600.0, 0.0, math.nan, prev=(0.0, 0.0, 0.0))    # SP_LAND, no altitude
    rig.run(6.0, lambda r: hs.append(r.local()[2]), every_n=100)
    c = rig.topic("actuator_controls_0").control
    assert all(math.isfinite(x) for x in c[:4]) and c[3] > 0.2
    assert max(abs(h) for h in hs) < 3.0, (min(hs), max(hs))
