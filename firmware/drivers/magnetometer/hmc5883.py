"""HMC5883L magnetometer driver (I2C), in the shape of PX4's ``hmc5883``.

Flow (reference sheet 5.6): probe reads the three ID bytes one at a time (retrying) and wants
'H', '4', '3'; configure writes CRA (1 sample, 15 Hz, normal) and CRB (+-1.9 Ga, 820 LSB/Ga) and
reads both back; then each run reads the 6 data bytes of the measurement started on the previous
run, starts the next single measurement (MR = 0x01) and sleeps 6666 us: 150 Hz.

Every bus call goes through the handle's ``transfer`` (``I2cDeviceHandle``: the emulated I2C1,
or a Linux bus through ``hil/hostbus.py``) so that a NAK or any other bus error is a result, not
an exception: it is counted as a bad transfer and added to ``error_count``, and the driver keeps trying. An
axis reading the overflow value (-4096, or anything beyond +-2048 as PX4 checks) is counted and
the sample is not published. CRA is re-checked every 128 samples and CRB every 256; a mismatch
is a bad register and the driver rewrites it. A gain change takes effect from the measurement
after next, so the first sample after any CRB write is discarded.

Optional self-test at start (``self_test=True``): CRB = +-2.5 Ga (660 LSB/Ga), positive then
negative bias, averaging four samples each; half the difference is the strap field, which the
datasheet limits (243..575 counts at 390 LSB/Ga) bound to 0.62..1.47 Ga on every axis. The
result is logged and kept in ``self_test_field_ga`` / ``self_test_passed``; a failure does not
stop the driver (PX4 also only reports it).
"""

from __future__ import annotations

from typing import Any, Final

from firmware.drivers.device import BUS_TYPE_I2C, DeviceId, I2cDeviceHandle, SensorDriver
from firmware.platform import Platform
from firmware.platform.perf import PC_COUNT

__all__ = ["DRV_MAG_DEVTYPE_HMC5883", "GAIN_LSB_PER_GA", "Hmc5883Driver"]

DRV_MAG_DEVTYPE_HMC5883: Final = 0x01

# Registers and fields in the datasheet's names (reference sheet 5.3, 5.4).
CRA: Final = 0x00                   # configuration A
CRA_DO: Final = 0x1C                # output rate code
CRA_MS: Final = 0x03                # measurement mode: 00 normal, 01 +bias, 10 -bias
CRB: Final = 0x01                   # configuration B
CRB_GN: Final = 0xE0                # gain code
CRB_GN_LSB: Final = 5
MR: Final = 0x02                    # mode
MR_MD: Final = 0x03                 # 00 continuous, 01 single, 1x idle
DXRA: Final = 0x03                  # X MSB, then X LSB, Z, Y: the 6-byte data block
SR: Final = 0x09
IRA: Final = 0x0A                   # identification "H", "4", "3" in IRA, IRB, IRC
ID: Final = b"H43"
GAIN_LSB_PER_GA: Final[tuple[int, ...]] = (1370, 1090, 820, 660, 440, 390, 330, 230)

CRA_NORMAL: Final = 0x10            # MA = 1 sample, DO = 15 Hz (100), MS = normal
CRA_POS_BIAS: Final = 0x01          # MS = 01
CRA_NEG_BIAS: Final = 0x02          # MS = 10
CRB_RUN: Final = 0x40               # GN = 2: +-1.9 Ga, 820 LSB/Ga (PX4's choice)
CRB_SELF_TEST: Final = 0x60         # GN = 3: +-2.5 Ga, 660 LSB/Ga
MR_SINGLE: Final = 0x01             # MD = 01
MEASURE_INTERVAL_US: Final = 6666   # 150 Hz
RETRY_US: Final = 100_000
PROBE_RETRIES: Final = 10
SELF_TEST_SAMPLES: Final = 4
SELF_TEST_LIMITS_GA = (243 / 390, 575 / 390)
STUCK_SAMPLES: Final = 20
NAK_WARN: Final = 10


