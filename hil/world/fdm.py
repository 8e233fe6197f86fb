"""JSBSim flight dynamics: airframe registry, initial conditions and cached property nodes.

JSBSim works in imperial units; everything leaving this module is SI. Properties read or
written every step go through ``FGPropertyNode`` objects resolved once at load time
(get/set_double_value ~0.08 us per call against ~0.16 us for ``fdm['name']`` reads and ~0.6 us
for ``fdm['name'] = x`` writes, JSBSim 1.3).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

# JSBSim prints a banner and load chatter unless told otherwise; read when the FGFDMExec
# is constructed. Respect an explicit setting by the user.
os.environ.setdefault("JSBSIM_DEBUG", "0")

import jsbsim  # noqa: E402

from .battery import BatteryParams  # noqa: E402
from common.units import G0_M_S2

__all__ = ["Airframe", "AIRFRAMES", "Fdm", "FT", "LBF_N", "PSF_PA", "Motor", "Servo",
           "N_MAIN", "N_AUX", "N_CHANNELS"]

FT = 0.3048  # m per ft
LBF_N = 4.4482216152605  # N per lbf
PSF_PA = 47.880258980335840  # Pa per lbf/ft^2
HP_W = 745.69987158227022  # W per hp

MODELS_DIR = Path(__file__).resolve().parent / "models"


#: PWM channels the world takes: MAIN1..8 (the IO's outputs, world channels 0..7) and AUX1..6
#: (the FMU's own outputs, world channels 8..13).
N_MAIN = 8
N_AUX = 6
N_CHANNELS = N_MAIN + N_AUX


@dataclass(frozen=True, slots=True)
class Motor:
    """A PWM channel that drives JSBSim engine ``engine`` through an ESC (hil/world/esc.py)."""

    engine: int


@dataclass(frozen=True, slots=True)
class Servo:
    """A PWM channel that drives a hobby servo: 1500 us is the centre, 1000..2000 us is -1..+1
    of full throw, written to the JSBSim property ``prop`` (the servo's dynamics - lag, rate
    limit - are an actuator in the model's flight-control section). ``throw_rad`` is the
    surface deflection at +-1, for documentation and tests."""

    prop: str
    throw_rad: float


Output = Motor | Servo | None


@dataclass(frozen=True, slots=True)
class Airframe:
    """What the world needs to know about a JSBSim model beyond the model itself."""

    name: str
    model: str  # JSBSim model name (directory and file under models/aircraft/)
    #: what each world PWM channel drives (index 0..13: MAIN1..8, AUX1..6); None: nothing
    outputs: tuple[Output, ...]
    gear_height_m: float  # IMU height above the ground with the gear just touching
    gear_stiffness_n_m: float  # sum of the contact spring rates (static deflection at start)
    mass_kg: float
    motor_max_volts: float  # the JSBSim motor's MaxVolts: throttle 1 applies this voltage
    #: "multicopter", "fixedwing" or "vtol" (PX4's classes)
    vehicle_class: str = "multicopter"
    #: angle of attack of maximum lift (rad); None for a vehicle without a wing
    stall_aoa_rad: float | None = None
    #: the airframe's flight pack
    battery: BatteryParams = field(default_factory=BatteryParams)
    #: engine that pulls the vehicle forward in wing-borne flight (None: a multicopter)
    forward_engine: int | None = None
    #: engines that lift the vehicle in hover (a multicopter's or a VTOL's rotors)
    lift_engines: tuple[int, ...] = ()

    @property
    def motor_channels(self) -> tuple[int, ...]:
        """World channel of each engine, in engine order."""
        chans = {o.engine: ch for ch, o in enumerate(self.outputs) if isinstance(o, Motor)}
        return tuple(chans[e] for e in range(len(chans)))

    @property
    def servo_channels(self) -> tuple[int, ...]:
        return tuple(ch for ch, o in enumerate(self.outputs) if isinstance(o, Servo))

    @property
    def n_motors(self) -> int:
        return sum(1 for o in self.outputs if isinstance(o, Motor))


def _outputs(main: tuple[Output, ...], aux: tuple[Output, ...] = ()) -> tuple[Output, ...]:
    return (main + (None,) * (N_MAIN - len(main)) + aux + (None,) * (N_AUX - len(aux)))


_SURFACE_THROW_RAD = 0.4363  # +-25 deg (StickPlane.xml)

AIRFRAMES: dict[str, Airframe] = {
    "f450": Airframe(
        name="f450",
        model="F450",
        outputs=_outputs((Motor(0), Motor(1), Motor(2), Motor(3))),  # PX4 quad X order
        lift_engines=(0, 1, 2, 3),
        gear_height_m=0.15,
        gear_stiffness_n_m=4 * 3000.0,
        mass_kg=1.4,
        motor_max_volts=14.63,  # DJI E305 in JSBSim's engine/DJI_E305.xml
    ),
    # Small electric sport plane (models/aircraft/StickPlane: the Ultra Stick 25e scaled to a
    # 1.5 m span). MAIN in PX4's AETR order: aileron, elevator, throttle, rudder.
    "plane": Airframe(
        name="plane",
        model="StickPlane",
        outputs=_outputs((
            Servo("fcs/aileron-cmd-norm", _SURFACE_THROW_RAD),
            Servo("fcs/elevator-cmd-norm", _SURFACE_THROW_RAD),
            Motor(0),
            Servo("fcs/rudder-cmd-norm", _SURFACE_THROW_RAD),
        )),
        gear_height_m=0.20,
        gear_stiffness_n_m=3 * 2000.0,
        mass_kg=2.7,
        motor_max_volts=16.8,  # Engines/Stick_Motor.xml (4S full)
        vehicle_class="fixedwing",
        stall_aoa_rad=0.2094,  # 12 deg: the lift table's maximum (StickPlane.xml)
        # 4S 4000 mAh LiPo (4 x ~7 mOhm + leads); avionics plus three servos at cruise
        battery=BatteryParams(cells=4, capacity_mah=4000.0, r0_ohm=0.035, r1_ohm=0.018,
                              avionics_a=0.5),
        forward_engine=0,
    ),
    # Standard VTOL (models/aircraft/QuadPlane: the StickPlane plus four lift rotors). Lift
    # rotors on MAIN1-4 through the IO (PX4 quad X order), the plane's surfaces and its
    # forward motor on the FMU's AUX1-4 in AETR order.
    "quadplane": Airframe(
        name="quadplane",
        model="QuadPlane",
        outputs=_outputs(
            (Motor(0), Motor(1), Motor(2), Motor(3)),
            (Servo("fcs/aileron-cmd-norm", _SURFACE_THROW_RAD),
             Servo("fcs/elevator-cmd-norm", _SURFACE_THROW_RAD),
             Motor(4),
             Servo("fcs/rudder-cmd-norm", _SURFACE_THROW_RAD)),
        ),
        gear_height_m=0.20,
        gear_stiffness_n_m=3 * 2000.0,
        mass_kg=3.5,
        motor_max_volts=16.8,
        vehicle_class="vtol",
        stall_aoa_rad=0.2094,
        battery=BatteryParams(cells=4, capacity_mah=5000.0, r0_ohm=0.030, r1_ohm=0.015,
                              avionics_a=0.5),
        forward_engine=4,
        lift_engines=(0, 1, 2, 3),
    ),
}

# Properties read each step (motor currents) or for truth, in this order.
_TRUTH_PROPS = (
    "accelerations/a-pilot-x-ft_sec2",
    "accelerations/a-pilot-y-ft_sec2",
    "accelerations/a-pilot-z-ft_sec2",
    "velocities/pi-rad_sec",
    "velocities/qi-rad_sec",
    "velocities/ri-rad_sec",
    "attitude/phi-rad",
    "attitude/theta-rad",
    "attitude/psi-rad",
    "position/lat-geod-deg",
    "position/long-gc-deg",
    "position/h-sl-ft",
    "position/h-agl-ft",
    "velocities/v-north-fps",
    "velocities/v-east-fps",
    "velocities/v-down-fps",
    "atmosphere/P-psf",
    "atmosphere/T-R",
    "velocities/vt-fps",
    "aero/qbar-psf",
    "aero/alpha-rad",
    "aero/beta-rad",
)


class Fdm:
    """One JSBSim instance for one airframe, with the world's initial conditions."""

    def __init__(
        self,
        airframe: Airframe,
        dt_s: float,
        lat_deg: float,
        lon_deg: float,
        ground_alt_m: float,
        heading_deg: float,
        agl_m: float,
        seed: int = 0,
        airspeed_m_s: float = 0.0,
        pitch_deg: float = 0.0,
    ) -> None:
        """``airspeed_m_s``: initial speed through still air, horizontal, along the heading;
        ``pitch_deg``: initial pitch (so the initial angle of attack is the pitch)."""
        self.airframe = airframe
        root = jsbsim.get_default_root_dir()
        fdm = jsbsim.FGFDMExec(root)
        fdm.set_debug_level(0)
        # dt before the model: the flight-control components (servo lags, rate limits) take
        # their time step when they are built
        fdm.set_dt(dt_s)
        ok = fdm.load_model_with_paths(
            airframe.model,
            str(MODELS_DIR / "aircraft"),
            os.path.join(root, "engine"),
            os.path.join(root, "systems"),
            True,
        )
        if not ok:
            raise RuntimeError(f"JSBSim could not load model {airframe.model!r}")
        self.exec = fdm
        fdm["simulation/randomseed"] = float(seed % (1 << 31))
        # Start with the gear compressed by the static load, so that a vehicle on the ground
        # starts at rest instead of dropping onto its springs.
        if agl_m <= 0.0:
            sag = airframe.mass_kg * G0_M_S2 / airframe.gear_stiffness_n_m
            h_agl = airframe.gear_height_m - sag
        else:
            h_agl = airframe.gear_height_m + agl_m
        fdm["ic/lat-geod-deg"] = lat_deg
        fdm["ic/long-gc-deg"] = lon_deg
        fdm["ic/terrain-elevation-ft"] = ground_alt_m / FT
        fdm["ic/h-agl-ft"] = h_agl / FT
        fdm["ic/psi-true-deg"] = heading_deg
        fdm["ic/phi-deg"] = 0.0
        fdm["ic/theta-deg"] = pitch_deg
        for name in ("ic/v-fps", "ic/p-rad_sec", "ic/q-rad_sec", "ic/r-rad_sec"):
            fdm[name] = 0.0
        theta = math.radians(pitch_deg)
        fdm["ic/u-fps"] = airspeed_m_s * math.cos(theta) / FT
        fdm["ic/w-fps"] = airspeed_m_s * math.sin(theta) / FT
        if not fdm.run_ic():
            raise RuntimeError("JSBSim run_ic failed")
        fdm["propulsion/set-running"] = -1  # all engines

        pm = fdm.get_property_manager()

        def node(name: str):
            n = pm.get_node(name, False)
            if n is None:
                raise KeyError(f"JSBSim property {name!r} not found")
            return n

        n = airframe.n_motors
        self._throttle_set = tuple(
            node(f"fcs/throttle-cmd-norm[{i}]").set_double_value for i in range(n)
        )
        self._current_get = tuple(
            node(f"propulsion/engine[{i}]/current-amperes").get_double_value for i in range(n)
        )
        self._rpm_get = tuple(
            node(f"propulsion/engine[{i}]/propeller-rpm").get_double_value for i in range(n)
        )
        self._thrust_get = tuple(
            node(f"propulsion/engine[{i}]/thrust-lbs").get_double_value for i in range(n)
        )
        self.truth_getters = tuple(node(p).get_double_value for p in _TRUTH_PROPS)
        #: world channel -> setter of the servo's command property (-1..1)
        self.servo_setters = {
            ch: node(out.prop).set_double_value
            for ch, out in enumerate(airframe.outputs) if isinstance(out, Servo)
        }
        self.run = fdm.run  # one JSBSim step of dt_s

    # -- per-step helpers -----------------------------------------------------------------
    @property
    def throttle_setters(self):
        """Tuple of callables, one per motor, taking a JSBSim throttle in [0, 1]."""
        return self._throttle_set

    @property
    def current_getters(self):
        """Tuple of callables, one per motor, returning the motor current (A)."""
        return self._current_get

    def motor_rpm(self, i: int) -> float:
        return self._rpm_get[i]()

    def motor_thrust_n(self, i: int) -> float:
        return self._thrust_get[i]() * LBF_N

    def __getitem__(self, name: str) -> float:
        """Any JSBSim property by name (slow path, for tests and diagnostics)."""
        return self.exec[name]
