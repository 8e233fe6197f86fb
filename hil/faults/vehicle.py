"""Vehicle faults: what breaks or changes in the physics the world simulates.

Each acts on the JSBSim world in the orchestrator (``rig.dev["world"]``) at the quantum
boundary where it starts; the FMU learns of it only through its sensors, its power module's
ADC and the IO's outputs, as on a real vehicle.
"""

from __future__ import annotations

from typing import Any

from hil.faults import FaultError, Rig, fault_kind
from hil.faults._rig import number, vector, world

MOTORS = ("motor1", "motor2", "motor3", "motor4")


def _motor(target: str, fault: str) -> int:
    if target not in MOTORS:
        raise FaultError(f"fault {fault}: target must be one of {', '.join(MOTORS)}, "
                         f"got {target!r}")
    return MOTORS.index(target)


@fault_kind("vehicle.motor_failure", level="vehicle", targets=MOTORS, thrust_fraction=0.0,
            doc="A motor (PX4 quad-X numbering, motor1 = front right) stops producing thrust "
                "whatever its ESC is told: a burnt winding, a dead ESC power stage, a seized "
                "bearing. thrust_fraction > 0 leaves a weak motor with about that share of its "
                "thrust. The rotor spins down, its current and yaw torque go; the vehicle rolls "
                "and pitches towards the dead arm and yaws, which the rate controller fights "
                "with the three others (a quad cannot hold yaw; PX4 has no motor-failure "
                "detection on this airframe, so it tumbles or descends).")
def motor_failure(rig: Rig, target: str, params: dict[str, Any], t_ns: int) -> Any:
    name = "vehicle.motor_failure"
    i = _motor(target, name)
    frac = number(params, "thrust_fraction", name, 0.0, 0.99)
    w = world(rig, name)
    w.fail_motor(i, "motor", frac)
    return i


@motor_failure.stopper
def _motor_failure_stop(rig: Rig, target: str, params: dict[str, Any], t_ns: int,
                        token: Any) -> None:
    world(rig, "vehicle.motor_failure").restore_motor(token)


@fault_kind("vehicle.propeller_loss", level="vehicle", targets=MOTORS,
            doc="A propeller comes off: that rotor's thrust and torque are gone for good, the "
                "motor spins free and draws only its no-load current, so the battery current "
                "the power module measures drops by about a quarter. Cannot be undone.")
def propeller_loss(rig: Rig, target: str, params: dict[str, Any], t_ns: int) -> Any:
    name = "vehicle.propeller_loss"
    w = world(rig, name)
    w.fail_motor(_motor(target, name), "propeller")
    return None


@fault_kind("vehicle.wind", level="vehicle", north_m_s=0.0, east_m_s=5.0, down_m_s=0.0,
            turbulence_m_s=0.0, severity=3,
            doc="Steady wind (the velocity the air moves with, NED) plus optional Dryden "
                "turbulence (JSBSim MIL-HDBK-1797, turbulence_m_s = wind at 20 ft, severity "
                "1..7). The airframe's drag turns it into a force: the position controller "
                "must tilt into the wind, and the estimator sees the drift through GPS.")
def wind(rig: Rig, target: str, params: dict[str, Any], t_ns: int) -> Any:
    name = "vehicle.wind"
    w = world(rig, name)
    n, e, d = (number(params, k, name, -60.0, 60.0) for k in ("north_m_s", "east_m_s",
                                                                "down_m_s"))
    turb = number(params, "turbulence_m_s", name, 0.0, 60.0)
    sev = int(number(params, "severity", name, 1, 7))
    w.set_wind(n, e, d)
    w.set_turbulence(turb, sev)
    return None


@wind.stopper
def _wind_stop(rig: Rig, target: str, params: dict[str, Any], t_ns: int, token: Any) -> None:
    w = world(rig, "vehicle.wind")
    w.set_wind(0.0, 0.0, 0.0)
    w.set_turbulence(0.0)


@fault_kind("vehicle.gust", level="vehicle", north_m_s=8.0, east_m_s=0.0, down_m_s=0.0,
            rise_s=1.0, hold_s=2.0, fall_s=1.0,
            doc="A discrete 1-cosine gust (JSBSim's cosine gust, NED): the extra wind rises "
                "over rise_s, holds, and dies over fall_s. The vehicle is pushed off its "
                "position and the position controller pulls it back.")
def gust(rig: Rig, target: str, params: dict[str, Any], t_ns: int) -> Any:
    name = "vehicle.gust"
    vals = [number(params, k, name, -60.0, 60.0) for k in ("north_m_s", "east_m_s", "down_m_s")]
    times = [number(params, k, name, 0.0, 600.0) for k in ("rise_s", "hold_s", "fall_s")]
    if not any(vals):
        raise FaultError(f"fault {name}: the gust needs a non-zero velocity")
    world(rig, name).gust(*vals, *times)
    return None


