"""MS4525DO airspeed sensor driver (I2C), in the shape of PX4's ``ms4525_airspeed``.

The cycle, at 100 Hz (PX4's MEAS_RATE): a *measure* is a one-byte write (the chip's
measurement request; the byte is ignored), then, one conversion interval (10 ms) later, a
*collect* reads the four data bytes, decodes them and publishes ``differential_pressure``;
the same run sends the next measurement request. Errors are results, never exceptions:

* a NAK (or any bus error) on either phase counts a comms error (``perf_bad_transfer``,
  ``error_count``) and the state machine restarts with a new request (PX4's ``start()``);
* status 2 (stale: nothing new since the last fetch), 3 (the chip's diagnostics report a
  fault) and 1 (reserved) count an error and restart the same way, nothing is published;
* a temperature count of 2047 (all ones: an invalid reading) counts an error too.

Counts to units (the datasheet's type-A transfer function, +-1 psi part):
``P = -((counts - 0.1 * 16383) * 2 / (0.8 * 16383) - 1) psi``; the sign is PX4's: the Pixhawk
kit's pitot drives the port that makes the datasheet's P negative, so the negation makes the
pressure positive when the air comes from ahead. ``T = counts * 200 / 2047 - 50`` degC.
SENS_DPRES_OFF (the calibrated zero offset, Pa) is subtracted from both published pressures,
read at every sample so a new calibration applies at once (PX4's sensors module pushes it to
the driver with an ioctl at every parameter update); the filtered pressure is a 2nd-order
Butterworth low-pass at 1.2 Hz on the 100 Hz samples (PX4's MEAS_DRIVER_FILTER_FREQ), primed
with the first sample instead of ramping up from zero.

Not modelled: PX4's correction for the 5 V rail (its ``system_power`` topic is not published on
this board), the MS4515 variant (``-T 4515``).
"""

from __future__ import annotations

from typing import Any, Final

from firmware.drivers.device import BUS_TYPE_I2C, DeviceId, I2cDeviceHandle, SensorDriver
from firmware.modules.sensors.filters import butterworth2
from firmware.platform import Platform
from firmware.platform.perf import PC_COUNT

__all__ = ["DRV_DIFF_PRESS_DEVTYPE_MS4525", "Ms4525Driver", "Sample", "decode"]

DRV_DIFF_PRESS_DEVTYPE_MS4525: Final = 0x49
MEAS_RATE_HZ: Final = 100
CONVERSION_INTERVAL_US: Final = 1_000_000 // MEAS_RATE_HZ
FILTER_CUTOFF_HZ: Final = 1.2
PSI_PA: Final = 6894.757
PROBE_RETRIES: Final = 4
NAK_WARN: Final = 10

STATUS_NORMAL: Final = 0
STATUS_STALE: Final = 2
STATUS_FAULT: Final = 3


class Sample:
    """One decoded data fetch: status, differential pressure (Pa, PX4's sign, no offset
    removed) and temperature (degC); ``why`` says what is wrong with it, or is empty."""

    __slots__ = ("diff_pressure_pa", "status", "temperature_c", "why")

    def __init__(self, status: int, diff_pressure_pa: float, temperature_c: float,
                 why: str) -> None:
        self.status = status
        self.diff_pressure_pa = diff_pressure_pa
        self.temperature_c = temperature_c
        self.why = why


def decode(data: bytes) -> Sample:
    """The four bytes of a Read_DF4 as PX4's ``collect`` reads them (anything else is
    reported in ``why``, never raised)."""
    if len(data) != 4:
        return Sample(-1, float("nan"), float("nan"), f"{len(data)} bytes, expected 4")
    status = data[0] >> 6
    p_counts = (data[0] << 8 | data[1]) & 0x3FFF
    t_counts = (data[2] << 8 | data[3]) >> 5
    psi = -((p_counts - 0.1 * 16383) * 2.0 / (0.8 * 16383) - 1.0)
    temp = t_counts * 200.0 / 2047 - 50.0
    why = ""
    if status == STATUS_STALE:
        why = "stale data"
    elif status == STATUS_FAULT:
        why = "fault detected"
    elif status != STATUS_NORMAL:
        why = f"reserved status {status}"
    elif t_counts == 2047:
        why = "temperature count 2047 (invalid)"
    return Sample(status, psi * PSI_PA, temp, why)


