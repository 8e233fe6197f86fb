"""Straight-and-level trim of a fixed-wing airframe: fixed surface and throttle commands.

JSBSim's own trim routine cannot be used: it expects the thrust to follow the throttle at
once, and an electric motor's thrust follows the propeller's speed, a state of its own ("udot
doesn't appear to be trimmable"). So the trim here is a small Newton search on JSBSim's
accelerations with the airframe's state frozen: JSBSim's integrators are switched off
(integrator type 0), so each evaluation sets the flight condition (airspeed, angle of attack,
bank, no rates), runs the model long enough for the servos and the propeller to settle, and
reads the six body accelerations. The unknowns are angle of attack, throttle, elevator,
aileron, rudder and bank angle (sideslip held at 0: the aileron and rudder take the propeller's
torque and swirl); the residuals are u', v', w', p', q', r'.

The result is what a test (or a mixer's trim) needs: the position commands (-1..1) and the
ESC throttle (0..1), their PWM widths (servo 1500 +- 500 us, ESC 1000..2000 us), and the
attitude to start the world in. The ESC throttle accounts for the pack's steady-state sag at
the trim current, since the world scales the motor voltage by the pack voltage.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .battery import lipo_cell_ocv_v
from .fdm import AIRFRAMES, FT, LBF_N, Airframe, Fdm, Motor, Servo
from .world import PX4_HOME

__all__ = ["TrimPoint", "HoverPoint", "trim_level", "trim_climb", "trim_hover"]

_INTEGRATORS = ("rate/rotational", "rate/translational", "position/rotational",
                "position/translational")
_RESIDUALS = ("accelerations/udot-ft_sec2", "accelerations/vdot-ft_sec2",
              "accelerations/wdot-ft_sec2", "accelerations/pdot-rad_sec2",
              "accelerations/qdot-rad_sec2", "accelerations/rdot-rad_sec2")
# unknowns: alpha (rad), JSBSim throttle, aileron, elevator, rudder (-1..1), bank (rad)
_STEPS = np.array([1e-3, 5e-3, 5e-3, 5e-3, 5e-3, 1e-3])
# largest Newton step per unknown (damped Newton: the lift curve is not linear near the stall)
_MAX_STEP = np.array([0.03, 0.2, 0.2, 0.2, 0.2, 0.05])
# residual scale: ft/s^2 for forces, rad/s^2 for moments (both ~ what a 1 % error gives)
_SCALE = np.array([1.0 / FT, 1.0 / FT, 1.0 / FT, 1.0, 1.0, 1.0])


@dataclass(frozen=True, slots=True)
class TrimPoint:
    """Straight flight at ``airspeed_m_s`` (true airspeed, still air), level unless
    ``gamma_rad`` (flight-path angle) says otherwise."""

    airframe: str
    airspeed_m_s: float
    aoa_rad: float  # pitch minus the flight-path angle
    roll_rad: float
    aileron: float  # position commands, -1..1 (+: roll right / nose up / yaw right)
    elevator: float
    rudder: float
    throttle: float  # ESC throttle 0..1 (PWM 1000 + 1000 x throttle us)
    motor_current_a: float
    battery_current_a: float
    battery_voltage_v: float
    residual: float  # largest remaining acceleration, m/s^2 or rad/s^2
    gamma_rad: float = 0.0  # flight-path angle (climb positive)

    @property
    def pitch_deg(self) -> float:
        return math.degrees(self.aoa_rad + self.gamma_rad)

    @property
    def climb_rate_m_s(self) -> float:
        return self.airspeed_m_s * math.sin(self.gamma_rad)

    def channel_us(self) -> dict[int, float]:
        """Pulse width (us) per world channel the airframe uses: servos at their trim, the
        forward motor at the trim throttle, lift rotors stopped (1000 us)."""
        af = AIRFRAMES[self.airframe]
        by_prop = {"fcs/aileron-cmd-norm": self.aileron, "fcs/elevator-cmd-norm": self.elevator,
                   "fcs/rudder-cmd-norm": self.rudder}
        widths: dict[int, float] = {}
        for ch, out in enumerate(af.outputs):
            if isinstance(out, Servo):
                widths[ch] = 1500.0 + 500.0 * by_prop[out.prop]
            elif isinstance(out, Motor):
                forward = out.engine == af.forward_engine
                widths[ch] = 1000.0 + 1000.0 * self.throttle if forward else 1000.0
        return widths

    def pwm_us(self) -> tuple[float, ...]:
        """:meth:`channel_us` as a tuple from MAIN1 up to the last channel used (1500 us on a
        channel wired to nothing)."""
        widths = self.channel_us()
        return tuple(widths.get(ch, 1500.0) for ch in range(max(widths) + 1))


@dataclass(frozen=True, slots=True)
class HoverPoint:
    """Hover in still air: the common ESC throttle of the lift rotors."""

    airframe: str
    throttle: float  # ESC throttle 0..1 of every lift rotor
    rpm: float
    thrust_per_rotor_n: float
    battery_current_a: float
    battery_voltage_v: float
    residual: float  # largest remaining body acceleration, m/s^2 or rad/s^2

    def channel_us(self) -> dict[int, float]:
        """Lift rotors at the hover throttle, servos centred, the forward motor stopped."""
        af = AIRFRAMES[self.airframe]
        widths: dict[int, float] = {}
        for ch, out in enumerate(af.outputs):
            if isinstance(out, Servo):
                widths[ch] = 1500.0
            elif isinstance(out, Motor):
                lift = out.engine in af.lift_engines
                widths[ch] = 1000.0 + 1000.0 * self.throttle if lift else 1000.0
        return widths


def _pack_steady_v(af: Airframe, jsb_throttle: float, motor_a: float) -> tuple[float, float]:
    """Pack voltage and current in steady state (polarisation settled) at full charge, for
    the world's current model (motor power through the ESC efficiency plus avionics)."""
    bp = af.battery
    ocv = bp.cells * lipo_cell_ocv_v(bp.soc0)
    k = jsb_throttle * motor_a * af.motor_max_volts / bp.esc_efficiency
    v = ocv
    for _ in range(50):
        i = bp.avionics_a + k / v
        v = ocv - i * (bp.r0_ohm + bp.r1_ohm)
    return v, bp.avionics_a + k / v


