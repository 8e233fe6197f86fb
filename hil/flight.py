"""``hil run``: the default flight, flown by a ground station in virtual time.

Both boards and the world run in lockstep. A virtual-time GCS (MAVLink over the FMU's network
port) waits for the estimator, uploads a mission (takeoff to 10 m, a square of four waypoints
20 m apart), presses nothing but what a pilot would (the safety switch), arms, starts the
mission, and the vehicle returns and lands by itself; the commander disarms after landing.

The run records the world's truth every 50 ms and the phases' virtual times, then prints a
summary: phases, tracking errors against the planned path, the estimator's errors against truth,
the landing distance from home, and the real-time factor. While it flies it says what it is
doing (hil.progress), and at the start which tier runs (compiled or pure) and how to get the
faster one. The ULog is the FMU's own, written to
the emulated SD card; the PNG is drawn from the recorded truth and estimate.
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hil.accuracy import TruthSample, estimator_accuracy
from hil.airframes import resolve as airframe_info
from hil.flight_checks import VTOL_STATES, fixed_wing_checks, vtol_checks
from hil.gcs import GcsClient, GcsTimeout
from hil.missions import M_PER_DEG_LAT, SQUARE_NE, DefaultMission, mission_for
from hil.native import active as native_active
from hil.native import status as native_status
from hil.progress import Progress
from hil.system import DEFAULT_QUANTUM_NS, SystemConfig, build_system

__all__ = ["FlightConfig", "fly", "main", "SQUARE_NE"]

NS_PER_S = 1_000_000_000
#: sea-level air density of the standard atmosphere (equivalent airspeed)
RHO0_KG_M3 = 1.225


@dataclass
class FlightConfig:
    seed: int = 1
    out_dir: str = "out"
    airframe: int = 4011
    quantum_ns: int = DEFAULT_QUANTUM_NS  # 500 us, see hil.system
    speed: float | None = None
    mode: str = "process"
    altitude_m: float = 10.0
    timeout_s: float = 240.0            # virtual seconds for the whole flight
    #: end the flight this many virtual seconds after the start (None: fly it to the end); for
    #: checks that need only the start of a flight, such as byte-identical logs per seed
    stop_after_s: float | None = None
    params: dict[str, Any] = field(default_factory=dict)
    progress: bool = True
    plot: bool = True
    keep_truth: bool = False            # return the recorded truth in the summary ("truth")
    pipeline: bool = True               # lookahead lockstep (see Orchestrator._step_pipelined)
    pin_cpus: bool = True               # the FMU on a CPU of its own (hil.cpu_plan)
    trace_path: str | None = None       # write a lockstep trace (hil.trace) of every board
    can_escs: bool = False              # motors on DroneCAN ESCs (hil.system.SystemConfig); the
                                        # summary then has "can1", "outputs_at_takeoff" and
                                        # "uavcan_status"
    #: a companion computer on TELEM2 with the uORB bridge (hil.system.SystemConfig); the
    #: summary then has "companion" (the bridge's counters on both sides)
    companion: bool = False
    companion_att: bool = False         # the attitude law on the companion (implies companion)
    ros: bool = False                   # the companion's topics on ROS 1 (implies companion)


class _Recorder:
    """Samples the world's truth every 50 ms of virtual time."""

    def __init__(self, world: Any) -> None:
        self.world = world
        self.next_ns = 0
        #: (t_s, pos_ned_m, agl_m, euler_rad, lat_deg, lon_deg, alt_m, airspeed_m_s, aoa_rad);
        #: the airspeed is the equivalent airspeed sqrt(2 q / rho0), what a pitot measures and
        #: what PX4's FW_AIRSPD_* parameters mean
        self.rows: list[tuple] = []

    def __call__(self, orch: Any) -> None:
        if orch.t_ns < self.next_ns:
            return
        self.next_ns = orch.t_ns + 50_000_000
        tr = self.world.truth()
        self.rows.append((orch.t_ns / NS_PER_S, tr.pos_ned_m, tr.agl_m, tr.euler_rad,
                          tr.lat_deg, tr.lon_deg, tr.alt_m,
                          math.sqrt(2.0 * max(tr.diff_pressure_pa, 0.0) / RHO0_KG_M3),
                          tr.aoa_rad))


def tier_line() -> str:
    """Which tier this run uses, and how to get the faster one: said once, at the start, so a
    new user flies at once on the pure modules and knows what the compiled tier would buy."""
    if native_active():
        return "compiled tier (mypyc; HIL_PURE=1 runs the pure modules)"
    state = native_status()[0]
    why = "stale: the sources changed since it was built" if state == "stale" else "not built"
    return (f"pure Python (compiled tier {why}; `make native` or `hil native build` compiles "
            "its fast modules in a few minutes, then runs go ~1.3x faster)")