class Ms4525Driver(SensorDriver):
    """Reads an MS4525DO through ``i2c`` (the handle at the spec's address, 0x28) and
    publishes ``differential_pressure``; ``params`` gives SENS_DPRES_OFF (None: no offset)."""

    def __init__(self, platform: Platform, i2c: I2cDeviceHandle, name: str = "ms4525_airspeed",
                 bus: int = 1, params: Any = None) -> None:
        super().__init__(platform, name, f"wq:I2C{bus}")
        self.i2c = i2c
        self.params = params
        self.device_id = DeviceId(BUS_TYPE_I2C, bus, i2c.addr, DRV_DIFF_PRESS_DEVTYPE_MS4525)
        self.perf_stale = self.perf_alloc(PC_COUNT, "stale")
        self.perf_fault = self.perf_alloc(PC_COUNT, "status fault")
        self._b = butterworth2(float(MEAS_RATE_HZ), FILTER_CUTOFF_HZ)
        self._w1 = self._w2 = 0.0
        self._primed = False
        self._collect_phase = False
        self._naks = 0
        self.samples = 0
        self.last_raw_pa = float("nan")
        self.last_temperature_c = float("nan")
        self.max_diff_pressure_pa = 0.0
        self._pub: Any = None
        self._msg = platform.orb.new("differential_pressure")

    # -- bus (errors are results) ----------------------------------------------------------

    def _measure(self) -> bool:
        status, _ = self.i2c.transfer(b"\x00")
        if status:
            self._comms_error()
            return False
        return True

    def _comms_error(self) -> None:
        self.perf_bad_transfer.count()
        self.error_count += 1
        self._naks += 1
        if self._naks == NAK_WARN:
            self.platform.warn(self.name, f"no ACK from 0x{self.i2c.addr:02X} "
                                          f"{NAK_WARN} times in a row")

    # -- probe and start -------------------------------------------------------------------

    def probe(self) -> str | None:
        for _ in range(PROBE_RETRIES):
            if self.i2c.transfer(b"\x00")[0] == 0:
                return None
        return f"no ACK at I2C address 0x{self.i2c.addr:02X} ({PROBE_RETRIES} tries)"

    def _start(self) -> None:
        self._pub = self.advertise_multi("differential_pressure")
        self._restart()

    def _restart(self) -> None:
        """PX4's ``start()``: back to the measure phase, now."""
        self._collect_phase = False
        self.schedule_now()

    # -- the cycle -------------------------------------------------------------------------

    def run(self) -> None:
        if not self.running:
            return
        self.perf_interval.count()
        self.perf_cycle.begin()
        if self._collect_phase:
            ok = self._collect()
            if not ok:
                self.perf_cycle.end()
                self._restart()
                return
        self._collect_phase = self._measure()
        self.schedule_delayed(CONVERSION_INTERVAL_US)
        self.perf_cycle.end()

    def _collect(self) -> bool:
        status, data = self.i2c.transfer(b"", 4)
        if status:
            self._comms_error()
            return False
        self._naks = 0
        s = decode(data)
        if s.why:
            self.error_count += 1
            if s.status == STATUS_STALE:
                self.perf_stale.count()
            else:
                self.perf_fault.count()
            self.perf_bad_transfer.count()
            return False
        self._publish(s.diff_pressure_pa, s.temperature_c)
        return True

    def _filter(self, x: float) -> float:
        b0, b1, b2, a1, a2 = self._b
        if not self._primed:
            self._primed = True
            d = 1.0 + a1 + a2
            self._w1 = self._w2 = x / d if d else x
        w0 = x - a1 * self._w1 - a2 * self._w2
        y = b0 * w0 + b1 * self._w1 + b2 * self._w2
        self._w2, self._w1 = self._w1, w0
        return y

    def offset_pa(self) -> float:
        p = self.params
        if p is None or "SENS_DPRES_OFF" not in p:
            return 0.0
        return float(p["SENS_DPRES_OFF"])

    def _publish(self, diff_pa: float, temperature_c: float) -> None:
        raw = diff_pa - self.offset_pa()
        filtered = self._filter(raw)
        self.samples += 1
        self.last_raw_pa = raw
        self.last_temperature_c = temperature_c
        if raw > self.max_diff_pressure_pa:
            self.max_diff_pressure_pa = raw
        m = self._msg
        m.timestamp = self.platform.time_us()
        m.error_count = self.error_count
        m.differential_pressure_raw_pa = raw
        m.differential_pressure_filtered_pa = filtered
        m.temperature = temperature_c
        m.device_id = self.device_id.value
        self._pub.publish(m)

    def status(self) -> str:
        lines = [super().status(), "  " + self.perf_stale.summary(),
                 "  " + self.perf_fault.summary(),
                 f"  {self.samples} samples, last {self.last_raw_pa:.2f} Pa "
                 f"{self.last_temperature_c:.1f} degC, max {self.max_diff_pressure_pa:.1f} Pa, "
                 f"offset {self.offset_pa():.2f} Pa, errors {self.error_count}"]
        return "\n".join(lines)
