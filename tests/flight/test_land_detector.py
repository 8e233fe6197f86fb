"""Land detector: landed at start, takeoff seen at once, landing seen after the stage times."""

from __future__ import annotations

import pytest

from board.kernel import Kernel
from firmware.modules.land_detector import LandDetectorModule
from firmware.modules.land_detector.land_detector import Hysteresis
from firmware.platform import Platform
from firmware.platform.params import Params
from firmware.system import System
from common.units import G0_M_S2



class Bench:
    """The land detector alone on a platform, its inputs published by the test."""

    def __init__(self) -> None:
        self.kernel = Kernel("ld")
        p = self.platform = Platform(self.kernel)
        self.system = System(p, Params(p, LandDetectorModule.PARAMS),
                             modules={"land_detector": LandDetectorModule})
        orb = p.orb
        self.pubs = {t: orb.advertise(t) for t in (
            "actuator_armed", "vehicle_local_position", "actuator_controls_0",
            "vehicle_control_mode", "vehicle_local_position_setpoint",
            "vehicle_angular_velocity")}
        self.msgs = {t: orb.new(t) for t in self.pubs}
        self.msgs["vehicle_local_position"].az = 0.0
        self.msgs["vehicle_control_mode"].flag_control_climb_rate_enabled = True
        assert self.system.modules.start("land_detector") == 0
        self.t_ns = 0

    def set(self, topic: str, **fields) -> None:
        m = self.msgs[topic]
        for k, v in fields.items():
            setattr(m, k, v)
        m.timestamp = self.platform.time_us()
        self.pubs[topic].publish(m)

    def run(self, seconds: float) -> None:
        """Advance, re-publishing the inputs at 50 Hz as the estimator and controllers do."""
        end = self.t_ns + int(seconds * 1e9)
        while self.t_ns < end:
            self.t_ns += 10_000_000
            for t in self.pubs:
                self.set(t)
            self.kernel.run(self.t_ns)

    @property
    def state(self):
        return self.platform.orb.node("vehicle_land_detected").last


def test_landed_at_start_and_when_disarmed():
    b = Bench()
    b.run(0.1)
    assert b.state.landed and b.state.maybe_landed and b.state.ground_contact


def test_takeoff_is_detected_at_once_and_landing_after_the_stage_times():
    b = Bench()
    b.set("actuator_armed", armed=True)
    b.set("actuator_controls_0", control=[0.0, 0.0, 0.0, 0.0, 0, 0, 0, 0])
    b.run(0.5)
    assert b.state.landed                           # armed on the ground, idle
    b.set("actuator_controls_0", control=[0.0, 0.0, 0.0, 0.6, 0, 0, 0, 0])
    b.set("vehicle_local_position", vz=-1.0)
    b.run(0.1)
    assert not b.state.landed and not b.state.maybe_landed
    # descending for landing: moving, then stopped by the ground with the thrust still high
    b.set("actuator_controls_0", control=[0.0, 0.0, 0.0, 0.45, 0, 0, 0, 0])
    b.set("vehicle_local_position_setpoint", vz=0.7)
    b.set("vehicle_local_position", vz=0.7)
    b.run(2.0)
    assert not b.state.landed and not b.state.ground_contact
    b.set("vehicle_local_position", vz=0.0)
    b.run(0.4)
    assert b.state.ground_contact and not b.state.maybe_landed   # thrust not low yet
    b.set("actuator_controls_0", control=[0.0, 0.0, 0.0, 0.15, 0, 0, 0, 0])
    b.run(0.3)
    assert not b.state.landed
    b.run(0.5)
    assert b.state.maybe_landed and b.state.landed


def test_rotation_prevents_maybe_landed():
    b = Bench()
    b.set("actuator_armed", armed=True)
    b.set("actuator_controls_0", control=[0.0, 0.0, 0.0, 0.6, 0, 0, 0, 0])
    b.run(0.2)
    assert not b.state.landed
    b.set("actuator_controls_0", control=[0.0, 0.0, 0.0, 0.1, 0, 0, 0, 0])
    b.set("vehicle_angular_velocity", xyz=[1.0, 0.0, 0.0])
    b.run(2.0)
    assert b.state.ground_contact and not b.state.maybe_landed


def test_free_fall():
    b = Bench()
    b.set("actuator_armed", armed=True)
    b.set("actuator_controls_0", control=[0.0, 0.0, 0.0, 0.6, 0, 0, 0, 0])
    b.set("vehicle_local_position", az=G0_M_S2, vz=3.0)   # specific force 0: falling
    b.run(0.2)
    assert not b.state.freefall
    b.run(0.3)
    assert b.state.freefall


@pytest.mark.parametrize("hold_us", [0, 300_000])
def test_hysteresis(hold_us):
    h = Hysteresis(False, set_us=hold_us)
    assert h.update(True, 1_000_000) is (hold_us == 0)
    assert h.update(True, 1_000_000 + hold_us) is True
    assert h.update(False, 2_000_000) is False       # clears at once
