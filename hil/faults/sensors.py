"""Sensor faults: a chip on the FMU misbehaves at its registers, pins or bus interface.

Each kind sets one field of the chip model's :class:`peripherals.faults.FaultState` through the
FMU board's ``ctl_fault`` hook, at a virtual time; the model then answers its bus the way the
faulty chip would. The drivers and the sensors module must notice by themselves (register
checks, data-ready timeouts, stuck-data and error counters, the redundancy voter).

Targets are the sensor chips of the rig's FMU by their device names in its spec
(``board/specs.py``): every SPI or I2C device whose model is a sensor of :data:`SENSOR_MODELS`.
On the standard FMUv2 that is ``mpu6000`` (accel+gyro, primary IMU), ``l3gd20`` (gyro) and
``lsm303d`` (accel+mag) forming the second IMU, ``ms5611`` (the only barometer), ``hmc5883``
(the GPS module's compass); a board variant's extra chip of a known model is a target too.
Failing one of several redundant chips (the IMUs, the two compasses) is what the failover
scenarios use.

Almost every kind sets one field of the chip's fault state and clears it again, so each is one
:func:`_field` line: the field, the value it gets, the value that clears it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from board.specs import FMU_V2, BoardSpecData
from hil.faults import FaultError, Rig, switch_kind
from hil.faults._rig import board_call, number, vector

#: sensor models: their outputs a noise burst can act on (SI units: rad/s, m/s^2, gauss, Pa;
#: the default first) and whether the chip has a data-ready line. Facts about the chips; which
#: chips a board has is its spec's business.
SENSOR_MODELS: dict[str, tuple[tuple[str, ...], bool]] = {
    "mpu6000": (("accel", "gyro"), True),
    "l3gd20": (("gyro",), True),
    "lsm303d": (("accel", "mag"), True),
    "ms5611": (("pressure",), False),   # no data-ready: the driver times its conversions
    "hmc5883": (("mag",), True),
    "ms4525do": (("pressure",), False),  # airspeed: polled after a measurement request
}
#: sensor models without an identity register (nothing for ``sensor.wrong_id`` to change)
NO_IDENTITY: frozenset[str] = frozenset({"ms4525do"})
#: airspeed (differential pressure) sensor models: the ``airspeed.*`` kinds' targets
AIRSPEED_MODELS: frozenset[str] = frozenset({"ms4525do"})


def sensor_models(spec: BoardSpecData) -> dict[str, str]:
    """Device name -> model, for the spec's SPI and I2C devices that are sensors."""
    devices = [d for b in spec.spi for d in b.devices] + [d for b in spec.i2c for d in b.devices]
    return {d.name: d.model for d in devices if d.model in SENSOR_MODELS}


def sensor_targets(spec: BoardSpecData) -> tuple[str, ...]:
    return tuple(sensor_models(spec))


def drdy_targets(spec: BoardSpecData) -> tuple[str, ...]:
    return tuple(n for n, m in sensor_models(spec).items() if SENSOR_MODELS[m][1])


def identity_targets(spec: BoardSpecData) -> tuple[str, ...]:
    return tuple(n for n, m in sensor_models(spec).items() if m not in NO_IDENTITY)


def airspeed_targets(spec: BoardSpecData) -> tuple[str, ...]:
    return tuple(n for n, m in sensor_models(spec).items() if m in AIRSPEED_MODELS)


def mpu6000_targets(spec: BoardSpecData) -> tuple[str, ...]:
    return tuple(n for n, m in sensor_models(spec).items() if m == "mpu6000")


#: the standard FMUv2's targets (the catalogue's listing and the default target)
SENSORS = sensor_targets(FMU_V2)
DRDY_SENSORS = drdy_targets(FMU_V2)


def _set(rig: Rig, fault: str, target: str, field: str, value: Any) -> None:
    board_call(rig, fault, "fmu", "fault", target, field, value)


def _field(name: str, field: str, doc: str, on: Callable[[dict[str, Any]], Any] = lambda p: True,
           off: Any = False, targets: Callable[[BoardSpecData], tuple[str, ...]] = sensor_targets,
           **params: Any) -> None:
    """A kind that sets the chip's ``FaultState.<field>`` to ``on(params)`` and back to
    ``off`` when it stops."""

    def apply(rig: Rig, target: str, p: dict[str, Any], active: bool) -> None:
        _set(rig, name, target, field, on(p) if active else off)

    switch_kind(name, apply, level="sensor", doc=doc, targets=targets(FMU_V2),
                spec_board="fmu", spec_targets=targets, **params)


