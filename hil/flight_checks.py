"""What a PX4 user looks at after a fixed-wing or VTOL mission, from the world's recorded truth.

The rows are ``hil.flight._Recorder`` rows: (t_s, pos_ned_m, agl_m, euler_rad, lat_deg,
lon_deg, alt_m, airspeed_m_s, aoa_rad), every 50 ms of virtual time; the airspeed is the
equivalent airspeed (what FW_AIRSPD_TRIM means). "Cruise" is the square:
from waypoint 1 reached to the last waypoint reached, where altitude and airspeed are held.
"""

from __future__ import annotations

import math
from typing import Any

from hil.missions import DefaultMission

__all__ = ["VTOL_STATES", "fixed_wing_checks", "vtol_checks"]

#: vtol_vehicle_status.vehicle_vtol_state -> the phase name ``hil.flight`` records ("vtol: ...")
VTOL_STATES: dict[int, str] = {1: "transition to fixed wing", 2: "transition to multicopter",
                               3: "multicopter", 4: "fixed wing"}

#: a row counts as airborne when the IMU is this far above its height on the gear
AIRBORNE_MARGIN_M = 1.0
#: and as touched down when it is within this of it
TOUCHDOWN_MARGIN_M = 0.15


def _phase_t(phases: list[dict[str, Any]], name: str) -> float | None:
    return next((p["t_s"] for p in phases if p["name"] == name), None)


def fixed_wing_checks(mission: DefaultMission, rows: list[tuple], phases: list[dict[str, Any]],
                      airframe: Any, airspeed_target_m_s: float | None = None
                      ) -> dict[str, Any]:
    """Waypoint misses, cruise altitude and airspeed errors, the highest angle of attack
    against the model's stall angle, and where the plane touched down."""
    n = len(mission.waypoints)
    miss = [min((math.hypot(r[1][0] - wn, r[1][1] - we) for r in rows), default=math.inf)
            for wn, we in mission.waypoints]
    t1 = _phase_t(phases, "waypoint 1 reached")
    tn = _phase_t(phases, f"waypoint {n} reached")
    cruise = [r for r in rows if t1 is not None and tn is not None and t1 <= r[0] <= tn]
    alt_err = max((abs(r[2] - mission.altitude_m) for r in cruise), default=math.nan)
    speeds = [r[7] for r in cruise]
    mean_speed = sum(speeds) / len(speeds) if speeds else math.nan
    target = airspeed_target_m_s if airspeed_target_m_s is not None else mean_speed
    speed_err = max((abs(v - target) for v in speeds), default=math.nan)
    gear = float(getattr(airframe, "gear_height_m", 0.0))
    airborne = [r for r in rows if r[2] > gear + AIRBORNE_MARGIN_M]
    max_aoa = max((r[8] for r in airborne), default=math.nan)
    stall = getattr(airframe, "stall_aoa_rad", None)
    touchdown = None
    if tn is not None:
        for r in rows:
            if r[0] > tn and r[2] < gear + TOUCHDOWN_MARGIN_M:
                touchdown = r
                break
    td_n, td_e = mission.touchdown_ne
    return {
        "waypoint_miss_m": [round(d, 2) for d in miss],
        "cruise_max_alt_error_m": round(alt_err, 2),
        "cruise_airspeed_mean_m_s": round(mean_speed, 2),
        "cruise_airspeed_target_m_s": None if target is None else round(target, 2),
        "cruise_max_airspeed_error_m_s": round(speed_err, 2),
        "max_aoa_deg": round(math.degrees(max_aoa), 2),
        "stall_aoa_deg": None if stall is None else round(math.degrees(stall), 2),
        "touchdown_t_s": None if touchdown is None else round(touchdown[0], 2),
        "touchdown_distance_m": (None if touchdown is None else
                                 round(math.hypot(touchdown[1][0] - td_n,
                                                  touchdown[1][1] - td_e), 2)),
    }


def _after(phases: list[dict[str, Any]], name: str, t0: float | None) -> float | None:
    """The first time of phase ``name`` at or after ``t0``."""
    if t0 is None:
        return None
    return next((p["t_s"] for p in phases if p["name"].startswith(name) and p["t_s"] >= t0),
                None)


def vtol_checks(mission: DefaultMission, rows: list[tuple], phases: list[dict[str, Any]],
                airframe: Any, limits: dict[str, float | None]) -> dict[str, Any]:
    """Both transitions' durations against their limits (front: VT_TRANS_TIMEOUT, after which
    PX4 gives up with a quad-chute; back: VT_B_TRANS_DUR, which ends it), whether a quad-chute
    happened, the height lost in the front transition, the waypoints' misses and the cruise
    on the wing, and the highest angle of attack while the wing flew."""
    names = {k: f"vtol: {v}" for k, v in VTOL_STATES.items()}
    t_f0 = _after(phases, names[1], 0.0)
    t_f1 = _after(phases, names[4], t_f0)
    t_b0 = _after(phases, names[2], t_f1)
    t_b1 = _after(phases, names[3], t_b0)
    front = None if t_f0 is None or t_f1 is None else round(t_f1 - t_f0, 2)
    back = None if t_b0 is None or t_b1 is None else round(t_b1 - t_b0, 2)
    f_lim, b_lim = limits.get("VT_TRANS_TIMEOUT"), limits.get("VT_B_TRANS_DUR")
    # a phase is recorded at most 0.2 s (the flight's step) after the state changed
    front_ok = front is not None and (not f_lim or front <= f_lim + 0.2)
    back_ok = back is not None and (b_lim is None or back <= b_lim + 0.4)
    chute = any("quad-chute" in p["name"] for p in phases)
    loss = None
    if t_f0 is not None and t_f1 is not None:
        during = [r[2] for r in rows if t_f0 <= r[0] <= t_f1 + 10.0]
        start = next((r[2] for r in rows if r[0] >= t_f0), None)
        if during and start is not None:
            loss = round(max(0.0, start - min(during)), 2)
    wing = [r for r in rows if t_f1 is not None and r[0] >= t_f1
            and (t_b0 is None or r[0] <= t_b0)]
    miss = [min((math.hypot(r[1][0] - wn, r[1][1] - we) for r in rows), default=math.inf)
            for wn, we in mission.waypoints]
    n = len(mission.waypoints)
    t1 = _phase_t(phases, "waypoint 1 reached")
    tn = _phase_t(phases, f"waypoint {n} reached")
    cruise = [r for r in rows if t1 is not None and tn is not None and t1 <= r[0] <= tn]
    stall = getattr(airframe, "stall_aoa_rad", None)
    return {
        "front_transition_s": front,
        "front_transition_limit_s": f_lim,
        "back_transition_s": back,
        "back_transition_limit_s": b_lim,
        "transitions_ok": front_ok and back_ok,
        "quad_chute": chute,
        "front_transition_height_loss_m": loss,
        "waypoint_miss_m": [round(d, 2) for d in miss],
        "cruise_max_alt_error_m": round(max((abs(r[2] - mission.altitude_m) for r in cruise),
                                            default=math.nan), 2),
        "cruise_airspeed_mean_m_s": round(sum(r[7] for r in cruise) / len(cruise), 2)
        if cruise else None,
        "max_aoa_deg": round(math.degrees(max((r[8] for r in wing), default=math.nan)), 2),
        "stall_aoa_deg": None if stall is None else round(math.degrees(stall), 2),
    }
