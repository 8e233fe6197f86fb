"""A closed loop for the fixed-wing controllers: the world's plane (JSBSim StickPlane), the FMU
board without drivers, the test-only truth estimator (tests/flight/truth_estimator.py) and an
airspeed stub, the AETR mixer straight onto the world's servos and ESC (hil.sil), and
test-side stand-ins for the commander and navigator (control mode, arming, setpoints).

The airspeed stub publishes what the airspeed module will (``airspeed`` at 20 Hz: indicated
from the world's dynamic pressure at sea-level density, true from the world), so the
controllers fly on airspeed as they will on the boards.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

from firmware.platform import Platform
from firmware.platform.workqueue import WorkItem
from common.truth import Truth
from tests.flight.truth_estimator import TruthEstimator

__all__ = ["FW_MODULES", "FwRig", "PLANE_PARAMS"]

FW_MODULES = {
    "fw_att_control": "firmware.modules.fw_att_control:FwAttControlModule",
    "fw_pos_control_l1": "firmware.modules.fw_pos_control_l1:FwPosControlL1Module",
}

#: the gains this package's closed-loop tests fly the StickPlane with (the values for the
#: 2100 airframe file); everything else keeps PX4's defaults
PLANE_PARAMS: dict[str, float] = {
    # StickPlane: 1 g stall at 10.3 m/s (StickPlane.xml); hil.world.trim: level at 16 m/s on
    # throttle 0.57, pitch 3.9 deg
    "FW_AIRSPD_MIN": 13.0, "FW_AIRSPD_TRIM": 16.0, "FW_AIRSPD_MAX": 24.0,
    "FW_THR_CRUISE": 0.57,
    # hil.world.trim at 16 m/s: elevator 0.21, aileron 0.015 (the propeller's torque)
    "TRIM_PITCH": 0.21, "TRIM_ROLL": 0.015,
    # roll rate feed-forward: 0.35 gives the commanded roll rate in acro (0.5 gives 1.25x)
    "FW_RR_FF": 0.35,
    # full throttle climbs at ~3.5 m/s at trim speed: PX4 wants the climb limit reachable
    "FW_T_CLMB_MAX": 3.0,
}

AETR = (Path(__file__).resolve().parents[3] / "firmware" / "romfs" / "mixers"
        / "AETR.main.mix").read_text()
RHO0 = 1.225


_TRIM_CACHE: dict[float, float] = {}


def _trim_pitch_deg(airspeed_m_s: float) -> float:
    """The plane's straight-and-level pitch at this airspeed (hil.world.trim), cached."""
    if airspeed_m_s not in _TRIM_CACHE:
        from hil.world.trim import trim_level
        _TRIM_CACHE[airspeed_m_s] = trim_level(airspeed_m_s=airspeed_m_s).pitch_deg
    return _TRIM_CACHE[airspeed_m_s]


class AirspeedStub(WorkItem):
    """``airspeed`` from the world's truth at 20 Hz (the airspeed module's topic)."""

    def __init__(self, platform: Platform, truth: Callable[[], Truth]) -> None:
        super().__init__(platform, "airspeed_stub", "wq:lp_default")
        self.truth = truth
        self.pub = platform.orb.advertise("airspeed")
        self.msg = platform.orb.new("airspeed")
        self.valid = True

    def run(self) -> None:
        tr = self.truth()
        m = self.msg
        m.timestamp = self.platform.hrt.absolute_time()
        m.indicated_airspeed_m_s = math.sqrt(2.0 * max(tr.diff_pressure_pa, 0.0) / RHO0)
        m.true_airspeed_m_s = tr.airspeed_m_s
        m.air_temperature_celsius = 15.0
        m.confidence = 1.0 if self.valid else 0.0
        self.pub.publish(m)


