"""Sensor faults: a chip on the FMU misbehaves at its registers, pins or bus interface.

Each kind sets one field of the chip model's :class:`peripherals.faults.FaultState` through the
FMU board's ``ctl_fault`` hook, at a virtual time; the model then answers its bus the way the
faulty chip would. The drivers and the sensors module must notice by themselves (register
checks, data-ready timeouts, stuck-data and error counters, the redundancy voter).

Targets are the FMUv2 sensor chips by their device names in ``board/specs.py``: ``mpu6000``
(accel+gyro, primary IMU), ``l3gd20`` (gyro) and ``lsm303d`` (accel+mag) forming the second
IMU, ``ms5611`` (the only barometer), ``hmc5883`` (the GPS module's compass). Failing one of
several redundant chips (the IMUs, the two compasses) is what the failover scenarios use.
"""

from __future__ import annotations

from typing import Any

from hil.faults import fault_kind
from hil.faults.bus import board_call

SENSORS = ("mpu6000", "l3gd20", "lsm303d", "ms5611", "hmc5883")
#: chips with a data-ready line (the MS5611 has none: the driver times its conversions)
DRDY_SENSORS = ("mpu6000", "l3gd20", "lsm303d", "hmc5883")


def _set(rig: Any, target: str, field: str, value: Any) -> None:
    rig.orch.call("fmu", "fault", target, field, value)


def _flag(name: str, field: str, doc: str, targets: tuple[str, ...] = SENSORS) -> None:
    """A kind that sets a boolean FaultState field and clears it on stop."""

    @fault_kind(name, level="sensor", doc=doc, targets=targets)
    def start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
        _set(rig, target, field, True)

    @start.stopper
    def stop(rig: Any, target: str, params: dict[str, Any], t_ns: int, token: Any) -> None:
        _set(rig, target, field, False)


_flag("sensor.absent", "absent",
      "The chip stops answering on its bus: a cracked solder joint, a dead chip, a lost supply. "
      "On SPI nothing drives MISO so every byte reads 0xFF; on I2C the chip no longer ACKs its "
      "address; data-ready lines stay low. The driver sees bad registers and timeouts, resets "
      "the chip in vain, and the sensors module fails over to a redundant chip if there is one "
      "(otherwise the preflight checks report the sensor missing).")
_flag("sensor.stuck", "frozen",
      "The data registers stop updating while the chip still answers and signals data-ready "
      "(a hung conversion, a latched ADC): every sample repeats. Real sensor noise never "
      "repeats exactly, so the driver's stuck-data counter and the voter's freeze detection "
      "declare the sensor unhealthy.")
_flag("sensor.noise", "random_data",
      "The data registers read random bytes (a corrupted SPI line, EMI on the bus, a chip "
      "in a bad internal state). The driver's consistency checks count errors and the voter "
      "drops the sensor for its error rate or its disagreement with the others.")
_flag("sensor.saturate", "saturate",
      "Every axis reads its positive full scale (a shock beyond the range, a broken MEMS "
      "structure, an overflowed magnetometer). The readings clip and freeze at the limit; "
      "the voter and the estimator reject the sensor.")
_flag("sensor.drdy_stuck", "drdy_stuck",
      "The data-ready line never asserts (a broken trace or a lost interrupt configuration). "
      "The driver notices the missing interrupts and polls the chip instead, as PX4's drivers "
      "fall back to polling, so the data keeps flowing.", DRDY_SENSORS)


@fault_kind("sensor.wrong_id", level="sensor", targets=SENSORS, value=0x00,
            doc="The chip answers a wrong identity (WHO_AM_I, the HMC5883's ID registers, the "
                "MS5611's PROM CRC word): a wrong or counterfeit part fitted, or a chip whose "
                "identity register reads garbage after a brown-out. A driver checks the "
                "identity when it (re)initialises the chip and periodically with its other "
                "registers: it finds the mismatch, resets, and gives the sensor up when the "
                "reset keeps failing. ``value`` is what the identity register reads.")
def wrong_id_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    _set(rig, target, "wrong_id", int(params["value"]))


@wrong_id_start.stopper
def wrong_id_stop(rig: Any, target: str, params: dict[str, Any], t_ns: int, token: Any) -> None:
    _set(rig, target, "wrong_id", None)


@fault_kind("sensor.bias_step", level="sensor", targets=SENSORS, x=0.0, y=0.0, z=0.0,
            doc="A step in the sensor's offset (a shock that shifts a MEMS proof mass, a "
                "temperature jump, a magnetised part near the compass), in SI units on the "
                "chip's axes: rad/s for a gyro, m/s^2 for an accel, gauss for a magnetometer, "
                "pascal on x (and kelvin on y, the die temperature) for the barometer. The readings stay plausible, so the drivers "
                "cannot see it; only the voter's inconsistency between redundant sensors and "
                "the estimator's innovations can.")