def _dist_to_segment(p: tuple[float, float], a: tuple[float, float],
                     b: tuple[float, float]) -> float:
    ax, ay = a
    bx, by = b
    dx, dy = bx - ax, by - ay
    L2 = dx * dx + dy * dy
    t = 0.0 if L2 == 0 else max(0.0, min(1.0, ((p[0] - ax) * dx + (p[1] - ay) * dy) / L2))
    return math.hypot(p[0] - (ax + t * dx), p[1] - (ay + t * dy))


def fly(cfg: FlightConfig) -> dict[str, Any]:
    """Fly the airframe's default mission; returns the summary (see module docstring)."""
    frame = airframe_info(cfg.airframe)
    mission = mission_for(frame.vehicle_class)
    fixed_wing = frame.vehicle_class == "fixedwing"
    vtol = frame.vehicle_class == "vtol"
    altitude_m = cfg.altitude_m if not (fixed_wing or vtol) else mission.altitude_m
    # Return at the mission's altitude (PX4's default RTL_RETURN_ALT of 60 m would climb).
    params = {"SDLOG_MODE": 0, "EKF2_MAG_DECL": 2.6, "RTL_RETURN_ALT": altitude_m,
              "RTL_DESCEND_ALT": altitude_m, **cfg.params}
    scfg = SystemConfig(seed=cfg.seed, out_dir=cfg.out_dir, airframe=cfg.airframe,
                        quantum_ns=cfg.quantum_ns, mode=cfg.mode, speed=cfg.speed,
                        params=params, gcs=True, pipeline=cfg.pipeline,
                        pin_cpus=cfg.pin_cpus, trace_path=cfg.trace_path,
                        can_escs=cfg.can_escs, companion=cfg.companion,
                        companion_att=cfg.companion_att, ros=cfg.ros)
    with_companion = cfg.companion or cfg.companion_att or cfg.ros
    progress = Progress(enabled=cfg.progress)
    if cfg.progress:
        boards = "FMU + IO + companion" if with_companion else "FMU + IO"
        print(f"hil run: Pixhawk 1 ({boards} processes) flying the {frame.title} "
              f"({frame.host.world_model} JSBSim model), seed {cfg.seed}; {tier_line()}",
              flush=True)
    progress.doing("starting the FMU, IO and companion board processes" if with_companion
                   else "starting the FMU and IO board processes")
    orch, dev = build_system(scfg)
    orch.on_quantum.append(progress)
    gcs: GcsClient = dev["gcs"]
    world = dev["world"].world
    rec = _Recorder(world)
    orch.on_quantum.append(rec)
    phases: list[dict[str, Any]] = []
    S = NS_PER_S
    n_wp = len(mission.waypoints)

    def phase(name: str, then: str | None = None) -> None:
        """A phase reached (recorded for the summary and printed), and what comes next."""
        phases.append({"name": name, "t_s": round(orch.t_ns / S, 3)})
        progress.t_ns = orch.t_ns
        progress.event(name)
        if then is not None:
            progress.activity = then

    wall0 = time.perf_counter()
    home = (47.397742, 8.545594)
    with orch:
        gcs.attach(orch)
        progress.doing("booting: rcS, drivers, estimator, px4io link (waiting for a heartbeat)")
        gcs.wait_heartbeat(timeout_s=10.0)
        phase("booted (heartbeat)", then="waiting for a GPS fix and the estimator's position")
        gcs.wait_for(lambda: (gcs.last.get("HOME_POSITION") is not None
                              or _estimator_ready(gcs)), timeout_s=60.0)
        phase("estimator ready (GPS position)")
        progress.doing("uploading the mission; the pilot presses the safety switch")
        # The IO takes the button only once the FMU says it is ready to arm (IO_ARM_OK): the
        # pilot presses when the vehicle is ready, as with the real safety LED.
        dev["safety"].press(orch.t_ns + S // 10, hold_s=1.5)
        gp = gcs.last.get("GLOBAL_POSITION_INT")
        if gp is not None:
            home = (gp.lat * 1e-7, gp.lon * 1e-7)
        if fixed_wing or vtol:
            items: list[Any] = mission.items(home[0], home[1], gcs.target_system,
                                             gcs.target_component)
        else:  # the tuples the quadrotor's flight has always sent (same bytes, same logs)
            m_per_deg_lon = M_PER_DEG_LAT * math.cos(math.radians(home[0]))
            items = [(home[0], home[1], cfg.altitude_m, 22)]  # NAV_TAKEOFF
            for n, e in mission.waypoints:
                items.append((home[0] + n / M_PER_DEG_LAT, home[1] + e / m_per_deg_lon,
                              cfg.altitude_m, 16))
            items.append((home[0], home[1], cfg.altitude_m, 20))  # NAV_RETURN_TO_LAUNCH
        result = gcs.upload_mission(items)
        if result != 0:
            raise RuntimeError(f"mission upload refused (MISSION_ACK type {result})")
        phase(f"mission uploaded ({mission.description})",
              then="waiting for the safety switch to be off")
        try:
            gcs.wait_for(lambda: _safety_off(orch), timeout_s=10.0)
        except GcsTimeout:
            rc, why = orch.call("fmu", "shell", "commander check")
            raise RuntimeError("the safety switch stayed on: the IO takes the button only "
                               "when the FMU is ready to arm; commander check says: "
                               + " / ".join(ln.strip() for ln in why.splitlines()
                                            if "Fail" in ln)) from None
        phase("safety switch off")
        progress.doing("arming")
        ack = gcs.arm(timeout_s=5.0)
        if ack.result != 0:
            raise RuntimeError(f"arming refused: {gcs.last.get('STATUSTEXT')}")
        phase("armed", then=f"mission: taking off to {altitude_m:.0f} m")
        gcs.start_mission()
        t_takeoff = None
        outputs: dict[str, Any] | None = None
        reached: set[int] = set()
        seq0 = mission.first_waypoint_seq
        vtol_state = 3          # vtol_vehicle_status: the VTOL starts as a multicopter
        # a plane counts as up near its cruise altitude, a multicopter within 0.5 m of it
        up_m = altitude_m - (5.0 if fixed_wing else 0.5)
        deadline = orch.t_ns + int(cfg.timeout_s * S)
        stop_ns = None if cfg.stop_after_s is None else int(cfg.stop_after_s * S)
        while orch.t_ns < deadline:
            gcs.step(0.2)
            agl = world.truth().agl_m
            if t_takeoff is None and agl > up_m:
                t_takeoff = orch.t_ns
                if cfg.can_escs:  # which outputs drive the motors in the climb
                    outputs = {"io_pwm": orch.call("io", "pwm"),
                               "io_should_arm": orch.call("io", "status").get("should_arm"),
                               "can_esc": [orch.call("fmu", "port_level", f"can_esc{i}")
                                           for i in range(1, 5)]}
                phase(f"takeoff: reached {altitude_m:.0f} m",
                      then="mission: flying to waypoint 1")
            for m in gcs.messages("MISSION_ITEM_REACHED", since=max(0, gcs.mark() - 200)):
                wp = m.seq - seq0 + 1
                if 1 <= wp <= n_wp and wp not in reached:
                    reached.add(wp)
                    phase(f"waypoint {wp} reached",
                          then=(f"mission: flying to waypoint {wp + 1}"
                                if wp < n_wp else
                                "mission: returning home and landing"))
            if vtol:   # the VTOL module's state, as its log has it (vtol_vehicle_status)
                st = orch.call("fmu", "topic", "vtol_vehicle_status")
                if st and int(st["vehicle_vtol_state"]) != vtol_state:
                    vtol_state = int(st["vehicle_vtol_state"])
                    chute = " (quad-chute)" if st["fixed_wing_system_failure"] else ""
                    phase(f"vtol: {VTOL_STATES.get(vtol_state, vtol_state)}{chute}")
            hb = gcs.last.get("HEARTBEAT")
            armed = bool(hb and hb.base_mode & 128)
            if t_takeoff is not None and not armed:
                phase("landed and disarmed")
                break
            if stop_ns is not None and orch.t_ns >= stop_ns:
                phase(f"stopped after {cfg.stop_after_s:g} s (stop_after_s)")
                break
        else:
            raise RuntimeError(f"flight did not finish within {cfg.timeout_s} virtual s")
        rtf = orch.rtf
        cpus = orch.cpu_plan.describe() if orch.cpu_plan is not None else None
        can1 = orch.call("fmu", "can_stats", "CAN1") if cfg.can_escs else None
        uavcan = orch.call("fmu", "shell", "uavcan status")[1] if cfg.can_escs else None
        trim_m_s = _param_value(orch, "FW_AIRSPD_TRIM") if fixed_wing else None
        vt_limits = {n: _param_value(orch, n) for n in ("VT_TRANS_TIMEOUT", "VT_B_TRANS_DUR")} \
            if vtol else {}
        companion = None
        if with_companion:
            from hil.companion_system import companion_summary

            companion = companion_summary(orch)
    wall = time.perf_counter() - wall0
    summary = _summary(cfg, mission, altitude_m, rec.rows, phases, reached, home, rtf, wall)
    summary["airframe"] = frame.as_json()
    summary["mission_altitude_m"] = altitude_m
    if fixed_wing:
        summary.update(fixed_wing_checks(mission, rec.rows, phases, world.airframe, trim_m_s))
    if vtol:
        summary.update(vtol_checks(mission, rec.rows, phases, world.airframe, vt_limits))
    summary["cpus"] = cpus
    if cfg.can_escs:
        summary["can1"] = can1                   # CAN1 and its ESC nodes' counters at the end
        summary["outputs_at_takeoff"] = outputs
        summary["uavcan_status"] = uavcan
    if with_companion:
        summary["companion"] = companion
    return summary


def _param_value(orch: Any, name: str) -> float | None:
    """A parameter's value from the FMU's shell (None if the build does not have it)."""
    rc, text = orch.call("fmu", "shell", f"param get {name}")
    try:
        return float(text.strip()) if rc == 0 else None
    except ValueError:
        return None


def _estimator_ready(gcs: GcsClient) -> bool:
    gp = gcs.last.get("GPS_RAW_INT")
    return gp is not None and gp.fix_type >= 3 and gcs.last.get("GLOBAL_POSITION_INT") is not None


def _safety_off(orch: Any) -> bool:
    io = orch.call("fmu", "topic", "px4io_status")
    return bool(io and io["status_safety_off"])


def _summary(cfg: FlightConfig, mission: DefaultMission, altitude_m: float, rows: list[tuple],
             phases: list[dict], reached: set[int], home: tuple[float, float], rtf: float,
             wall: float) -> dict[str, Any]:
    t_of = {p["name"]: p["t_s"] for p in phases}
    t_top = next((p["t_s"] for p in phases if p["name"].startswith("takeoff")), None)
    square = mission.waypoints
    t_wp4 = next((p["t_s"] for p in phases if p["name"] == f"waypoint {len(square)} reached"),
                 None)
    t_wp1 = next((p["t_s"] for p in phases if p["name"] == "waypoint 1 reached"), None)
    legs = list(zip(square, square[1:]))
    max_h = max_v = 0.0
    for t, pos, agl, *_ in rows:
        if t_top is not None and t_wp4 is not None and t_top <= t <= t_wp4:
            max_v = max(max_v, abs(agl - altitude_m))
        if t_wp1 is not None and t_wp4 is not None and t_wp1 <= t <= t_wp4:
            d = min(_dist_to_segment((pos[0], pos[1]), a, b) for a, b in legs)
            max_h = max(max_h, d)
    last = rows[-1] if rows else None
    landed_dist = math.hypot(last[1][0], last[1][1]) if last else float("nan")
    log = _newest_log(Path(cfg.out_dir) / "sd" / "log")
    acc = None
    t_armed = t_of.get("armed")
    t_landed = next((p["t_s"] for p in phases if p["name"].startswith("landed")), None)
    truth = [TruthSample(r[0], r[4], r[5], r[6], tuple(r[3])) for r in rows]
    if log is not None and t_armed is not None and t_landed is not None:
        acc = estimator_accuracy(str(log), truth, t_armed, t_landed)
    summary: dict[str, Any] = {
        "rtf": round(rtf, 2),
        "wall_s": round(wall, 1),
        "compiled": native_active(),
        "log": str(log) if log else None,
        "landed_distance_m": round(landed_dist, 2),
        "max_alt_error_m": round(max_v, 3),
        "max_track_error_m": round(max_h, 3),
        "waypoints_reached": sorted(reached),
        "attitude_error_rms_deg": round(acc.attitude_rms_deg, 3) if acc else None,
        "attitude_error_max_deg": round(acc.attitude_max_deg, 2) if acc else None,
        "tilt_error_max_deg": round(acc.tilt_max_deg, 2) if acc else None,
        "position_error_rms_m": round(acc.position_rms_m, 3) if acc else None,
        "position_error_max_m": round(acc.position_max_m, 2) if acc else None,
        "phases": phases,
        "seed": cfg.seed,
    }
    if cfg.keep_truth:
        summary["truth"] = [(t.t_s, t.lat_deg, t.lon_deg, t.alt_m, *t.euler_rad) for t in truth]
    if cfg.plot and rows:
        summary["plot"] = str(_plot(cfg, mission, altitude_m, rows))
    return summary


def _newest_log(root: Path) -> Path | None:
    logs = sorted(root.rglob("*.ulg"), key=lambda p: p.stat().st_mtime) if root.exists() else []
    return logs[-1] if logs else None


def _plot(cfg: FlightConfig, mission: DefaultMission, altitude_m: float, rows: list[tuple]
          ) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = [r[0] for r in rows]
    n = [r[1][0] for r in rows]
    e = [r[1][1] for r in rows]
    agl = [r[2] for r in rows]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.5))
    ax1.plot(e, n, label="flown (truth)")
    sq = list(mission.waypoints) + [mission.waypoints[0]]
    ax1.plot([p[1] for p in sq], [p[0] for p in sq], "k:", label="mission")
    ax1.plot([0], [0], "g^", label="home")
    ax1.set_xlabel("east (m)")
    ax1.set_ylabel("north (m)")
    ax1.set_aspect("equal")
    ax1.legend(loc="best")
    ax2.plot(t, agl, label="height above ground (truth)")
    ax2.axhline(altitude_m, color="k", ls=":", lw=0.8)
    ax2.set_xlabel("virtual time (s)")
    ax2.set_ylabel("m")
    ax2.legend(loc="best")
    fig.suptitle(f"fmu-hil default flight, seed {cfg.seed}")
    fig.tight_layout()
    out = Path(cfg.out_dir) / "flight.png"
    fig.savefig(out, dpi=90)
    plt.close(fig)
    return out


