"""The standard VTOL world (issue 23): the StickPlane with four lift rotors on MAIN1-4 and its
surfaces and forward motor on AUX1-4. Trimmed in hover (lift rotors) and in cruise (wing)."""

from __future__ import annotations

import math

import pytest

from hil.world import EscParams, World
from hil.world.fdm import AIRFRAMES, Motor, Servo
from hil.world.trim import trim_hover, trim_level
from hil.worldlink import WorldPorts
from common.units import G0_M_S2

MC_PERIOD_NS = 2_500_000  # 400 Hz, PX4's multicopter PWM rate (MAIN)
SERVO_PERIOD_NS = 20_000_000  # 50 Hz (AUX)


def _apply(w: World, widths: dict[int, float], first: dict[int, float] | None = None) -> None:
    """Set every channel (MAIN at 400 Hz, AUX at 50 Hz); ``first`` one step before (to arm
    the ESCs on a low pulse)."""
    for stage in ([first] if first else []) + [widths]:
        for ch, us in stage.items():
            w.set_pwm(ch, w.t_ns, round(us * 1000), MC_PERIOD_NS if ch < 8 else SERVO_PERIOD_NS)
        w.step(1)


def test_channel_map_lift_on_main_wing_on_aux() -> None:
    af = AIRFRAMES["quadplane"]
    assert [o.engine for o in af.outputs[:4]] == [0, 1, 2, 3]  # PX4 quad X order
    assert all(o is None for o in af.outputs[4:8])
    aux = af.outputs[8:12]
    assert [type(o) for o in aux] == [Servo, Servo, Motor, Servo]  # AETR
    assert aux[0].prop == "fcs/aileron-cmd-norm" and aux[3].prop == "fcs/rudder-cmd-norm"
    assert af.forward_engine == 4 and af.lift_engines == (0, 1, 2, 3)
    assert af.vehicle_class == "vtol" and af.mass_kg == pytest.approx(3.5)


def test_aux_port_moves_the_elevator() -> None:
    ports = WorldPorts(World(airframe="quadplane", agl_m=20.0, airspeed_m_s=15.0))
    ports.input("aux2", 0, (1800_000, SERVO_PERIOD_NS))
    ports.world.step(300)
    assert ports.world.fdm["fcs/elevator-pos-norm"] == pytest.approx(0.6, abs=1e-3)
    assert ports.world.fdm["fcs/aileron-pos-norm"] == pytest.approx(0.0, abs=1e-9)


def test_hover_trim_holds_the_weight() -> None:
    h = trim_hover("quadplane")
    assert h.residual < 1e-3
    assert 4 * h.thrust_per_rotor_n == pytest.approx(3.5 * G0_M_S2, rel=0.01)
    assert 0.4 < h.throttle < 0.75 and 4000 < h.rpm < 7000
    assert 15.0 < h.battery_current_a < 40.0  # ~430 W
    w = World(airframe="quadplane", agl_m=30.0, esc_params=EscParams(arm_low_s=0.0))
    widths = h.channel_us()
    _apply(w, widths, first={ch: 1000.0 for ch, us in widths.items() if us != 1500.0})
    h0 = w.truth().alt_m
    w.step(1500)  # rotors spin up from rest: the vehicle sinks a little, then holds
    mid = w.truth()
    w.step(1500)
    end = w.truth()
    assert abs(end.vel_ned_m_s[2]) < 0.2 and abs(end.alt_m - mid.alt_m) < 0.3
    assert abs(end.alt_m - h0) < 1.5
    assert all(w.motor_rpm(i) == pytest.approx(w.motor_rpm(0), rel=0.02) for i in range(4))
    assert w.motor_rpm(4) < 100.0  # forward motor stopped


def test_cruise_trim_flies_level_on_the_wing_with_rotors_stopped() -> None:
    c = trim_level("quadplane", 18.0)
    plane = trim_level("plane", 18.0)
    assert c.residual < 1e-3
    assert c.aoa_rad > plane.aoa_rad  # heavier: more lift needed
    assert c.battery_current_a > plane.battery_current_a  # and more drag (booms, rotors)
    w = World(airframe="quadplane", agl_m=50.0, airspeed_m_s=18.0, pitch_deg=c.pitch_deg,
              esc_params=EscParams(arm_low_s=0.0))
    widths = c.channel_us()
    fwd = 8 + 2  # AUX3
    assert widths[fwd] == pytest.approx(1000 + 1000 * c.throttle)
    assert all(widths[ch] == 1000.0 for ch in range(4))
    _apply(w, widths, first={fwd: 1000.0})
    h0 = w.truth().alt_m
    for _ in range(5):
        w.step(2000)
        t = w.truth()
        assert abs(t.alt_m - h0) < 1.5 and abs(t.airspeed_m_s - 18.0) < 0.5
        assert abs(t.euler_rad[0]) < math.radians(5.0)
        assert t.aoa_rad < AIRFRAMES["quadplane"].stall_aoa_rad