def trim_level(airframe: str = "plane", airspeed_m_s: float = 16.0, agl_m: float = 50.0,
               settle_steps: int = 300, max_iter: int = 40) -> TrimPoint:
    """Find the straight-and-level trim at ``airspeed_m_s``; raises if it does not converge
    (the speed is below the stall or above what the motor can hold)."""
    return _solve(airframe, airspeed_m_s, agl_m, settle_steps, max_iter, esc_throttle=None)


def trim_hover(airframe: str = "quadplane", agl_m: float = 50.0, settle_steps: int = 600,
               max_iter: int = 20) -> HoverPoint:
    """The lift rotors' common throttle that holds the vehicle in still air (secant search on
    the vertical acceleration, state frozen as for :func:`trim_level`)."""
    af = AIRFRAMES[airframe]
    if not af.lift_engines:
        raise ValueError(f"{airframe!r} has no lift rotors")
    lat, lon, alt = PX4_HOME
    fdm = Fdm(af, 0.001, lat, lon, alt, 0.0, agl_m)
    x = fdm.exec
    for k in _INTEGRATORS:
        x["simulation/integrator/" + k] = 0

    def accel(jsb: float) -> np.ndarray:
        for e in af.lift_engines:
            x[f"fcs/throttle-cmd-norm[{e}]"] = jsb
        for _ in range(settle_steps):
            x.run()
        return np.array([x[p] for p in _RESIDUALS]) / _SCALE

    a0, a1 = 0.3, 0.6
    w0, w1 = accel(a0)[2], accel(a1)[2]
    for _ in range(max_iter):
        if abs(w1) < 1e-5 or w1 == w0:
            break
        a0, a1, w0 = a1, min(1.0, max(0.05, a1 - w1 * (a1 - a0) / (w1 - w0))), w1
        w1 = accel(a1)[2]
    res = accel(a1)
    amps = sum(x[f"propulsion/engine[{e}]/current-amperes"] for e in af.lift_engines)
    v, i = _pack_steady_v(af, a1, amps)
    e0 = af.lift_engines[0]
    return HoverPoint(
        airframe=airframe, throttle=float(a1 * af.motor_max_volts / v),
        rpm=float(x[f"propulsion/engine[{e0}]/propeller-rpm"]),
        thrust_per_rotor_n=float(x[f"propulsion/engine[{e0}]/thrust-lbs"] * LBF_N),
        battery_current_a=float(i), battery_voltage_v=float(v),
        residual=float(np.max(np.abs(res))))