def main(cfg: FlightConfig, as_json: bool = False) -> int:
    try:
        summary = fly(cfg)
    except (RuntimeError, GcsTimeout) as exc:
        print(f"hil run: {exc}", file=sys.stderr)
        return 1
    if as_json:
        print(json.dumps(summary))
        return 0
    print("summary:")
    for p in summary["phases"]:
        print(f"  {p['t_s']:8.2f} s  {p['name']}")
    print(f"  max altitude error at {summary['mission_altitude_m']:.0f} m: "
          f"{summary['max_alt_error_m']:.2f} m; max track error on the square: "
          f"{summary['max_track_error_m']:.2f} m")
    if "touchdown_distance_m" in summary:
        print(f"  waypoints passed within {summary['waypoint_miss_m']} m; cruise airspeed "
              f"{summary['cruise_airspeed_mean_m_s']} m/s (target "
              f"{summary['cruise_airspeed_target_m_s']}, max error "
              f"{summary['cruise_max_airspeed_error_m_s']}); highest angle of attack "
              f"{summary['max_aoa_deg']} deg (stall {summary['stall_aoa_deg']}); touched down "
              f"{summary['touchdown_distance_m']} m from the landing point")
    if "front_transition_s" in summary:
        print(f"  VTOL: front transition {summary['front_transition_s']} s (VT_TRANS_TIMEOUT "
              f"{summary['front_transition_limit_s']} s), back transition "
              f"{summary['back_transition_s']} s; quad-chute: {summary['quad_chute']}; "
              f"waypoints passed within {summary['waypoint_miss_m']} m; highest angle of "
              f"attack on the wing {summary['max_aoa_deg']} deg (stall "
              f"{summary['stall_aoa_deg']})")
    print(f"  estimator vs truth (its own log): attitude rms {summary['attitude_error_rms_deg']}"
          f" deg, tilt max {summary['tilt_error_max_deg']} deg, position rms "
          f"{summary['position_error_rms_m']} m, max {summary['position_error_max_m']} m")
    print(f"  landed {summary['landed_distance_m']:.2f} m from home")
    if summary.get("can1"):
        nodes = summary["can1"]["nodes"].values()
        print(f"  motors on CAN ESCs: RawCommands received {[n['commands_rx'] for n in nodes]}, "
              f"esc.Status sent {[n['status_tx'] for n in nodes]}, CAN error frames "
              f"{summary['can1']['error_frames']}")
    if summary.get("companion"):
        from hil.companion_system import format_companion

        print(format_companion(summary["companion"]))
    tier = ("compiled tier" if summary["compiled"]
            else "pure Python; `make native` compiles the fast modules, ~1.3x faster")
    cpus = summary.get("cpus") or "CPUs not pinned"
    print(f"  real-time factor {summary['rtf']:.1f} ({summary['wall_s']:.0f} s of wall time, "
          f"{tier}; {cpus})")
    print(f"  log: {summary['log']}")
    if summary.get("plot"):
        print(f"  plot: {summary['plot']}")
    return 0
