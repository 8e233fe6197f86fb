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
from .fdm import AIRFRAMES, FT, Airframe, Fdm, Motor, Servo
from .world import PX4_HOME

__all__ = ["TrimPoint", "trim_level"]

_INTEGRATORS = ("rate/rotational", "rate/translational", "position/rotational",
                "position/translational")
_RESIDUALS = ("accelerations/udot-ft_sec2", "accelerations/vdot-ft_sec2",
              "accelerations/wdot-ft_sec2", "accelerations/pdot-rad_sec2",
              "accelerations/qdot-rad_sec2", "accelerations/rdot-rad_sec2")
# unknowns: alpha (rad), JSBSim throttle, aileron, elevator, rudder (-1..1), bank (rad)
_STEPS = np.array([1e-3, 5e-3, 5e-3, 5e-3, 5e-3, 1e-3])
# residual scale: ft/s^2 for forces, rad/s^2 for moments (both ~ what a 1 % error gives)
_SCALE = np.array([1.0 / FT, 1.0 / FT, 1.0 / FT, 1.0, 1.0, 1.0])


@dataclass(frozen=True, slots=True)
class TrimPoint:
    """Straight and level flight at ``airspeed_m_s`` (true airspeed, still air)."""

    airframe: str
    airspeed_m_s: float
    aoa_rad: float  # = pitch, the flight path being level
    roll_rad: float
    aileron: float  # position commands, -1..1 (+: roll right / nose up / yaw right)
    elevator: float
    rudder: float
    throttle: float  # ESC throttle 0..1 (PWM 1000 + 1000 x throttle us)
    motor_current_a: float
    battery_current_a: float
    battery_voltage_v: float
    residual: float  # largest remaining acceleration, m/s^2 or rad/s^2

    @property
    def pitch_deg(self) -> float:
        return math.degrees(self.aoa_rad)

    def pwm_us(self) -> tuple[float, ...]:
        """Pulse widths for MAIN1.. up to the last channel the airframe uses (1500 us on a
        channel wired to nothing)."""
        af = AIRFRAMES[self.airframe]
        by_prop = {"fcs/aileron-cmd-norm": self.aileron, "fcs/elevator-cmd-norm": self.elevator,
                   "fcs/rudder-cmd-norm": self.rudder}
        used = [ch for ch, o in enumerate(af.outputs) if o is not None]
        widths: list[float] = []
        for ch in range(max(used) + 1):
            out = af.outputs[ch]
            if isinstance(out, Servo):
                widths.append(1500.0 + 500.0 * by_prop[out.prop])
            elif isinstance(out, Motor):
                widths.append(1000.0 + 1000.0 * self.throttle)
            else:
                widths.append(1500.0)
        return tuple(widths)


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
               settle_steps: int = 300, max_iter: int = 20) -> TrimPoint:
    """Find the straight-and-level trim at ``airspeed_m_s``; raises if it does not converge
    (the speed is below the stall or above what the motor can hold)."""
    af = AIRFRAMES[airframe]
    if af.vehicle_class == "multicopter":
        raise ValueError(f"{airframe!r} has no wing to trim")
    lat, lon, alt = PX4_HOME
    fdm = Fdm(af, 0.001, lat, lon, alt, 0.0, agl_m, airspeed_m_s=airspeed_m_s)
    x = fdm.exec
    engine = next(o.engine for o in af.outputs if isinstance(o, Motor))
    thr_prop = f"fcs/throttle-cmd-norm[{engine}]"

    def residual(z: np.ndarray) -> np.ndarray:
        alpha, thr, ail, elev, rud, phi = (float(v) for v in z)
        x["ic/vt-fps"] = airspeed_m_s / FT
        x["ic/alpha-rad"] = alpha
        x["ic/beta-rad"] = 0.0
        x["ic/gamma-rad"] = 0.0
        x["ic/phi-rad"] = phi
        for r in ("ic/p-rad_sec", "ic/q-rad_sec", "ic/r-rad_sec"):
            x[r] = 0.0
        x.run_ic()
        for k in _INTEGRATORS:
            x["simulation/integrator/" + k] = 0
        x[thr_prop] = thr
        x["fcs/aileron-cmd-norm"] = ail
        x["fcs/elevator-cmd-norm"] = elev
        x["fcs/rudder-cmd-norm"] = rud
        for _ in range(settle_steps):
            x.run()
        return np.array([x[p] for p in _RESIDUALS]) / _SCALE

    z = np.array([0.06, 0.5, 0.0, 0.1, 0.0, 0.0])
    r = residual(z)
    for _ in range(max_iter):
        if np.max(np.abs(r)) < 1e-4:
            break
        jac = np.empty((6, 6))
        for j in range(6):
            dz = np.zeros(6)
            dz[j] = _STEPS[j]
            jac[:, j] = (residual(z + dz) - r) / _STEPS[j]
        z = z - np.linalg.solve(jac, r)
        z[1] = min(max(z[1], 0.0), 1.0)
        z[2:5] = np.clip(z[2:5], -1.0, 1.0)
        r = residual(z)
    worst = float(np.max(np.abs(r)))
    if worst > 1e-3 or not 0.0 < z[1] < 1.0 or np.any(np.abs(z[2:5]) >= 1.0):
        raise RuntimeError(f"no straight-and-level trim for {airframe!r} at {airspeed_m_s} m/s "
                           f"(residual {worst:.3g}, commands {np.round(z, 3).tolist()})")
    motor_a = x[f"propulsion/engine[{engine}]/current-amperes"]
    v, i = _pack_steady_v(af, float(z[1]), motor_a)
    return TrimPoint(
        airframe=airframe, airspeed_m_s=airspeed_m_s, aoa_rad=float(z[0]), roll_rad=float(z[5]),
        aileron=float(z[2]), elevator=float(z[3]), rudder=float(z[4]),
        throttle=float(z[1]) * af.motor_max_volts / v, motor_current_a=motor_a,
        battery_current_a=i, battery_voltage_v=v, residual=worst)