def trim_climb(airframe: str = "plane", airspeed_m_s: float = 16.0, esc_throttle: float = 1.0,
               agl_m: float = 50.0, settle_steps: int = 300, max_iter: int = 40) -> TrimPoint:
    """Steady straight climb (or descent) at ``airspeed_m_s`` with the ESC at
    ``esc_throttle``: the flight-path angle is the unknown instead of the throttle."""
    if not 0.0 <= esc_throttle <= 1.0:
        raise ValueError(f"ESC throttle must be in [0, 1], got {esc_throttle!r}")
    return _solve(airframe, airspeed_m_s, agl_m, settle_steps, max_iter, esc_throttle)


def _solve(airframe: str, airspeed_m_s: float, agl_m: float, settle_steps: int,
           max_iter: int, esc_throttle: float | None) -> TrimPoint:
    af = AIRFRAMES[airframe]
    if af.vehicle_class == "multicopter":
        raise ValueError(f"{airframe!r} has no wing to trim")
    lat, lon, alt = PX4_HOME
    fdm = Fdm(af, 0.001, lat, lon, alt, 0.0, agl_m, airspeed_m_s=airspeed_m_s)
    x = fdm.exec
    engine = af.forward_engine
    if engine is None:
        raise ValueError(f"{airframe!r} has no forward motor")
    thr_prop = f"fcs/throttle-cmd-norm[{engine}]"
    amps_prop = f"propulsion/engine[{engine}]/current-amperes"
    climb = esc_throttle is not None
    # with the ESC throttle fixed, the JSBSim throttle follows the pack voltage
    jsb_fixed = 0.0
    if esc_throttle is not None:
        v_pack = _pack_steady_v(af, esc_throttle, 0.0)[0]

    def residual(z: np.ndarray) -> np.ndarray:
        alpha, second, ail, elev, rud, phi = (float(v) for v in z)
        # attitude and body velocity directly (JSBSim's alpha/gamma initial-condition setters
        # depend on the order they are called in): no sideslip, and the pitch that puts the
        # velocity on the flight path gamma: -cos(a) sin(th) + sin(a) cos(phi) cos(th) = -sin(g)
        gamma = second if climb else 0.0
        ca, sa_phi = math.cos(alpha), math.sin(alpha) * math.cos(phi)
        theta = math.atan2(sa_phi, ca) + math.asin(math.sin(gamma) / math.hypot(ca, sa_phi))
        x["ic/phi-rad"] = phi
        x["ic/theta-rad"] = theta
        x["ic/u-fps"] = airspeed_m_s * ca / FT
        x["ic/v-fps"] = 0.0
        x["ic/w-fps"] = airspeed_m_s * math.sin(alpha) / FT
        for r in ("ic/p-rad_sec", "ic/q-rad_sec", "ic/r-rad_sec"):
            x[r] = 0.0
        x.run_ic()
        for k in _INTEGRATORS:
            x["simulation/integrator/" + k] = 0
        x[thr_prop] = jsb_fixed if climb else second
        x["fcs/aileron-cmd-norm"] = ail
        x["fcs/elevator-cmd-norm"] = elev
        x["fcs/rudder-cmd-norm"] = rud
        for _ in range(settle_steps):
            x.run()
        return np.array([x[p] for p in _RESIDUALS]) / _SCALE

    # first guess of the throttle: enough for the propeller to pull at this speed (past its
    # zero-thrust advance ratio the thrust no longer answers the throttle and Newton stalls)
    thr0 = min(0.95, max(0.3, 0.035 * airspeed_m_s))
    z = np.array([0.06, 0.0 if climb else thr0, 0.0, 0.1, 0.0, 0.0])
    for _outer in range(4 if climb else 1):
        if esc_throttle is not None:
            jsb_fixed = min(1.0, esc_throttle * v_pack / af.motor_max_volts)
        r = residual(z)
        for _ in range(max_iter):
            if np.max(np.abs(r)) < 1e-4:
                break
            jac = np.empty((6, 6))
            for j in range(6):
                dz = np.zeros(6)
                dz[j] = _STEPS[j]
                jac[:, j] = (residual(z + dz) - r) / _STEPS[j]
            dz = np.linalg.solve(jac, r)
            z = z - dz * min(1.0, float(np.min(_MAX_STEP / (np.abs(dz) + 1e-12))))
            if not climb:
                z[1] = min(max(z[1], 0.0), 1.0)
            z[2:5] = np.clip(z[2:5], -1.0, 1.0)
            r = residual(z)
        if esc_throttle is not None:  # pack sag at this current, then solve again
            v_pack = _pack_steady_v(af, jsb_fixed, x[amps_prop])[0]
    worst = float(np.max(np.abs(r)))
    thr_ok = climb or 0.0 < z[1] < 1.0
    if worst > 1e-3 or not thr_ok or np.any(np.abs(z[2:5]) >= 1.0):
        raise RuntimeError(f"no straight trim for {airframe!r} at {airspeed_m_s} m/s "
                           f"(residual {worst:.3g}, unknowns {np.round(z, 3).tolist()})")
    jsb = jsb_fixed if climb else float(z[1])
    motor_a = x[amps_prop]
    v, i = _pack_steady_v(af, jsb, motor_a)
    if not climb and jsb * af.motor_max_volts / v > 1.0:
        raise RuntimeError(f"no straight trim for {airframe!r} at {airspeed_m_s} m/s: needs "
                           f"more than full throttle on the sagging pack")
    return TrimPoint(
        airframe=airframe, airspeed_m_s=airspeed_m_s, aoa_rad=float(z[0]), roll_rad=float(z[5]),
        aileron=float(z[2]), elevator=float(z[3]), rudder=float(z[4]),
        throttle=float(esc_throttle if esc_throttle is not None
                       else jsb * af.motor_max_volts / v),
        motor_current_a=float(motor_a), battery_current_a=float(i), battery_voltage_v=float(v),
        residual=worst,
        gamma_rad=float(z[1]) if climb else 0.0)


