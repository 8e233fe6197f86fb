"""Fixed-wing land detector (``land_detector start fixedwing``) on synthetic topics: landed on the
ground, flying at once on the takeoff roll or a launch jolt, landed LNDFW_TRIG_TIME after the
plane has come to rest, the tighter groundspeed limit without an airspeed."""

from __future__ import annotations

from board.kernel import Kernel
from firmware.modules.land_detector import LandDetectorModule
from firmware.platform import Platform
from firmware.platform.params import Params
from firmware.system import System
from common.units import G0_M_S2



class FwBench:
    """The land detector alone, started as ``fixedwing``; the test publishes its inputs."""

    TOPICS = ("actuator_armed", "vehicle_local_position", "vehicle_acceleration", "airspeed")

    def __init__(self, kind: str = "fixedwing") -> None:
        self.kernel = Kernel("ld")
        p = self.platform = Platform(self.kernel)
        self.out: list[str] = []
        self.system = System(p, Params(p, LandDetectorModule.PARAMS),
                             modules={"land_detector": LandDetectorModule},
                             console=self.out.append)
        orb = p.orb
        self.pubs = {t: orb.advertise(t) for t in self.TOPICS}
        self.msgs = {t: orb.new(t) for t in self.TOPICS}
        self.msgs["vehicle_acceleration"].xyz = [0.0, 0.0, -G0_M_S2]
        self.silent: set[str] = set()
        self.start_rc = self.system.modules.start("land_detector", [kind])
        self.t_ns = 0

    def set(self, topic: str, **fields) -> None:
        m = self.msgs[topic]
        for k, v in fields.items():
            setattr(m, k, v)
        self.silent.discard(topic)

    def run(self, seconds: float) -> None:
        """Advance, publishing the inputs at 50 Hz (the airspeed unless silenced)."""
        end = self.t_ns + int(seconds * 1e9)
        while self.t_ns < end:
            self.t_ns += 20_000_000
            for t, m in self.msgs.items():
                if t not in self.silent:
                    m.timestamp = self.platform.time_us()
                    self.pubs[t].publish(m)
            self.kernel.run(self.t_ns)

    @property
    def landed(self) -> bool:
        m = self.platform.orb.node("vehicle_land_detected").last
        assert m.maybe_landed == m.landed and m.ground_contact == m.landed
        return bool(m.landed)

    def fly(self, speed_m_s: float) -> None:
        self.set("vehicle_local_position", vx=speed_m_s, vy=0.0, vz=0.0)
        self.set("airspeed", true_airspeed_m_s=speed_m_s, indicated_airspeed_m_s=speed_m_s)


def test_unknown_type_is_refused() -> None:
    b = FwBench("submarine")
    assert b.start_rc != 0 and any("unknown vehicle type" in line for line in b.out)


def test_takeoff_roll_flight_and_landing() -> None:
    b = FwBench()
    assert b.start_rc == 0
    b.run(0.2)
    assert b.landed                                   # disarmed
    b.set("actuator_armed", armed=True)
    b.fly(0.0)
    b.run(3.0)
    assert b.landed                                   # armed on the runway
    b.fly(14.0)                                       # takeoff roll
    b.run(0.3)
    assert not b.landed                               # airspeed filter past 6 m/s: at once
    b.fly(18.0)
    b.run(5.0)
    assert not b.landed
    b.fly(0.0)                                        # touched down and stopped
    b.run(2.0)
    assert not b.landed                               # filters settle, then LNDFW_TRIG_TIME
    b.run(2.0)
    assert b.landed
    lines = b.system.modules.get("land_detector").status_lines()
    assert lines[0] == "type: fixedwing" and "groundspeed" in lines[1]


def test_launch_jolt_is_flight_before_any_speed() -> None:
    b = FwBench()
    b.set("actuator_armed", armed=True)
    b.fly(0.0)
    b.run(1.0)
    assert b.landed
    b.set("vehicle_acceleration", xyz=[30.0, 0.0, -G0_M_S2])  # catapult: 3 g forwards
    b.run(0.1)
    assert not b.landed


def test_groundspeed_limit_is_tighter_without_airspeed() -> None:
    b = FwBench()
    b.set("actuator_armed", armed=True)
    b.set("vehicle_local_position", vx=4.0)           # taxiing: under 5 m/s, over 0.7 x 5
    b.set("airspeed", true_airspeed_m_s=4.0)
    b.run(4.0)
    assert b.landed
    b.silent.add("airspeed")                          # airspeed lost for over a second
    b.run(1.5)
    assert not b.landed