_field("sensor.absent", "absent",
       "The chip stops answering on its bus: a cracked solder joint, a dead chip, a lost supply. "
       "On SPI nothing drives MISO so every byte reads 0xFF; on I2C the chip no longer ACKs its "
       "address; data-ready lines stay low. The driver sees bad registers and timeouts, resets "
       "the chip in vain, and the sensors module fails over to a redundant chip if there is one "
       "(otherwise the preflight checks report the sensor missing).")
_field("sensor.stuck", "frozen",
       "The data registers stop updating while the chip still answers and signals data-ready "
       "(a hung conversion, a latched ADC): every sample repeats. Real sensor noise never "
       "repeats exactly, so the driver's stuck-data counter and the voter's freeze detection "
       "declare the sensor unhealthy.")
_field("sensor.noise", "random_data",
       "The data registers read random bytes (a corrupted SPI line, EMI on the bus, a chip "
       "in a bad internal state). The driver's consistency checks count errors and the voter "
       "drops the sensor for its error rate or its disagreement with the others.")
_field("sensor.saturate", "saturate",
       "Every axis reads its positive full scale (a shock beyond the range, a broken MEMS "
       "structure, an overflowed magnetometer). The readings clip and freeze at the limit; "
       "the voter and the estimator reject the sensor.")
_field("sensor.drdy_stuck", "drdy_stuck",
       "The data-ready line never asserts (a broken trace or a lost interrupt configuration). "
       "The driver notices the missing interrupts and polls the chip instead, as PX4's drivers "
       "fall back to polling, so the data keeps flowing.", targets=drdy_targets)
_field("sensor.wrong_id", "wrong_id",
       "The chip answers a wrong identity (WHO_AM_I, the HMC5883's ID registers, the "
       "MS5611's PROM CRC word): a wrong or counterfeit part fitted, or a chip whose "
       "identity register reads garbage after a brown-out. A driver checks the "
       "identity when it (re)initialises the chip and periodically with its other "
       "registers: it finds the mismatch, resets, and gives the sensor up when the "
       "reset keeps failing. ``value`` is what the identity register reads.",
       on=lambda p: int(p["value"]), off=None, targets=identity_targets, value=0x00)
_field("sensor.bias_step", "bias_step",
       "A step in the sensor's offset (a shock that shifts a MEMS proof mass, a "
       "temperature jump, a magnetised part near the compass), in SI units on the "
       "chip's axes: rad/s for a gyro, m/s^2 for an accel, gauss for a magnetometer, "
       "pascal on x (and kelvin on y, the die temperature) for the barometer and the airspeed "
       "sensor (its differential pressure). The readings stay "
       "plausible, so the drivers cannot see it; only the voter's inconsistency between "
       "redundant sensors and the estimator's innovations can.",
       on=lambda p: (float(p["x"]), float(p["y"]), float(p["z"])), off=(0.0, 0.0, 0.0),
       x=0.0, y=0.0, z=0.0)
_field("sensor.fifo_overflow", "fifo_overflow",
       "The MPU6000's FIFO fills faster than the driver reads it, so at every read "
       "it holds 1024 bytes and has overflowed (FIFO_OFLOW, the oldest bytes lost "
       "and the 12-byte records misaligned): an overrun sample clock, or in practice "
       "a driver starved of its work queue. PX4's driver sees the FIFO count at 1024, "
       "counts 'FIFO overflow' (perf and error_count) and resets the FIFO; sustained, "
       "no valid data is published, and the voter fails over to the second IMU.",
       targets=mpu6000_targets)
_field("sensor.wrong_id_after_reset", "wrong_id_after_reset",
       "The chip answers correctly until it is reset (PWR_MGMT_1 DEVICE_RESET from "
       "the driver, or a power cycle of the sensor rail): from then on WHO_AM_I reads "
       "``value`` (a part damaged by a brown-out or ESD whose fuses reload wrong). "
       "Nothing shows until a reset; then PX4's driver fails its identity check on "
       "every reset ('reset failed'), never re-probes the chip and the sensor is lost "
       "(the voter fails over). Stopping the fault makes the next reset good again.",
       on=lambda p: int(p["value"]) & 0xFF, off=None, targets=mpu6000_targets, value=0x00)


def _bias_drift(rig: Rig, target: str, params: dict[str, Any], on: bool) -> None:
    rate = vector(params, "rate", "sensor.bias_drift") if on else (0.0, 0.0, 0.0)
    board_call(rig, "sensor.bias_drift", "fmu", "sensor_drift", target, rate)


