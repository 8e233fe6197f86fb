"""MAV_CMD_INJECT_FAILURE mapped onto the catalogue: what PX4's simulator does in SITL.

PX4 (docs "System Failure Injection", MAVLink's FAILURE_UNIT / FAILURE_TYPE): with
``SYS_FAILURE_EN`` 1 a ground station or a MAVSDK script (``failure.inject(unit, type,
instance)``) asks the vehicle to fail one of its parts; in SITL the simulator acts on what it
feeds the autopilot. The FMU's ``failure_injector`` module hands the request to the board
(``failure_request``), the orchestrator calls :meth:`FailureInjection.handle`, which picks the
catalogue fault of :data:`MAPPING` for (unit, type) and starts it through the
:class:`~hil.faults.Injector` on the chip, bus, wire, world or link where it happens in
reality; never on flight-stack state. The answer (a MAV_RESULT and a text) becomes the
COMMAND_ACK:

* ACCEPTED: the fault is on; ``FAILURE_TYPE_OK`` clears every fault an injection started on
  that unit (and instance), or is a no-op;
* UNSUPPORTED: no fault of the catalogue models that pair (a unit this vehicle lacks: optical
  flow, VIO, distance sensor, airspeed, servo, avoidance; or a type such as ``slow`` that no
  chip model offers);
* DENIED: an instance the vehicle lacks (``instance`` 0 means every one);
* FAILED: the rig cannot take it (no virtual-time GCS for a link fault, a fault refused).

Instances are PX4's 1-based sensor instances on the FMUv2 (0: all): gyro 1 MPU6000, 2 L3GD20;
accel 1 MPU6000, 2 LSM303D; mag 1 HMC5883 (the GPS module's, PX4's first compass), 2 LSM303D;
baro 1 MS5611; GPS 1; motors 1-4 (PX4 quad-X numbering). A chip fault takes out the whole
chip, so failing the MPU6000's gyro also fails its accelerometer, as on real hardware.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from hil.faults import ActiveFault, FaultError, Injector

__all__ = ["FAILURE_TYPES", "FAILURE_UNITS", "INSTANCES", "MAPPING", "FailureInjection",
           "Mapped", "lookup"]

#: MAVLink FAILURE_UNIT
FAILURE_UNITS = {0: "gyro", 1: "accel", 2: "mag", 3: "baro", 4: "gps", 5: "optical_flow",
                 6: "vio", 7: "distance_sensor", 8: "airspeed", 100: "battery", 101: "motor",
                 102: "servo", 103: "avoidance", 104: "rc_signal", 105: "mavlink_signal"}
#: MAVLink FAILURE_TYPE
FAILURE_TYPES = {0: "ok", 1: "off", 2: "stuck", 3: "garbage", 4: "wrong", 5: "slow",
                 6: "delayed", 7: "intermittent"}
OK = 0
ACCEPTED, DENIED, UNSUPPORTED, FAILED = 0, 2, 3, 4

#: each unit's instances, 1-based, as the fault targets they are
INSTANCES: dict[str, tuple[str, ...]] = {
    "gyro": ("mpu6000", "l3gd20"),
    "accel": ("mpu6000", "lsm303d"),
    "mag": ("hmc5883", "lsm303d"),
    "baro": ("ms5611",),
    "gps": ("gps",),
    "motor": ("motor1", "motor2", "motor3", "motor4"),
}


@dataclass(frozen=True)
class Mapped:
    """A catalogue fault for one (unit, type): its kind and parameters; ``target`` None takes
    the instance's target from :data:`INSTANCES`."""

    kind: str
    target: str | None = None
    params: dict[str, Any] = field(default_factory=dict)


_CHIP = {1: Mapped("sensor.absent"), 2: Mapped("sensor.stuck"), 3: Mapped("sensor.noise"),
         4: Mapped("sensor.saturate")}

