"""JSBSim flight dynamics: airframe registry, initial conditions and cached property nodes.

JSBSim works in imperial units; everything leaving this module is SI. Properties read or
written every step go through ``FGPropertyNode`` objects resolved once at load time
(get/set_double_value ~0.08 us per call against ~0.16 us for ``fdm['name']`` reads and ~0.6 us
for ``fdm['name'] = x`` writes, JSBSim 1.3).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

# JSBSim prints a banner and load chatter unless told otherwise; read when the FGFDMExec
# is constructed. Respect an explicit setting by the user.
os.environ.setdefault("JSBSIM_DEBUG", "0")

import jsbsim  # noqa: E402

__all__ = ["Airframe", "AIRFRAMES", "Fdm", "FT", "LBF_N", "PSF_PA"]

FT = 0.3048  # m per ft
LBF_N = 4.4482216152605  # N per lbf
PSF_PA = 47.880258980335840  # Pa per lbf/ft^2
HP_W = 745.69987158227022  # W per hp

MODELS_DIR = Path(__file__).resolve().parent / "models"


@dataclass(frozen=True, slots=True)
class Airframe:
    """What the world needs to know about a JSBSim model beyond the model itself."""

    name: str
    model: str  # JSBSim model name (directory and file under models/aircraft/)
    n_motors: int  # engines 0..n-1 are driven by ESC channels 0..n-1
    gear_height_m: float  # IMU height above the ground with the gear just touching
    gear_stiffness_n_m: float  # sum of the contact spring rates (static deflection at start)
    mass_kg: float
    motor_max_volts: float  # the JSBSim motor's MaxVolts: throttle 1 applies this voltage


AIRFRAMES: dict[str, Airframe] = {
    "f450": Airframe(
        name="f450",
        model="F450",
        n_motors=4,
        gear_height_m=0.15,
        gear_stiffness_n_m=4 * 3000.0,
        mass_kg=1.4,
        motor_max_volts=14.63,  # DJI E305 in JSBSim's engine/DJI_E305.xml
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
    ) -> None:
        self.airframe = airframe
        root = jsbsim.get_default_root_dir()
        fdm = jsbsim.FGFDMExec(root)
        fdm.set_debug_level(0)
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
        fdm.set_dt(dt_s)
        fdm["simulation/randomseed"] = float(seed % (1 << 31))
        # Start with the gear compressed by the static load, so that a vehicle on the ground
        # starts at rest instead of dropping onto its springs.
        if agl_m <= 0.0:
            sag = airframe.mass_kg * 9.80665 / airframe.gear_stiffness_n_m
            h_agl = airframe.gear_height_m - sag
        else:
            h_agl = airframe.gear_height_m + agl_m
        fdm["ic/lat-geod-deg"] = lat_deg
        fdm["ic/long-gc-deg"] = lon_deg
        fdm["ic/terrain-elevation-ft"] = ground_alt_m / FT
        fdm["ic/h-agl-ft"] = h_agl / FT
        fdm["ic/psi-true-deg"] = heading_deg
        fdm["ic/phi-deg"] = 0.0
        fdm["ic/theta-deg"] = 0.0
        for name in ("ic/u-fps", "ic/v-fps", "ic/w-fps", "ic/p-rad_sec", "ic/q-rad_sec",
                     "ic/r-rad_sec"):
            fdm[name] = 0.0
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