def main() -> None:
    """Print the airframe's key figures: trim over speed, stall, top speed, climb, endurance
    (``python -m hil.world.trim [airframe]``)."""
    import sys

    name = sys.argv[1] if len(sys.argv) > 1 else "plane"
    af = AIRFRAMES[name]
    print(f"{name}: {af.model}, {af.mass_kg} kg, stall angle of attack "
          f"{math.degrees(af.stall_aoa_rad or 0.0):.1f} deg, {af.battery.cells}S "
          f"{af.battery.capacity_mah:.0f} mAh")
    print(" V m/s  aoa deg  elev   thr   I_batt A   P W   endurance min (80 % of the pack)")
    slowest = top = None
    for v in np.arange(9.0, 32.0, 1.0):
        try:
            t = trim_level(name, float(v))
        except RuntimeError:
            if slowest is not None and top is None:
                top = float(v) - 1.0
            continue
        slowest = slowest if slowest is not None else float(v)
        p = t.battery_current_a * t.battery_voltage_v
        minutes = 0.8 * af.battery.capacity_mah / 1000.0 / t.battery_current_a * 60.0
        print(f" {v:5.1f}  {math.degrees(t.aoa_rad):6.2f}  {t.elevator:5.3f}  {t.throttle:5.3f}"
              f"  {t.battery_current_a:7.2f}  {p:6.1f}  {minutes:6.1f}")
    print(f"slowest level trim {slowest} m/s, fastest {top} m/s")
    if af.lift_engines:
        h = trim_hover(name)
        minutes = 0.8 * af.battery.capacity_mah / 1000.0 / h.battery_current_a * 60.0
        print(f"hover: ESC throttle {h.throttle:.3f}, {h.rpm:.0f} rpm, {h.thrust_per_rotor_n:.2f} N "
              f"per rotor, battery {h.battery_current_a:.1f} A "
              f"({h.battery_current_a * h.battery_voltage_v:.0f} W, {minutes:.1f} min)")
    for v in (14.0, 16.0, 18.0):
        c = trim_climb(name, v, 1.0)
        print(f"full-throttle climb at {v:.0f} m/s: {c.climb_rate_m_s:.2f} m/s "
              f"(path {math.degrees(c.gamma_rad):.1f} deg, battery {c.battery_current_a:.1f} A)")


if __name__ == "__main__":
    main()