def bias_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    _set(rig, target, "bias_step", (float(params["x"]), float(params["y"]), float(params["z"])))


@bias_start.stopper
def bias_stop(rig: Any, target: str, params: dict[str, Any], t_ns: int, token: Any) -> None:
    _set(rig, target, "bias_step", (0.0, 0.0, 0.0))


@fault_kind("sensor.bias_drift", level="sensor", rate=(0.01, 0.0, 0.0),
            doc="A sensor's bias drifts at `rate` SI units per second per axis (target the FMU "
                "device: mpu6000 gyro rad/s/s, l3gd20, lsm303d accel m/s^2/s, hmc5883 gauss/s, "
                "ms5611 Pa/s on the first axis): a temperature-driven or aging drift, a part "
                "slowly magnetised. The chip's output ramps (updated every 10 ms); the "
                "estimator's bias states follow a slow drift, a fast one shows as growing "
                "innovations and, between redundant sensors, as inconsistency in the voter. "
                "Stopping leaves the bias where it got to.")
def bias_drift(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> Any:
    from hil.faults._rig import vector

    rate = vector(params, "rate", "sensor.bias_drift")
    board_call(rig, "sensor.bias_drift", "fmu", "sensor_drift", target, rate)
    return None


@bias_drift.stopper
def _bias_drift_stop(rig: Any, target: str, params: dict[str, Any], t_ns: int,
                     token: Any) -> None:
    board_call(rig, "sensor.bias_drift", "fmu", "sensor_drift", target, (0.0, 0.0, 0.0))


#: each chip's outputs a noise burst can act on, the default first (SI units: rad/s, m/s^2,
#: gauss, Pa)
NOISE_OUTPUTS = {"mpu6000": ("accel", "gyro"), "l3gd20": ("gyro",), "lsm303d": ("accel", "mag"),
                 "ms5611": ("pressure",), "hmc5883": ("mag",)}


@fault_kind("sensor.noise_burst", level="sensor", targets=SENSORS, sigma=3.0, output="",
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
def noise_burst_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    from hil.faults import FaultError
    from hil.faults._rig import number

    outputs = NOISE_OUTPUTS[target]
    output = params["output"] or outputs[0]
    if output not in outputs:
        raise FaultError(f"fault sensor.noise_burst: {target} has no output {output!r} "
                         f"(outputs: {', '.join(outputs)})")
    sigma = number(params, "sigma", "sensor.noise_burst", 0.0, 1e6)
    _set(rig, target, "noise", {output: sigma})


@noise_burst_start.stopper
def noise_burst_stop(rig: Any, target: str, params: dict[str, Any], t_ns: int,
                     token: Any) -> None:
    _set(rig, target, "noise", None)


@fault_kind("sensor.fifo_overflow", level="sensor", targets=("mpu6000",),
            doc="The MPU6000's FIFO fills faster than the driver reads it, so at every read "
                "it holds 1024 bytes and has overflowed (FIFO_OFLOW, the oldest bytes lost "
                "and the 12-byte records misaligned): an overrun sample clock, or in practice "
                "a driver starved of its work queue. PX4's driver sees the FIFO count at 1024, "
                "counts 'FIFO overflow' (perf and error_count) and resets the FIFO; sustained, "
                "no valid data is published, and the voter fails over to the second IMU.")
def fifo_overflow_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    _set(rig, target, "fifo_overflow", True)


@fifo_overflow_start.stopper
def fifo_overflow_stop(rig: Any, target: str, params: dict[str, Any], t_ns: int,
                       token: Any) -> None:
    _set(rig, target, "fifo_overflow", False)


@fault_kind("sensor.wrong_id_after_reset", level="sensor", targets=("mpu6000",), value=0x00,
            doc="The chip answers correctly until it is reset (PWR_MGMT_1 DEVICE_RESET from "
                "the driver, or a power cycle of the sensor rail): from then on WHO_AM_I reads "
                "``value`` (a part damaged by a brown-out or ESD whose fuses reload wrong). "
                "Nothing shows until a reset; then PX4's driver fails its identity check on "
                "every reset ('reset failed'), never re-probes the chip and the sensor is lost "
                "(the voter fails over). Stopping the fault makes the next reset good again.")
def wrong_id_after_reset_start(rig: Any, target: str, params: dict[str, Any],
                               t_ns: int) -> None:
    _set(rig, target, "wrong_id_after_reset", int(params["value"]) & 0xFF)


@wrong_id_after_reset_start.stopper
def wrong_id_after_reset_stop(rig: Any, target: str, params: dict[str, Any], t_ns: int,
                              token: Any) -> None:
    _set(rig, target, "wrong_id_after_reset", None)