class FwRig:
    """World plane + FMU + truth estimator + airspeed stub + the fixed-wing modules."""

    def __init__(self, params: dict[str, float] | None = None, agl_m: float = 100.0,
                 airspeed_m_s: float = 15.0, seed: int = 0,
                 modules: tuple[str, ...] = tuple(FW_MODULES)) -> None:
        from firmware.platform.module import ModuleRegistry
        from firmware.platform.params import Params
        from firmware.system import System
        from hil.sil import Sil
        from hil.world import World

        pitch_deg = 0.0
        if airspeed_m_s > 0.0:   # start in straight and level flight, not in a dive
            pitch_deg = _trim_pitch_deg(airspeed_m_s)
        world = World(seed=seed, airframe="plane", agl_m=agl_m, airspeed_m_s=airspeed_m_s,
                      pitch_deg=pitch_deg)
        self.sil = Sil(seed=seed, world=world, firmware="none", mixer_text=AETR)
        p = self.platform = self.sil.fmu.platform
        reg = ModuleRegistry(None, FW_MODULES)
        self.params = Params(p, reg.param_defs(list(FW_MODULES)))
        for k, v in {**PLANE_PARAMS, **(params or {})}.items():
            self.params.set(k, v, notify=False)
        self.system = System(p, self.params, modules=reg)
        w = self.sil.world
        self.ref = (w._lat0, w._lon0, w._alt0)
        self.est = TruthEstimator(p, w.truth, self.ref)
        self.est.start()
        self.asp = AirspeedStub(p, w.truth)
        self.asp.schedule_on_interval(50_000)
        orb = p.orb
        self.pub_armed = orb.advertise("actuator_armed")
        self.pub_mode = orb.advertise("vehicle_control_mode")
        self.pub_trip = orb.advertise("position_setpoint_triplet")
        self.pub_man = orb.advertise("manual_control_setpoint")
        self.pub_land = orb.advertise("vehicle_land_detected")
        self.armed_msg = orb.new("actuator_armed")
        self.mode_msg = orb.new("vehicle_control_mode")
        self.trip_msg = orb.new("position_setpoint_triplet")
        self.man_msg = orb.new("manual_control_setpoint")
        self.land_msg = orb.new("vehicle_land_detected")
        for name in modules:
            if self.system.modules.start(name) != 0:
                raise RuntimeError(f"{name} did not start: {self.system.console_lines[-3:]}")
        self._prime_esc()

    def _prime_esc(self) -> None:
        """The ESC arms only after 0.1 s of low pulses (hil/world/esc.py): give it 0.15 s
        of them, the surfaces centred, before the controllers' outputs take over."""
        w = self.sil.world

        def low(_sil: object) -> None:
            for ch in range(4):
                w.set_pwm(ch, w.t_ns, (1000 if ch == 2 else 1500) * 1000, 2_500_000)

        self.sil.hooks.append(low)
        for _ in range(150):
            self.sil.step()
        self.sil.hooks.remove(low)

    def now_us(self) -> int:
        return self.platform.hrt.absolute_time()

    def arm(self, armed: bool = True) -> None:
        m = self.armed_msg
        m.timestamp, m.armed, m.ready_to_arm = self.now_us(), armed, True
        self.pub_armed.publish(m)

    def set_landed(self, landed: bool) -> None:
        m = self.land_msg
        m.timestamp, m.landed = self.now_us(), landed
        self.pub_land.publish(m)

    def set_mode(self, mode: str) -> None:
        """``auto``, ``position``, ``altitude``, ``stabilized``, ``acro`` or ``manual``."""
        m = self.mode_msg
        m.timestamp = self.now_us()
        m.flag_armed = self.armed_msg.armed
        m.flag_control_manual_enabled = mode != "auto"
        m.flag_control_auto_enabled = mode == "auto"
        m.flag_control_rates_enabled = mode != "manual"
        m.flag_control_attitude_enabled = mode not in ("manual", "acro")
        pos = mode in ("auto", "position")
        alt = pos or mode == "altitude"
        m.flag_control_position_enabled = m.flag_control_velocity_enabled = pos
        m.flag_control_altitude_enabled = m.flag_control_climb_rate_enabled = alt
        self.pub_mode.publish(m)

    def set_sticks(self, roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.0,
                   throttle: float = 0.0) -> None:
        m = self.man_msg
        m.timestamp = m.timestamp_sample = self.now_us()
        m.valid, m.data_source = True, 1
        m.roll, m.pitch, m.yaw, m.throttle = roll, pitch, yaw, throttle
        self.pub_man.publish(m)

    def set_setpoint(self, kind: int, north_m: float, east_m: float, alt_rel_m: float,
                     prev: tuple[float, float, float] | None = None, loiter_radius: float = 0.0,
                     yaw: float = math.nan) -> None:
        """current (and previous) setpoint in local north/east metres, altitude above the
        world's start point."""
        m = self.trip_msg
        m.timestamp = self.now_us()
        lat, lon = self.est.proj.reproject(north_m, east_m)
        c = m.current
        c.timestamp, c.valid, c.type = m.timestamp, True, kind
        c.lat, c.lon, c.alt = lat, lon, self.ref[2] + alt_rel_m
        c.yaw, c.yaw_valid = yaw, math.isfinite(yaw)
        c.loiter_radius, c.acceptance_radius = loiter_radius, 15.0
        c.cruising_speed = c.cruising_throttle = -1.0
        p = m.previous
        if prev is None:
            p.valid = False
        else:
            plat, plon = self.est.proj.reproject(prev[0], prev[1])
            p.timestamp, p.valid, p.type = m.timestamp, True, 0
            p.lat, p.lon, p.alt = plat, plon, self.ref[2] + prev[2]
        self.pub_trip.publish(m)

    def topic(self, name: str):
        return self.platform.orb.node(name).last

    def truth(self) -> Truth:
        return self.sil.world.truth()

    def local(self) -> tuple[float, float, float]:
        """True north, east (m from the start) and height above the start point."""
        tr = self.truth()
        n, e = self.est.proj.project(tr.lat_deg, tr.lon_deg)
        return n, e, tr.alt_m - self.ref[2]

    def run(self, seconds: float, every: Callable[[FwRig], None] | None = None,
            every_n: int = 100) -> None:
        sil = self.sil
        for i in range(round(seconds * 1000)):
            sil.step()
            if every is not None and i % every_n == 0:
                every(self)
