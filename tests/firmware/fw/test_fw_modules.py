"""fw_att_control and fw_pos_control_l1 on an in-process FMU flying the world's StickPlane
(tests/firmware/fw/rig.py: truth estimator, airspeed stub, AETR mixer straight to the servos
and ESC, stand-ins for the commander and navigator).

What is asserted is what a PX4 user looks at: the modules start and stop from their command
line and publish on their topics; the manual scales and limits are respected; in auto the
plane climbs into a loiter and holds its radius, altitude and airspeed without nearing the stall;
it flies on the trim airspeed when told to ignore the sensor; it takes off from the runway on
its heading. Virtual flight time in this file: ~2 min (~6 s of CPU).
"""

from __future__ import annotations

import math

import pytest

from tests.firmware.fw.rig import PLANE_PARAMS, FwRig

SP_LOITER, SP_TAKEOFF = 2, 3
#: the StickPlane's stall angle of attack (hil/world/fdm.py Airframe.stall_aoa_rad)
STALL_AOA_RAD = 0.2094


def test_modules_start_stop_status_and_topics():
    rig = FwRig(agl_m=100.0, airspeed_m_s=16.0)
    mods = rig.system.modules
    assert mods.is_running("fw_att_control") and mods.is_running("fw_pos_control_l1")
    rig.set_landed(False)
    rig.arm(True)
    rig.set_mode("auto")
    rig.set_setpoint(SP_LOITER, 300.0, 0.0, 0.0, loiter_radius=80.0)
    rig.run(0.5)
    for topic in ("actuator_controls_0", "vehicle_attitude_setpoint", "vehicle_rates_setpoint",
                  "tecs_status", "position_controller_status"):
        assert rig.topic(topic) is not None, topic
    pcs = rig.topic("position_controller_status")
    # the navigator's acceptance radius: the L1 distance, damping * period / pi * groundspeed
    assert pcs.acceptance_radius == pytest.approx(0.75 * 20.0 / math.pi * 16.0, rel=0.1)
    assert rig.topic("tecs_status").airspeed_valid
    n = len(rig.system.console_lines)
    assert mods.command("fw_pos_control_l1", ["status"]) == 0
    out = "\n".join(rig.system.console_lines[n:])
    assert "control auto" in out and "airspeed valid" in out
    assert mods.command("fw_att_control", ["stop"]) == 0
    assert not mods.is_running("fw_att_control")
    count = rig.platform.orb.node("actuator_controls_0").publish_count
    rig.run(0.1)
    assert rig.platform.orb.node("actuator_controls_0").publish_count == count
    assert mods.command("fw_att_control", ["start"]) == 0
    rig.run(0.1)
    assert rig.platform.orb.node("actuator_controls_0").publish_count > count


def test_manual_passthrough_scales_and_stabilized_roll_limit():
    rig = FwRig({"FW_MAN_R_SC": 0.5, "FW_MAN_P_SC": 0.8, "FW_MAN_R_MAX": 30.0},
                agl_m=150.0, airspeed_m_s=16.0)
    rig.set_landed(False)
    rig.arm(True)
    rig.set_mode("manual")
    rig.set_sticks(roll=0.6, pitch=0.5, yaw=-0.4, throttle=0.2)
    rig.run(0.05)
    c = rig.topic("actuator_controls_0").control
    # stick forward is nose down; the airframe's trims (TRIM_*) are added, as in PX4
    assert c[0] == pytest.approx(0.3 + PLANE_PARAMS["TRIM_ROLL"])
    assert c[1] == pytest.approx(-0.4 + PLANE_PARAMS["TRIM_PITCH"])
    assert c[2] == pytest.approx(-0.4) and c[3] == pytest.approx(0.6)
    # stabilized: half roll stick is half of FW_MAN_R_MAX, held
    rig.set_mode("stabilized")
    rig.set_sticks(roll=0.5, throttle=0.2)
    rig.run(4.0)
    roll = rig.truth().euler_rad[0]
    assert roll == pytest.approx(math.radians(15.0), abs=math.radians(3.0))
    assert rig.topic("vehicle_attitude_setpoint").roll_body == pytest.approx(math.radians(15.0))


def test_acro_sticks_are_body_rates():
    rig = FwRig({"FW_ACRO_X_MAX": 60.0}, agl_m=150.0, airspeed_m_s=16.0)
    rig.set_landed(False)
    rig.arm(True)
    rig.set_mode("acro")
    rig.set_sticks(roll=0.5, throttle=0.15)
    rates: list[float] = []
    rig.run(1.5, lambda r: rates.append(r.truth().gyro_rad_s[0]), every_n=10)
    assert rig.topic("vehicle_rates_setpoint").roll == pytest.approx(math.radians(30.0))
    tail = rates[50:]
    assert sum(tail) / len(tail) == pytest.approx(math.radians(30.0), rel=0.2)


