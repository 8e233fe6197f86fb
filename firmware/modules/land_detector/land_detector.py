"""Land detector: ``land_detector start multicopter|fixedwing|vtol`` (PX4's module and types).

Fixed wing: see :mod:`firmware.modules.land_detector.fixedwing`. Multicopter (the default when
no type is given): ground contact -> maybe landed -> landed, with hysteresis. VTOL (PX4's
VtolLandDetector): the multicopter's, except that a VTOL flying as a plane or in a transition
(``vehicle_status``) is never landed: its rotors' thrust is low there by design.

A multicopter has no weight-on-wheels switch, so landing is inferred from what the controllers
and the estimator see (PX4's multicopter logic, restated):

* ground contact: armed, not moving horizontally, and either commanded to descend but not
  descending (it hit something) or holding low thrust without vertical motion;
* maybe landed: ground contact and low thrust and no rotation (the vehicle is not fighting to
  stay level), close to the ground if a distance to it is known;
* landed: maybe landed held for long enough.

"Low thrust" is the collective throttle below ``MPC_THR_MIN + (hover - MPC_THR_MIN) *
LNDMC_LOW_T_THR`` (in stabilized/acro modes ``MPC_MANTHR_MIN`` instead of ``MPC_THR_MIN``).
Each stage must hold for a third of ``LNDMC_TRIG_TIME`` to be set and clears at once, so takeoff
is recognised immediately. Disarmed means landed. Free fall: specific force below
``LNDMC_FFALL_THR`` for ``LNDMC_FFALL_TTRI``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

from firmware.modules.land_detector.fixedwing import FW_PARAMS, FixedwingDetector
from firmware.platform.module import UsageError, WorkItemModule
from firmware.platform.params import ParamDef
from firmware.platform.uorb import Subscription
from common.units import G0_M_S2

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["KINDS", "PARAMS", "Hysteresis", "LandDetectorModule"]

#: the vehicle types ``land_detector start`` takes (PX4's; rover, airship not built)
KINDS = ("multicopter", "fixedwing", "vtol")

_G = "Land Detector"


def _p(name: str, default: float, lo: float, hi: float, short: str, unit: str = "",
       decimals: int = 2) -> ParamDef:
    return ParamDef(name, "FLOAT", default, min=lo, max=hi, unit=unit, group=_G, short=short,
                    decimals=decimals)


PARAMS: tuple[ParamDef, ...] = (
    _p("LNDMC_TRIG_TIME", 1.0, 0.1, 10.0, "Time for the three land detection stages", "s", 1),
    _p("LNDMC_Z_VEL_MAX", 0.5, 0.1, 10.0, "Vertical speed below which the vehicle is still",
       "m/s"),
    _p("LNDMC_XY_VEL_MAX", 1.5, 0.1, 10.0, "Horizontal speed below which the vehicle is still",
       "m/s"),
    _p("LNDMC_ROT_MAX", 20.0, 0.1, 180.0, "Rotation rate below which the vehicle is still",
       "deg/s", 1),
    _p("LNDMC_LOW_T_THR", 0.3, 0.0, 1.0, "Low thrust: fraction of the way from min to hover"),
    _p("LNDMC_FFALL_THR", 2.0, 0.1, 10.0, "Specific force below which it is falling", "m/s^2",
       1),
    _p("LNDMC_FFALL_TTRI", 0.3, 0.02, 5.0, "Time of free fall before it is reported", "s"),
)


class Hysteresis:
    """A boolean that turns true after ``set_us`` of true requests and false after
    ``clear_us`` of false requests."""

    __slots__ = ("_pending", "_since", "clear_us", "set_us", "state")

    def __init__(self, state: bool, set_us: int = 0, clear_us: int = 0) -> None:
        self.state = state
        self.set_us = set_us
        self.clear_us = clear_us
        self._since = 0
        self._pending = state

    def update(self, want: bool, now_us: int) -> bool:
        if want == self.state:
            self._pending = want
            return self.state
        if want != self._pending:
            self._pending = want
            self._since = now_us
        hold = self.set_us if want else self.clear_us
        if now_us - self._since >= hold:
            self.state = want
        return self.state

    def force(self, state: bool) -> None:
        self.state = self._pending = state


class LandDetectorModule(WorkItemModule):
    """``land_detector``: publishes vehicle_land_detected at 50 Hz (on change, else at 1 Hz)."""

    NAME = "land_detector"
    DESCRIPTION = "land detector (multicopter, fixedwing, vtol)"
    USAGE = ("start [multicopter|fixedwing|vtol]   the vehicle type's detector "
             "(default multicopter)",)
    WQ = "wq:nav_and_controllers"
    INTERVAL_US = 20_000
    #: STM32F427: a handful of comparisons and three topic copies, ~40 us
    CPU_COST_NS = 40_000
    PARAMS = PARAMS + FW_PARAMS

    @classmethod
    def instantiate(cls, system: System, args: Sequence[str]) -> LandDetectorModule:
        kinds = [a for a in args if not a.startswith("-")]
        if len(kinds) > 1 or (kinds and kinds[0] not in KINDS):
            raise UsageError(f"unknown vehicle type {' '.join(kinds)!r} "
                             f"(one of {', '.join(KINDS)})")
        return cls(system, args)

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        kinds = [a for a in args if a in KINDS]
        self.kind = kinds[0] if kinds else "multicopter"
        self.fw: FixedwingDetector | None = FixedwingDetector() \
            if self.kind == "fixedwing" else None
        self.armed = False
        self.ground_contact = Hysteresis(True)
        self.maybe_landed = Hysteresis(True)
        self.landed = Hysteresis(True)
        self.freefall = Hysteresis(False)
        self.last_publish_us = -(1 << 62)
        self.sub_airspeed: Subscription | None = None

    def _start(self) -> None:
        orb = self.platform.orb
        self.pub = self.advertise("vehicle_land_detected")
        self.msg = orb.new("vehicle_land_detected")
        m = self.msg
        m.landed = m.maybe_landed = m.ground_contact = True
        m.has_low_throttle = m.at_rest = m.close_to_ground_or_skipped_check = True
        self.sub_lpos = self.subscribe("vehicle_local_position")
        self.sub_rate = self.subscribe("vehicle_angular_velocity")
        self.sub_armed = self.subscribe("actuator_armed")
        self.sub_ctl = self.subscribe("actuator_controls_0")
        self.sub_lsp = self.subscribe("vehicle_local_position_setpoint")
        self.sub_mode = self.subscribe("vehicle_control_mode")
        self.sub_hte = self.subscribe("hover_thrust_estimate")
        self.sub_param = self.subscribe("parameter_update")
        self.sub_status = self.subscribe("vehicle_status") if self.kind == "vtol" else None
        if self.fw is not None:
            self.sub_accel = self.subscribe("vehicle_acceleration")
            # the airspeed module's topic (absent from a build without it: no airspeed check)
            self.sub_airspeed = self.subscribe("airspeed") \
                if "airspeed" in orb.registry.topics else None
        self._load_params()
        m.timestamp = self.platform.hrt.absolute_time()
        self.pub.publish(m)

    def _load_params(self) -> None:
        p = self.param
        stage_us = int(p("LNDMC_TRIG_TIME") * 1e6 / 3.0)
        self.ground_contact.set_us = self.maybe_landed.set_us = self.landed.set_us = stage_us
        self.freefall.set_us = int(p("LNDMC_FFALL_TTRI") * 1e6)
        self.z_vel_max = float(p("LNDMC_Z_VEL_MAX"))
        self.xy_vel_max = float(p("LNDMC_XY_VEL_MAX"))
        self.rot_max = float(p("LNDMC_ROT_MAX")) * math.pi / 180.0
        self.low_t_thr = float(p("LNDMC_LOW_T_THR"))
        self.ffall_thr = float(p("LNDMC_FFALL_THR"))
        params = self.system.params
        get = params.get if params is not None else (lambda _n, d=None: d)
        self.thr_min = float(get("MPC_THR_MIN", 0.12))
        self.manthr_min = float(get("MPC_MANTHR_MIN", 0.08))
        self.hover_param = float(get("MPC_THR_HOVER", 0.5))
        if self.fw is not None:
            self.fw.load(p)
            self.landed.set_us = int(p("LNDFW_TRIG_TIME") * 1e6)

    def run(self) -> None:
        now = self.platform.hrt.absolute_time()
        if self.sub_param.updated():
            self.sub_param.update()
            self._load_params()
        armed_msg = self.sub_armed.copy()
        armed = bool(armed_msg.armed) if armed_msg is not None else False
        lp = self.sub_lpos.copy()
        m = self.msg
        if not armed or lp is None:
            for h in (self.ground_contact, self.maybe_landed, self.landed):
                h.force(True)
            self.freefall.force(False)
            m.vertical_movement = m.horizontal_movement = m.rotational_movement = False
            m.has_low_throttle = True
            m.in_descend = False
            m.close_to_ground_or_skipped_check = True
            if self.fw is not None:
                self.fw.reset()
        elif self.fw is not None:
            self._detect_fw(lp, now)
        else:
            self._detect(lp, now)
        changed = (m.landed != self.landed.state or m.maybe_landed != self.maybe_landed.state
                   or m.ground_contact != self.ground_contact.state
                   or m.freefall != self.freefall.state)
        m.landed = self.landed.state
        m.maybe_landed = self.maybe_landed.state
        m.ground_contact = self.ground_contact.state
        m.freefall = self.freefall.state
        m.at_rest = m.landed and not m.rotational_movement and not m.horizontal_movement
        if changed or now - self.last_publish_us >= 1_000_000:
            self.last_publish_us = now
            m.timestamp = now
            self.pub.publish(m)

    def _detect(self, lp, now: int) -> None:
        m = self.msg
        mode = self.sub_mode.copy()
        climb_ctl = bool(mode.flag_control_climb_rate_enabled) if mode is not None else False
        ctl = self.sub_ctl.copy()
        throttle = float(ctl.control[3]) if ctl is not None else 0.0
        hte = self.sub_hte.copy()
        hover = float(hte.hover_thrust) if hte is not None and hte.valid else self.hover_param
        lo = self.thr_min if climb_ctl else self.manthr_min
        low_thrust = throttle <= lo + (hover - lo) * self.low_t_thr
        vertical = abs(lp.vz) > self.z_vel_max
        horizontal = math.hypot(lp.vx, lp.vy) > self.xy_vel_max
        rate = self.sub_rate.copy()
        rotational = False
        if rate is not None:
            wx, wy, wz = rate.xyz
            rotational = wx * wx + wy * wy + wz * wz > self.rot_max * self.rot_max
        lsp = self.sub_lsp.copy()
        vz_sp = float(lsp.vz) if lsp is not None and math.isfinite(lsp.vz) else 0.0
        in_descend = climb_ctl and vz_sp > 0.5 * self.z_vel_max
        hit_ground = in_descend and not vertical
        close = (not lp.dist_bottom_valid) or lp.dist_bottom < 1.0
        fx, fy, fz = lp.ax, lp.ay, lp.az - G0_M_S2
        falling = fx * fx + fy * fy + fz * fz < self.ffall_thr * self.ffall_thr

        gc = not horizontal and (hit_ground or (low_thrust and not vertical))
        if self.sub_status is not None:     # a VTOL on the wing or in transition: flying
            st = self.sub_status.copy()
            if st is not None and (st.in_transition_mode
                                   or st.vehicle_type == st.VEHICLE_TYPE_FIXED_WING):
                gc = False
        self.ground_contact.update(gc, now)
        ml = self.ground_contact.state and low_thrust and not rotational and close
        self.maybe_landed.update(ml, now)
        self.landed.update(self.maybe_landed.state, now)
        self.freefall.update(falling, now)
        m.has_low_throttle = low_thrust
        m.vertical_movement = vertical
        m.horizontal_movement = horizontal
        m.rotational_movement = rotational
        m.in_descend = in_descend
        m.close_to_ground_or_skipped_check = close

    def _detect_fw(self, lp, now: int) -> None:
        """Fixed wing: one landed condition; ground contact and maybe landed follow it."""
        fw = self.fw
        assert fw is not None
        lp_age = now - self.sub_lpos.node.last_publish_ns // 1000
        aspd_sub = self.sub_airspeed
        aspd, aspd_age = None, 1 << 62
        if aspd_sub is not None:
            aspd = aspd_sub.copy()
            aspd_age = now - aspd_sub.node.last_publish_ns // 1000
        landed = fw.landed(lp, lp_age, aspd, aspd_age, self.sub_accel.copy())
        self.landed.update(landed, now)
        self.ground_contact.force(self.landed.state)
        self.maybe_landed.force(self.landed.state)
        self.freefall.force(False)
        m = self.msg
        m.vertical_movement = fw.vel_z_filt >= fw.vel_z_max
        m.horizontal_movement = fw.vel_xy_filt >= fw.vel_xy_max
        m.rotational_movement = False
        m.has_low_throttle = m.in_descend = False
        m.close_to_ground_or_skipped_check = True

    def status_lines(self) -> list[str]:
        m = self.msg
        extra = [self.fw.status_line()] if self.fw is not None else []
        return [f"type: {self.kind}", *extra,
                (f"landed {m.landed} maybe_landed {m.maybe_landed} ground_contact "
                 f"{m.ground_contact} freefall {m.freefall}"),
                (f"low throttle {m.has_low_throttle} vertical {m.vertical_movement} horizontal "
                 f"{m.horizontal_movement} rotational {m.rotational_movement}")]