switch_kind("sensor.bias_drift", _bias_drift, level="sensor", targets=SENSORS,
            rate=(0.01, 0.0, 0.0),
            spec_board="fmu", spec_targets=sensor_targets,
            doc="A sensor's bias drifts at `rate` SI units per second per axis (target the FMU "
                "device: mpu6000 gyro rad/s/s, l3gd20, lsm303d accel m/s^2/s, hmc5883 gauss/s, "
                "ms5611 Pa/s on the first axis): a temperature-driven or aging drift, a part "
                "slowly magnetised. The chip's output ramps (updated every 10 ms); the "
                "estimator's bias states follow a slow drift, a fast one shows as growing "
                "innovations and, between redundant sensors, as inconsistency in the voter. "
                "Stopping leaves the bias where it got to.")


def _noise_burst(rig: Rig, target: str, params: dict[str, Any], on: bool) -> None:
    name = "sensor.noise_burst"
    if not on:
        _set(rig, name, target, "noise", None)
        return
    spec = rig.spec("fmu") if hasattr(rig, "spec") else None
    model = sensor_models(spec if spec is not None else FMU_V2)[target]
    outputs = SENSOR_MODELS[model][0]
    output = params["output"] or outputs[0]
    if output not in outputs:
        raise FaultError(f"fault {name}: {target} has no output {output!r} "
                         f"(outputs: {', '.join(outputs)})")
    _set(rig, name, target, "noise", {output: number(params, "sigma", name, 0.0, 1e6)})


switch_kind("sensor.noise_burst", _noise_burst, level="sensor", targets=SENSORS,
            spec_board="fmu", spec_targets=sensor_targets, sigma=3.0, output="",
            doc="Extra white noise of standard deviation ``sigma`` (SI units per sample and "
                "axis: m/s^2, rad/s, gauss, Pa) on one of the chip's outputs (``output``: "
                "accel/gyro for the MPU6000, gyro for the L3GD20, accel/mag for the LSM303D, "
                "pressure, mag; default the first) while it lasts: vibration from a damaged "
                "propeller or a loose mount, EMI from a power lead, a marginal supply. The "
                "readings stay plausible sample by sample, so the driver sees nothing; the "
                "sensors module's inconsistency between redundant IMUs grows (PX4: 'Accels "
                "inconsistent' at COM_ARM_IMU_ACC refuses arming) and the estimator's "
                "innovations widen. A burst shorter than the voter's one-second persistence "
                "causes no failover.")


def _pitot_mode(p: dict[str, Any]) -> str:
    mode = p["mode"]
    if mode not in ("stuck", "zero"):
        raise FaultError(f"fault airspeed.pitot_blocked: mode must be 'stuck' or 'zero', "
                         f"got {mode!r}")
    return str(mode)


_field("airspeed.pitot_blocked", "port_blocked",
       "The pitot tube is blocked (ice, water, an insect, the cover left on) while the sensor "
       "works (target: the airspeed sensor of a plane's FMU, ms4525; the stock FMUv2 has "
       "none). mode 'stuck': the ram port and the drain are both blocked, so the pressure "
       "trapped at that moment stays, and the airspeed reads what it was whatever the vehicle "
       "does; mode 'zero': the ram port is blocked but the drain lets the tube settle to static "
       "pressure, so the airspeed reads about zero. The chip still converts with its noise, so "
       "the driver sees nothing; the sensors module's consistency check (ground speed above "
       "the true airspeed by more than ASPD_FS_INNOV for ASPD_FS_T_STOP while moving faster "
       "than ASPD_STALL) sets the airspeed's confidence to 0, which a zero reading in cruise "
       "trips within seconds and a stuck one only once the vehicle speeds up.",
       on=_pitot_mode, off="", targets=airspeed_targets, mode="zero")
_field("airspeed.stale", "stale",
       "The airspeed sensor (ms4525, on a plane's FMU) answers its bus but its conversions "
       "never complete (a hung "
       "conditioning ASIC): every data fetch returns the last result with the MS4525DO's "
       "status 2, 'stale data that has been already fetched'. PX4's ms4525_airspeed driver "
       "counts each as an error and restarts its measure/collect cycle; nothing is published, "
       "so the sensors module's airspeed times out after 300 ms and goes out with confidence "
       "0 until the conversions come back.", targets=airspeed_targets)