@pytest.fixture(scope="module")
def loiter_flight():
    """Climb 30 m into a loiter 250 m ahead (radius 80 m), 70 s."""
    rig = FwRig(agl_m=100.0, airspeed_m_s=16.0)
    rig.set_landed(False)
    rig.arm(True)
    rig.set_mode("auto")
    rig.set_setpoint(SP_LOITER, 250.0, 0.0, 30.0, loiter_radius=80.0)
    rows: list[tuple[float, ...]] = []

    def log(r: FwRig) -> None:
        tr = r.truth()
        n, e, h = r.local()
        eas = math.sqrt(2.0 * max(tr.diff_pressure_pa, 0.0) / 1.225)  # what FW_AIRSPD_* mean
        rows.append((tr.t_ns * 1e-9, n, e, h, eas, tr.aoa_rad, tr.euler_rad[0]))

    rig.run(70.0, log, every_n=100)
    return rig, rows


def test_loiter_holds_radius_altitude_and_airspeed(loiter_flight):
    _rig, rows = loiter_flight
    tail = [r for r in rows if r[0] > 45.0]
    radii = [math.hypot(r[1] - 250.0, r[2]) for r in tail]
    print(f"\nloiter: radius {min(radii):.1f}..{max(radii):.1f} m, altitude "
          f"{min(r[3] for r in tail):.2f}..{max(r[3] for r in tail):.2f} m, airspeed "
          f"{min(r[4] for r in tail):.2f}..{max(r[4] for r in tail):.2f} m/s (equivalent)")
    assert max(abs(x - 80.0) for x in radii) < 3.0
    assert max(abs(r[3] - 30.0) for r in tail) < 1.5
    trim = PLANE_PARAMS["FW_AIRSPD_TRIM"]
    assert max(abs(r[4] - trim) for r in tail) < 0.5
    # clockwise (the default direction): banked right all the way round
    assert min(r[6] for r in tail) > math.radians(10.0)


def test_loiter_climb_never_nears_the_stall(loiter_flight):
    _rig, rows = loiter_flight
    assert max(r[5] for r in rows) < 0.6 * STALL_AOA_RAD
    # the climb is flown at about FW_T_CLMB_MAX (3 m/s)
    t10 = next(r[0] for r in rows if r[3] > 10.0)
    t25 = next(r[0] for r in rows if r[3] > 25.0)
    assert 15.0 / (t25 - t10) == pytest.approx(PLANE_PARAMS["FW_T_CLMB_MAX"], rel=0.35)


def test_airspeed_less_mode_flies_on_trim():
    rig = FwRig({"FW_ARSP_MODE": 1}, agl_m=100.0, airspeed_m_s=16.0)
    rig.set_landed(False)
    rig.arm(True)
    rig.set_mode("auto")
    rig.set_setpoint(0, 2000.0, 0.0, 0.0, prev=(0.0, 0.0, 0.0))
    hs: list[float] = []
    rig.run(25.0, lambda r: hs.append(r.local()[2]), every_n=100)
    ts = rig.topic("tecs_status")
    assert not ts.airspeed_valid and ts.true_airspeed_filtered == PLANE_PARAMS["FW_AIRSPD_TRIM"]
    assert max(abs(h) for h in hs[50:]) < 4.0
    assert 13.0 < rig.truth().airspeed_m_s < 20.0


def test_runway_takeoff_holds_heading_and_climbs_out():
    rig = FwRig({"RWTO_TKOFF": 1}, agl_m=0.0, airspeed_m_s=0.0)
    rig.set_landed(True)
    rig.arm(True)
    rig.set_mode("auto")
    rig.set_setpoint(SP_TAKEOFF, 0.0, 0.0, 30.0, yaw=0.0)
    rows: list[tuple[float, ...]] = []

    def log(r: FwRig) -> None:
        tr = r.truth()
        n, e, h = r.local()
        if h > 2.0 and r.land_msg.landed:
            r.set_landed(False)
        sp = r.topic("vehicle_attitude_setpoint")
        rows.append((tr.t_ns * 1e-9, n, e, h, tr.airspeed_m_s, tr.aoa_rad, tr.agl_m,
                     sp.thrust_body[0] if sp else 0.0))

    rig.run(1.5, log, every_n=100)
    # the navigator raises the takeoff altitude during the ground roll: the same takeoff goes
    # on (no new throttle ramp)
    rig.set_setpoint(SP_TAKEOFF, 0.0, 0.0, 50.0, yaw=0.0)
    rig.run(28.5, log, every_n=100)
    liftoff = next(r for r in rows if r[6] > 0.5)
    ramp = [r[7] for r in rows if r[0] < liftoff[0]]
    assert all(b >= a for a, b in zip(ramp, ramp[1:]))
    ground = [r for r in rows if r[0] < liftoff[0]]
    print(f"\nrunway takeoff: lift-off at {liftoff[0]:.1f} s, {liftoff[1]:.0f} m down the "
          f"runway at {liftoff[4]:.1f} m/s")
    # no lift-off before the rotation speed, FW_AIRSPD_MIN * RWTO_AIRSPD_SCL
    assert liftoff[4] > PLANE_PARAMS["FW_AIRSPD_MIN"] * 1.3 - 0.5
    assert max(abs(r[2]) for r in ground) < 3.0            # on the runway's centre line
    assert abs(rows[-1][3] - 50.0) < 2.0
    # the end of the climb-out (10 m below) neither dips nor overshoots (TECS's demand kept up)
    hs = [r[3] for r in rows]
    assert max(hs) < 50.0 + 2.0
    up = hs[:next(i for i, h in enumerate(hs) if h > 49.0)]
    assert max(max(up[:i + 1]) - h for i, h in enumerate(up)) < 0.5
    assert max(r[5] for r in rows if r[4] > 8.0) < STALL_AOA_RAD