@fault_kind("vehicle.battery_low", level="vehicle", soc=0.12,
            doc="The pack holds only `soc` of its charge from now (it was not charged, a cell "
                "lost capacity); it goes on discharging. The open-circuit voltage and the sag "
                "under load follow the LiPo curve; the FMU's battery_status sees the voltage "
                "through the power module's ADC, estimates the remaining charge from it and "
                "raises BAT_LOW_THR / BAT_CRIT_THR / BAT_EMERGEN_THR warnings; the commander "
                "acts per COM_LOW_BAT_ACT. Cannot be undone (charge does not come back).")
def battery_low(rig: Rig, target: str, params: dict[str, Any], t_ns: int) -> Any:
    name = "vehicle.battery_low"
    world(rig, name).battery.force_soc(number(params, "soc", name, 0.0, 1.0))
    return None


@fault_kind("vehicle.battery_dying", level="vehicle", r0_ohm=0.15, soc=-1.0,
            doc="The pack's internal resistance rises to r0_ohm (healthy 0.03 ohm: a damaged "
                "or cold cell, a corroded connector), so its voltage collapses under load; "
                "soc >= 0 also forces the state of charge. The FMU sees the sagging voltage "
                "and rising current-induced drop at its ADC and warns; the motors get less "
                "voltage and the controllers need more throttle.")
def battery_dying(rig: Rig, target: str, params: dict[str, Any], t_ns: int) -> Any:
    name = "vehicle.battery_dying"
    b = world(rig, name).battery
    old = b.r0_ohm
    b.set_r0(number(params, "r0_ohm", name, 0.0, 10.0))
    soc = number(params, "soc", name, -1.0, 1.0)
    if soc >= 0:
        b.force_soc(soc)
    return old


@battery_dying.stopper
def _battery_dying_stop(rig: Rig, target: str, params: dict[str, Any], t_ns: int,
                        token: Any) -> None:
    world(rig, "vehicle.battery_dying").battery.set_r0(token)


@fault_kind("vehicle.mag_interference", level="vehicle", field_body_gauss=(0.0, 0.15, 0.0),
            per_amp_gauss=(0.0, 0.0, 0.0),
            doc="An extra magnetic field at the vehicle, fixed in the body frame: a constant "
                "part (a magnetised part, a tool left on the frame) plus a part proportional "
                "to the battery current (power wires near the compass, what PX4's "
                "CAL_MAG_COMP compensates). Every magnetometer sees it; the estimator's heading "
                "is pulled off and its magnetometer innovations grow.")
def mag_interference(rig: Rig, target: str, params: dict[str, Any], t_ns: int) -> Any:
    name = "vehicle.mag_interference"
    w = world(rig, name)
    old = w.mag_disturbance
    w.mag_disturbance = (vector(params, "field_body_gauss", name),
                         vector(params, "per_amp_gauss", name))
    return old


@mag_interference.stopper
def _mag_interference_stop(rig: Rig, target: str, params: dict[str, Any], t_ns: int,
                           token: Any) -> None:
    world(rig, "vehicle.mag_interference").mag_disturbance = token


@fault_kind("vehicle.geofence_breach", level="vehicle", targets=("pilot", "wind"), stick=0.6,
            speed_m_s=8.0, bearing_deg=0.0,
            doc="The vehicle is carried beyond its geofence (GF_MAX_HOR_DIST / GF_MAX_VER_DIST "
                "from home) the way it happens in the field. Target ``pilot``: the pilot "
                "holds the pitch stick forward (``stick``, -1..1) in a manual mode and flies "
                "out, the classic geofence test; it acts on the transmitter, so the FMU sees "
                "only RC channels. Target ``wind``: a steady wind of ``speed_m_s`` towards "
                "``bearing_deg`` (from north, clockwise) pushes a vehicle flying without "
                "position hold (Altitude, Stabilized) downwind. PX4's geofence check (the "
                "estimator's position, or GPS with GF_SOURCE 1) trips at the boundary and "
                "the commander takes GF_ACTION: warning, Hold, Return, Terminate or Land. "
                "Stopping it centres the stick or calms the wind. (PX4 rejects missions and "
                "GCS repositions beyond the fence, so neither is a way out.)")
def geofence_breach(rig: Rig, target: str, params: dict[str, Any], t_ns: int) -> Any:
    import math

    name = "vehicle.geofence_breach"
    if target == "pilot":
        stick = number(params, "stick", name, -1.0, 1.0)
        rc = rig.dev.get("rc")
        if rc is None:
            raise FaultError(f"fault {name}: target pilot needs an RC transmitter "
                             f"(SystemConfig rc=None)")
        rc.tx.set_sticks(t_ns, pitch=stick, ramp_ns=200_000_000)
        return None
    speed = number(params, "speed_m_s", name, 0.0, 60.0)
    bearing = math.radians(number(params, "bearing_deg", name, -360.0, 360.0))
    world(rig, name).set_wind(speed * math.cos(bearing), speed * math.sin(bearing), 0.0)
    return None


@geofence_breach.stopper
def _geofence_breach_stop(rig: Rig, target: str, params: dict[str, Any], t_ns: int,
                          token: Any) -> None:
    if target == "pilot":
        rig.dev["rc"].tx.set_sticks(t_ns, pitch=0.0, ramp_ns=200_000_000)
    else:
        world(rig, "vehicle.geofence_breach").set_wind(0.0, 0.0, 0.0)