#: (unit, type) -> the fault that does it; pairs not listed are UNSUPPORTED
MAPPING: dict[tuple[str, str], Mapped] = {
    **{(unit, FAILURE_TYPES[t]): m for unit in ("gyro", "accel", "mag", "baro")
       for t, m in _CHIP.items()},
    ("gps", "off"): Mapped("gps.absent"),
    ("gps", "wrong"): Mapped("gps.jump", params={"north_m": 50.0}),
    ("gps", "garbage"): Mapped("bus.uart_noise", "fmu.UART4", {"bit_error_rate": 2e-3}),
    ("battery", "off"): Mapped("vehicle.battery_low", "", {"soc": 0.0}),
    ("motor", "off"): Mapped("vehicle.motor_failure"),
    ("rc_signal", "off"): Mapped("rc.tx_off", "rc"),
    ("rc_signal", "garbage"): Mapped("rc.glitch", "rc"),
    ("rc_signal", "intermittent"): Mapped("rc.frame_loss", "rc", {"prob": 0.5}),
    ("mavlink_signal", "off"): Mapped("link.datalink_loss", "uplink"),
}


def lookup(unit: int, failure_type: int) -> Mapped | None:
    """The catalogue fault for a (unit, type) pair of MAVLink numbers, or None."""
    u, t = FAILURE_UNITS.get(unit), FAILURE_TYPES.get(failure_type)
    if u is None or t is None:
        return None
    return MAPPING.get((u, t))


def _describe(unit: int, failure_type: int, instance: int) -> str:
    u = FAILURE_UNITS.get(unit, f"unit {unit}")
    t = FAILURE_TYPES.get(failure_type, f"type {failure_type}")
    return f"{u} {t}" + (f" instance {instance}" if instance else "")


class FailureInjection:
    """Serves the boards' ``failure_request`` for an :class:`Injector`, and remembers what it
    started per (unit, instance) so that ``FAILURE_TYPE_OK`` can clear it."""

    def __init__(self, injector: Injector) -> None:
        self.injector = injector
        self.active: dict[tuple[str, str], list[ActiveFault]] = {}
        #: every request and its answer: (t_ns, unit, type, instance, result, text)
        self.history: list[tuple[int, int, int, int, int, str]] = []

    def handle(self, board: str, payload: Any) -> tuple[int, int, str]:
        """The orchestrator's request hook: ``(seq, unit, type, instance)`` -> ``(seq,
        mav_result, text)``. Never raises: a malformed request is DENIED."""
        try:
            seq, unit, failure_type, instance = (int(x) for x in payload)
        except (TypeError, ValueError, OverflowError):
            return 0, DENIED, "malformed failure request"
        try:
            result, text = self._apply(unit, failure_type, instance)
        except Exception as exc:  # noqa: BLE001 - the board always gets its answer
            result, text = FAILED, f"{_describe(unit, failure_type, instance)}: {exc}"
        self.history.append((self.injector.orch.t_ns, unit, failure_type, instance, result,
                             text))
        self.injector.log(f"inject failure {_describe(unit, failure_type, instance)}: "
                          f"{result} {text}")
        return seq, result, text

    def _apply(self, unit: int, failure_type: int, instance: int) -> tuple[int, str]:
        what = _describe(unit, failure_type, instance)
        uname = FAILURE_UNITS.get(unit)
        if uname is None:
            return UNSUPPORTED, f"unknown failure unit {unit}"
        if failure_type not in FAILURE_TYPES:
            return UNSUPPORTED, f"unknown failure type {failure_type}"
        mapped = lookup(unit, failure_type)
        if mapped is None and failure_type != OK:
            return UNSUPPORTED, f"{what}: no such fault on this vehicle"
        targets = INSTANCES.get(uname, (uname,))
        if instance > len(targets) or (instance > 1 and uname not in INSTANCES):
            return DENIED, f"{what}: no {uname} instance {instance} (has {len(targets)})"
        chosen = targets if instance == 0 else (targets[instance - 1],)
        if failure_type == OK:
            return ACCEPTED, f"{what}: cleared {self._clear(uname, chosen)} fault(s)"
        assert mapped is not None
        started: list[str] = []
        try:
            for target in chosen:
                self._clear(uname, (target,))  # a new failure replaces the old one
                tgt = mapped.target if mapped.target is not None else target
                af = self.injector.start(mapped.kind, tgt, dict(mapped.params))
                self.active.setdefault((uname, target), []).append(af)
                started.append(f"{mapped.kind} {tgt}".rstrip())
        except FaultError as exc:
            return FAILED, f"{what}: {exc}"
        return ACCEPTED, f"{what}: {', '.join(started)}"

    def _clear(self, unit: str, targets: tuple[str, ...]) -> int:
        n = 0
        for target in targets:
            for af in self.active.pop((unit, target), []):
                if af.active and af.kind.stop is not None:
                    self.injector.stop(af)
                    n += 1
        return n