class Hmc5883Driver(SensorDriver):
    """Reads an HMC5883L through ``i2c`` (the handle bound to the address the board's spec
    gives, 0x1E on the FMUv2) and publishes ``sensor_mag``."""

    def __init__(self, platform: Platform, i2c: I2cDeviceHandle, name: str = "hmc5883", bus: int = 1,
                 external: bool = True, self_test: bool = False) -> None:
        super().__init__(platform, name, f"wq:I2C{bus}")
        self.i2c = i2c
        self.external = external
        self.want_self_test = self_test
        self.device_id = DeviceId(BUS_TYPE_I2C, bus, i2c.addr, DRV_MAG_DEVTYPE_HMC5883)
        self.gain_lsb_per_ga = GAIN_LSB_PER_GA[CRB_RUN >> CRB_GN_LSB]
        self.perf_range = self.perf_alloc(PC_COUNT, "range (overflow)")
        self.perf_stuck = self.perf_alloc(PC_COUNT, "stuck")
        self.self_test_field_ga: tuple[float, float, float] | None = None
        self.self_test_passed: bool | None = None
        self.stuck = False
        self.overflowing = False
        self._state = "configure"
        self._discard = 0
        self._samples = 0
        self._acc: list[list[int]] = []
        self._pos: tuple[float, float, float] | None = None
        self._naks = 0
        self._last_raw: tuple[int, int, int] | None = None
        self._same = 0
        self._pub: Any = None
        self._msg = platform.orb.new("sensor_mag")
        self.last_field_ga = (float("nan"),) * 3

    # -- bus helpers (errors are results) --------------------------------------------------

    def _read(self, reg: int, n: int) -> bytes | None:
        status, data = self.i2c.transfer(bytes((reg,)), n)
        if status:
            self._nak()
            return None
        self._naks = 0
        return data

    def _write(self, reg: int, value: int) -> bool:
        status, _ = self.i2c.transfer(bytes((reg, value)))
        if status:
            self._nak()
            return False
        self._naks = 0
        return True

    def _nak(self) -> None:
        self.perf_bad_transfer.count()
        self.error_count += 1
        self._naks += 1
        if self._naks == NAK_WARN:
            self.platform.warn(self.name, f"no ACK from 0x{self.i2c.addr:02X} "
                                          f"{NAK_WARN} times in a row")

    # -- probe and start -------------------------------------------------------------------

    def probe(self) -> str | None:
        got = bytearray()
        for i in range(3):
            for _ in range(PROBE_RETRIES):
                status, data = self.i2c.transfer(bytes((IRA + i,)), 1)
                if status == 0:
                    got += data
                    break
            else:
                return (f"no ACK at I2C address 0x{self.i2c.addr:02X} "
                        f"(reading ID register 0x{IRA + i:02X}, {PROBE_RETRIES} tries)")
        if bytes(got) != ID:
            return (f"wrong ID {bytes(got)!r} = {got.hex(' ')} at 0x{self.i2c.addr:02X} "
                    f"(expected {ID!r} = {ID.hex(' ')})")
        return None

    def _start(self) -> None:
        self._pub = self.advertise_multi("sensor_mag")
        self._state = "configure"
        self.schedule_now()

    def _configure(self, cra: int, crb: int) -> bool:
        """Write CRA and CRB and read them back (PX4 ``write_checked_reg``)."""
        if not (self._write(CRA, cra) and self._write(CRB, crb)):
            return False
        back = self._read(CRA, 2)
        if back is None:
            return False
        if back != bytes((cra, crb)):
            self.perf_bad_register.count()
            self.error_count += 1
            return False
        self._discard = 1   # the next measurement still uses the old gain
        return True

    def _trigger(self) -> None:
        self._write(MR, MR_SINGLE)
        self.schedule_delayed(MEASURE_INTERVAL_US)

    # -- the cycle -------------------------------------------------------------------------

    def run(self) -> None:
        if not self.running:
            return
        self.perf_interval.count()
        self.perf_cycle.begin()
        if self._state == "configure":
            if self.want_self_test:
                ok = self._configure(CRA_NORMAL | CRA_POS_BIAS, CRB_SELF_TEST)
                self._state, self._acc = "self_test_pos", []
            else:
                ok = self._configure(CRA_NORMAL, CRB_RUN)
                self._state = "measure"
            if not ok:
                self._state = "configure"
                self.schedule_delayed(RETRY_US)
            else:
                self._trigger()
            self.perf_cycle.end()
            return
        data = self._read(DXRA, 6)
        if data is not None:
            self._sample(data)
        if self._state != "configure":
            self._trigger()
        else:
            self.schedule_delayed(RETRY_US)
        self.perf_cycle.end()

    def _sample(self, data: bytes) -> None:
        x = int.from_bytes(data[0:2], "big", signed=True)
        z = int.from_bytes(data[2:4], "big", signed=True)
        y = int.from_bytes(data[4:6], "big", signed=True)
        if self._discard:
            self._discard -= 1
            return
        if max(abs(x), abs(y), abs(z)) > 2048:
            self.perf_range.count()
            self.error_count += 1
            if not self.overflowing:
                self.overflowing = True
                axes = [n for n, v in zip("XYZ", (x, y, z)) if abs(v) > 2048]
                self.platform.warn(self.name, f"overflow on {''.join(axes)} (raw {x} {y} {z}): "
                                              f"field beyond the configured range")
            return
        self.overflowing = False
        if self._state == "measure":
            self._check_stuck((x, y, z))
            self._samples += 1
            self._recheck()
            self._publish(x, y, z)
        else:
            self._self_test_step(x, y, z)

    def _recheck(self) -> None:
        """PX4 re-reads CRA every 128 and CRB every 256 samples and rewrites on mismatch."""
        n = self._samples
        for period, reg, want in ((128, CRA, CRA_NORMAL), (256, CRB, CRB_RUN)):
            if n % period:
                continue
            got = self._read(reg, 1)
            if got is not None and got[0] != want:
                self.perf_bad_register.count()
                self.error_count += 1
                self.platform.warn(self.name, f"register 0x{reg:02X} reads 0x{got[0]:02X}, "
                                              f"expected 0x{want:02X}: rewriting")
                self._write(reg, want)
                self._discard = 1

    def _check_stuck(self, raw: tuple[int, int, int]) -> None:
        if raw == self._last_raw:
            self._same += 1
            if self._same >= STUCK_SAMPLES - 1:
                self.perf_stuck.count()
                self.error_count += 1
                if not self.stuck:
                    self.stuck = True
                    self.platform.error(self.name, f"field stuck at raw {raw} for "
                                                   f"{STUCK_SAMPLES} samples")
        else:
            self.stuck = False
            self._same = 0
        self._last_raw = raw

    def _self_test_step(self, x: int, y: int, z: int) -> None:
        self._acc.append([x, y, z])
        if len(self._acc) < SELF_TEST_SAMPLES:
            return
        mean = tuple(sum(s[i] for s in self._acc) / len(self._acc) for i in range(3))
        self._acc = []
        if self._state == "self_test_pos":
            self._pos = mean  # type: ignore[assignment]
            self._state = "self_test_neg"
            if not self._write(CRA, CRA_NORMAL | CRA_NEG_BIAS):
                self._state = "configure"
            self._discard = 1
            return
        gain = GAIN_LSB_PER_GA[CRB_SELF_TEST >> CRB_GN_LSB]
        pos = self._pos or (0.0, 0.0, 0.0)
        field = tuple((p - n) / 2.0 / gain for p, n in zip(pos, mean))
        lo, hi = SELF_TEST_LIMITS_GA
        self.self_test_field_ga = field  # type: ignore[assignment]
        self.self_test_passed = all(lo <= f <= hi for f in field)
        text = (f"self-test {'passed' if self.self_test_passed else 'FAILED'}: bias field "
                f"X {field[0]:.3f} Y {field[1]:.3f} Z {field[2]:.3f} Ga "
                f"(limits {lo:.2f}..{hi:.2f})")
        if self.self_test_passed:
            self.platform.info(self.name, text)
        else:
            self.platform.error(self.name, text)
        self.want_self_test = False
        if self._configure(CRA_NORMAL, CRB_RUN):
            self._state = "measure"
        else:
            self._state = "configure"

    def _publish(self, x: int, y: int, z: int) -> None:
        g = self.gain_lsb_per_ga
        field = (x / g, y / g, z / g)
        self.last_field_ga = field
        now = self.platform.time_us()
        msg = self._msg
        msg.timestamp = now
        msg.timestamp_sample = now
        msg.device_id = self.device_id.value
        msg.x, msg.y, msg.z = field
        msg.temperature = float("nan")
        msg.error_count = self.error_count
        msg.is_external = self.external
        self._pub.publish(msg)

    def status(self) -> str:
        lines = [super().status(), "  " + self.perf_range.summary(),
                 "  " + self.perf_stuck.summary()]
        f = self.last_field_ga
        lines.append(f"  {self.gain_lsb_per_ga} LSB/Ga, last field {f[0]:.3f} {f[1]:.3f} "
                     f"{f[2]:.3f} Ga, errors {self.error_count}, external {self.external}")
        if self.self_test_passed is not None:
            lines.append(f"  self-test {'passed' if self.self_test_passed else 'failed'}: "
                         f"{self.self_test_field_ga}")
        return "\n".join(lines)