def test_landing_approach_flare_and_touchdown_on_the_point():
    """From 20 m, a touchdown point 400 m ahead: hold altitude until the glide slope, follow
    it, flare, throttle cut (FW_THR_LND_MAX 0), touch down on the point and roll out straight."""
    rig = FwRig({"FW_THR_LND_MAX": 0.0}, agl_m=20.0, airspeed_m_s=16.0)
    rig.set_landed(False)
    rig.arm(True)
    rig.set_mode("auto")
    rig.set_setpoint(4, 400.0, 0.0, -20.0, prev=(0.0, 0.0, 0.0))   # SP_LAND on the ground
    rows: list[tuple[float, ...]] = []

    def log(r: FwRig) -> None:
        tr = r.truth()
        n, e, _h = r.local()
        c = r.topic("actuator_controls_0")
        thr = c.control[3] if c is not None else math.nan
        rows.append((tr.t_ns * 1e-9, n, e, tr.agl_m, tr.vel_ned_m_s[2], tr.airspeed_m_s,
                     tr.aoa_rad, thr))

    rig.run(30.0, log, every_n=100)
    touch = next(i for i, r in enumerate(rows) if r[3] < 0.21)
    t = rows[touch]
    sink = max(r[4] for r in rows[touch - 3:touch])
    print(f"\nlanding: touchdown {t[1] - 400.0:+.1f} m from the point, {t[2]:+.1f} m off the "
          f"line, sink {sink:.2f} m/s, airspeed {t[5]:.1f} m/s")
    assert abs(t[1] - 400.0) < 30.0 and abs(t[2]) < 3.0
    assert sink < 1.5
    assert max(r[6] for r in rows if r[5] > 8.0) < STALL_AOA_RAD
    # the throttle is cut below the flare altitude (FW_LND_TLALT -1 = FW_LND_FLALT, 3 m)
    assert all(r[7] == 0.0 for r in rows if r[3] < 2.5 and r[0] > 1.0)
    # on the ground, rolling straight along the approach line
    assert all(abs(r[2]) < 3.0 for r in rows[touch:])


def test_hand_launch_climbs_out_at_full_throttle():
    """A throw (12 m/s, 2 m up, motor running: LAUN_ALL_ON 0): climb-out at full throttle and
    at least FW_TKO_PITCH_MIN while more than FW_CLMBOUT_DIFF below the target, then level."""
    rig = FwRig(agl_m=2.0, airspeed_m_s=12.0)
    rig.set_landed(False)
    rig.arm(True)
    rig.set_mode("auto")
    rig.set_setpoint(SP_TAKEOFF, 0.0, 0.0, 30.0, yaw=0.0)
    rows: list[tuple[float, ...]] = []

    def log(r: FwRig) -> None:
        tr = r.truth()
        sp = r.topic("vehicle_attitude_setpoint")
        rows.append((tr.t_ns * 1e-9, tr.agl_m, tr.aoa_rad, sp.thrust_body[0] if sp else 0.0,
                     sp.pitch_body if sp else 0.0, r.local()[2]))

    rig.run(16.0, log, every_n=100)
    climb = [r for r in rows if 0.5 < r[0] and r[5] < 30.0 - 10.0 - 1.0]
    assert climb and all(r[3] == 1.0 for r in climb)
    assert all(r[4] >= math.radians(10.0) - 1e-6 for r in climb)
    assert min(r[1] for r in rows) > 1.5                 # never back onto the ground
    assert max(r[2] for r in rows) < STALL_AOA_RAD
    assert abs(rows[-1][5] - 30.0) < 3.0
