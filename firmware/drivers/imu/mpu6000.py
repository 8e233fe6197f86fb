"""MPU-6000 driver in the shape of PX4's modern InvenSense drivers.

State machine (each step ends by scheduling the next run on ``wq:SPI1``)::

    RESET -> WAIT_FOR_RESET -> CONFIGURE -> FIFO_READ
      ^             |              |            |
      +-- 1 s, no --+-- 5 fails ---+- bad reg. -+-- no answer (3 x 0xFF)

* The chip runs at its reset sample rate, 8 kHz (DLPF_CFG 0, SMPLRT_DIV 0), +-2000 deg/s and
  +-16 g, accel and gyro into the FIFO (12-byte records), INT active low on data ready.
* Publication rate: PX4's ``ConfigureSampleRate`` with the gyro's rate limit (``max_rate_hz``;
  the board passes IMU_GYRO_RATEMAX, default 400 Hz, as PX4's gyro front end does): the FIFO
  read interval is the limit's interval rounded to a multiple of 500 µs (2 kHz at most), in
  whole 8 kHz records, at most 32 of them. 400 Hz gives 20 records every 2.5 ms; 1 kHz eight
  every 1 ms. Each read publishes ``sensor_gyro`` and ``sensor_accel`` once, the records
  averaged (``samples`` says how many). With a DRDY pin the falling edge of every N-th
  interrupt schedules the FIFO read; without one the driver polls at that interval.
* Register access at 1 MHz; FIFO count, FIFO data and temperature at 20 MHz requested.
* Health, as a PX4 driver would see it: one configuration register (or WHO_AM_I) is re-read
  every 10 ms and any mismatch triggers a full reset (perf ``bad register``); FIFO count or data
  of all 0xFF is a bad transfer, three in a row reset the chip; a FIFO at 1024 bytes is an
  overflow (FIFO reset); accel must repeat over 8 records at 8 kHz (else the data is corrupt:
  bad transfer, FIFO reset); 100 cycles of identical records are reported as stuck data; no
  data-ready for 4 publication intervals falls back to polling and counts missed samples;
  clipping is counted per axis in ``clip_counter``. Every error also increments
  ``error_count`` in the published messages. A bias step is data, not a fault the driver can
  see: it passes through to the estimator, whose checks own it.

Counts to SI use PX4's scales: accel 9.80665/2048 m/s^2 per LSB (doubled LSB/g on rev C
silicon, whose sensitivity is twice rev D's), gyro radians(2000/32768) rad/s per LSB.
"""

from __future__ import annotations

import math
import struct
from typing import Any, Final

from firmware.drivers.device import BUS_TYPE_SPI, DeviceId, SensorDriver
from firmware.drivers.imu import rotation_matrix
from firmware.platform import Platform
from firmware.platform.perf import PC_COUNT
from common.units import G0_M_S2

__all__ = ["DRV_IMU_DEVTYPE_MPU6000", "PRODUCT_IDS", "Mpu6000Driver", "fifo_records_per_read",
           "gyro_rate_limit"]

DRV_IMU_DEVTYPE_MPU6000: Final = 0x21
WHO_AM_I_VALUE: Final = 0x68
#: PRODUCT_ID codes the legacy PX4 driver accepts (ES and production, rev C4..D10).
PRODUCT_IDS: Final = frozenset({0x14, 0x15, 0x16, 0x17, 0x18,
                         0x54, 0x55, 0x56, 0x57, 0x58, 0x59, 0x5A})
REV_C_IDS: Final = frozenset({0x14, 0x15, 0x54, 0x55})

# Registers and bits, in the register map's names (reference sheet 1.4, 1.5).
PRODUCT_ID: Final = 0x0C
SMPLRT_DIV: Final = 0x19
CONFIG: Final = 0x1A
CONFIG_DLPF_CFG: Final = 0x07
GYRO_CONFIG: Final = 0x1B
GYRO_CONFIG_FS_SEL_2000DPS: Final = 0x18         # FS_SEL 3
ACCEL_CONFIG: Final = 0x1C
ACCEL_CONFIG_AFS_SEL_16G: Final = 0x18           # AFS_SEL 3
SELF_TEST_BITS: Final = 0xE0                     # X/Y/Z self-test (GYRO_ and ACCEL_CONFIG)
FIFO_EN: Final = 0x23
FIFO_EN_TEMP_FIFO_EN: Final = 0x80
FIFO_EN_XG_FIFO_EN: Final = 0x40
FIFO_EN_YG_FIFO_EN: Final = 0x20
FIFO_EN_ZG_FIFO_EN: Final = 0x10
FIFO_EN_ACCEL_FIFO_EN: Final = 0x08
INT_PIN_CFG: Final = 0x37
INT_PIN_CFG_INT_LEVEL: Final = 0x80              # 1: active low
INT_ENABLE: Final = 0x38
INT_ENABLE_DATA_RDY_EN: Final = 0x01
TEMP_OUT_H: Final = 0x41
SIGNAL_PATH_RESET: Final = 0x68
SIGNAL_PATH_RESET_GYRO_RESET: Final = 0x04
SIGNAL_PATH_RESET_ACCEL_RESET: Final = 0x02
SIGNAL_PATH_RESET_TEMP_RESET: Final = 0x01
USER_CTRL: Final = 0x6A
USER_CTRL_FIFO_EN: Final = 0x40
USER_CTRL_I2C_IF_DIS: Final = 0x10
USER_CTRL_FIFO_RESET: Final = 0x04
USER_CTRL_SIG_COND_RESET: Final = 0x01
PWR_MGMT_1: Final = 0x6B
PWR_MGMT_1_DEVICE_RESET: Final = 0x80
PWR_MGMT_1_SLEEP: Final = 0x40
PWR_MGMT_1_CLKSEL_PLL_X: Final = 0x01            # CLKSEL 1: PLL with the X gyro
#: PWR_MGMT_1 after a reset: asleep on the internal oscillator.
PWR_MGMT_1_RESET_VALUE: Final = PWR_MGMT_1_SLEEP
FIFO_COUNTH: Final = 0x72
FIFO_R_W: Final = 0x74
WHO_AM_I: Final = 0x75
DIR_READ: Final = 0x80

#: What goes into the FIFO: the three gyro axes and the accelerometer, not the temperature.
FIFO_SOURCES: Final = (FIFO_EN_XG_FIFO_EN | FIFO_EN_YG_FIFO_EN | FIFO_EN_ZG_FIFO_EN
                       | FIFO_EN_ACCEL_FIFO_EN)

#: (register, bits to set, bits to clear): what configure() writes and the check re-reads.
REGISTER_CONFIG: Final[tuple[tuple[int, int, int], ...]] = (
    (SMPLRT_DIV, 0x00, 0xFF),                                    # 8 kHz / (1 + 0)
    (CONFIG, 0x00, CONFIG_DLPF_CFG),                             # 256 Hz gyro, 8 kHz
    (GYRO_CONFIG, GYRO_CONFIG_FS_SEL_2000DPS, SELF_TEST_BITS),   # +-2000 deg/s
    (ACCEL_CONFIG, ACCEL_CONFIG_AFS_SEL_16G, SELF_TEST_BITS),    # +-16 g
    (FIFO_EN, FIFO_SOURCES, FIFO_EN_TEMP_FIFO_EN),
    (INT_PIN_CFG, INT_PIN_CFG_INT_LEVEL, 0x00),                  # INT active low
    (INT_ENABLE, INT_ENABLE_DATA_RDY_EN, 0x00),
    (USER_CTRL, USER_CTRL_FIFO_EN | USER_CTRL_I2C_IF_DIS, 0x00),
    (PWR_MGMT_1, PWR_MGMT_1_CLKSEL_PLL_X, PWR_MGMT_1_SLEEP),
)

SAMPLE_RATE_HZ: Final = 8000
FIFO_SIZE: Final = 1024
RECORD_BYTES: Final = 12
MAX_RECORDS: Final = FIFO_SIZE // RECORD_BYTES
RECORD_US: Final = 1_000_000 // SAMPLE_RATE_HZ
#: Records per read at most: PX4's ``sensor_gyro_fifo`` holds 32 samples.
FIFO_MAX_SAMPLES: Final = 32
ACCEL_SCALE: Final = G0_M_S2 / 2048.0
GYRO_SCALE: Final = math.radians(2000.0 / 32768.0)
REG_CLOCK_HZ: Final = 1_000_000
DATA_CLOCK_HZ: Final = 20_000_000
REGISTER_CHECK_US: Final = 10_000
TEMPERATURE_US: Final = 1_000_000
STUCK_CYCLES: Final = 100
NO_ANSWER_RESET: Final = 3

#: FIFO count read: the command and two clock-out bytes (FIFO_COUNTH, FIFO_COUNTL).
_FIFO_COUNT_TX: Final = bytes((FIFO_COUNTH | DIR_READ, 0, 0))

RESET: Final = "reset"
WAIT_FOR_RESET: Final = "wait_for_reset"
CONFIGURE: Final = "configure"
FIFO_READ: Final = "fifo_read"


def gyro_rate_limit(params: Any) -> float:
    """IMU_GYRO_RATEMAX from a parameter set, as PX4's gyro front end reads it for its driver
    (0, which means 1 kHz, where the set has no such parameter or there is no set)."""
    return float(params.get("IMU_GYRO_RATEMAX", 0)) if params is not None else 0.0


def fifo_records_per_read(max_rate_hz: float) -> int:
    """PX4's MPU6000 ``ConfigureSampleRate``: 8 kHz records per FIFO read for a gyro rate
    limit (0 means 1 kHz). The interval is rounded to a multiple of four records (500 µs, so
    2 kHz at most), halves away from zero as ``roundf`` does, and capped at 32 records."""
    if max_rate_hz < 0:
        raise ValueError(f"gyro rate limit must be positive (or 0 for 1 kHz), got {max_rate_hz}")
    rate = max_rate_hz or 1000.0
    step = 4 * RECORD_US
    interval = max(math.floor(1e6 / rate / step + 0.5) * step, step)
    return min(interval // RECORD_US, FIFO_MAX_SAMPLES)


class Mpu6000Driver(SensorDriver):
    """One MPU-6000 on an SPI chip select, publishing ``sensor_accel`` and ``sensor_gyro``.

    ``drdy_pin`` is the board pin wired to INT (PD15 on FMUv2; None: poll). ``address`` goes
    into the device id (the chip-select index). ``rotation`` is the PX4 mounting rotation
    applied to the data before publication. ``max_rate_hz`` is the gyro's rate limit that sets
    the FIFO read interval (:func:`fifo_records_per_read`; IMU_GYRO_RATEMAX on a board).
    """

    def __init__(self, platform: Platform, spi_handle: Any, drdy_pin: Any | None = None,
                 bus: int = 1, rotation: int | str = 0, name: str = "mpu6000",
                 address: int = 0, max_rate_hz: float = 1000.0) -> None:
        super().__init__(platform, name, "wq:SPI1")
        records = fifo_records_per_read(max_rate_hz)
        self.spi = spi_handle
        self.drdy_pin = drdy_pin
        self.rotation = rotation_matrix(rotation)
        self.device_id = DeviceId(BUS_TYPE_SPI, bus, address, DRV_IMU_DEVTYPE_MPU6000).value
        self.samples_per_publish = records
        self.publish_interval_us = records * RECORD_US
        self.perf_fifo_empty = self.perf_alloc(PC_COUNT, "FIFO empty")
        self.perf_fifo_overflow = self.perf_alloc(PC_COUNT, "FIFO overflow")
        self.perf_fifo_reset = self.perf_alloc(PC_COUNT, "FIFO reset")
        self.perf_drdy_timeout = self.perf_alloc(PC_COUNT, "DRDY timeout")
        self.perf_stuck = self.perf_alloc(PC_COUNT, "stuck data")
        self.perf_reset = self.perf_alloc(PC_COUNT, "reset")
        self.state = RESET
        self.product_id: int | None = None
        self.accel_scale = ACCEL_SCALE
        self.temperature = math.nan
        self.publications = 0
        self._clock = 0
        self._attached = False
        self._reset_start_us = 0
        self._reset_failures = 0
        self._configure_failures = 0
        self._drdy_count = 0
        self._drdy_seen = False
        self._last_drdy_ns = 0
        self._polling_fallback = False
        self._no_answer = 0
        self._stuck_cycles = 0
        self._corrupt = 0
        self._last_record: bytes = b""
        self._clipping = False
        self._next_check_us = 0
        self._next_temp_us = 0
        self._check_index = 0
        self._fifo_tx: dict[int, bytes] = {}
        self._fifo_unpack: dict[int, Any] = {}  # records -> compiled big-endian unpack
        orb = platform.orb
        self._pub_accel = self.advertise_multi("sensor_accel")
        self._pub_gyro = self.advertise_multi("sensor_gyro")
        self._accel = orb.new("sensor_accel", device_id=self.device_id)
        self._gyro = orb.new("sensor_gyro", device_id=self.device_id)

    # -- register access --------------------------------------------------------------------------

    def _set_clock(self, hz: int) -> None:
        if self._clock != hz:
            self.spi.max_speed_hz = hz
            self._clock = hz

    def read_reg(self, reg: int) -> int:
        self._set_clock(REG_CLOCK_HZ)
        return self.spi.transfer(bytes((reg | DIR_READ, 0)))[1]

    def write_reg(self, reg: int, value: int) -> None:
        self._set_clock(REG_CLOCK_HZ)
        self.spi.transfer(bytes((reg & ~DIR_READ & 0xFF, value & 0xFF)))

    def modify_reg(self, reg: int, set_bits: int, clear_bits: int) -> None:
        orig = self.read_reg(reg)
        value = (orig | set_bits) & ~clear_bits & 0xFF
        if value != orig:
            self.write_reg(reg, value)

    # -- life cycle -------------------------------------------------------------------------------

    def probe(self) -> str | None:
        who = self.read_reg(WHO_AM_I)
        if who != WHO_AM_I_VALUE:
            return f"WHO_AM_I read 0x{who:02X}, expected 0x{WHO_AM_I_VALUE:02X}"
        pid = self.read_reg(PRODUCT_ID)
        if pid not in PRODUCT_IDS:
            return (f"unexpected PRODUCT_ID 0x{pid:02X}, expected one of "
                    f"{', '.join(f'0x{p:02X}' for p in sorted(PRODUCT_IDS))}")
        self.product_id = pid
        # Rev C silicon has twice the sensitivity: AFS_SEL 3 gives 4096 LSB/g (+-8 g).
        self.accel_scale = ACCEL_SCALE / 2 if pid in REV_C_IDS else ACCEL_SCALE
        return None

    def _start(self) -> None:
        if self.drdy_pin is not None and not self._attached:
            self.drdy_pin.attach_interrupt(self._drdy_isr, rising=False, falling=True)
            self._attached = True
        self.state = RESET
        self.schedule_now()

    def stop(self) -> None:
        if self._attached and self.drdy_pin is not None:
            self.drdy_pin.detach_interrupt()
            self._attached = False
        self.state = RESET
        super().stop()

    @property
    def publish_rate_hz(self) -> float:
        """FIFO reads (and publications) per second."""
        return 1e6 / self.publish_interval_us

    def status(self) -> str:
        pid = "?" if self.product_id is None else f"0x{self.product_id:02X}"
        extra = [(f"  state {self.state}, product id {pid}, {self.temperature:.2f} degC, "
                  f"{self.publications} publications, error count {self.error_count}"),
                 (f"  FIFO read every {self.publish_interval_us} us ({self.publish_rate_hz:.1f} Hz,"
                  f" {self.samples_per_publish} records)")]
        extra += ["  " + pc.summary() for pc in (
            self.perf_fifo_empty, self.perf_fifo_overflow, self.perf_fifo_reset,
            self.perf_drdy_timeout, self.perf_stuck, self.perf_reset)]
        return "\n".join([super().status()] + extra)

    def _error(self, counter: Any | None = None) -> None:
        self.error_count += 1
        if counter is not None:
            counter.count()

    def _drdy_isr(self, pin: Any, t_ns: int) -> None:
        """Falling edge of INT: count samples, schedule the FIFO read every N of them."""
        if self.state != FIFO_READ:
            return
        self._last_drdy_ns = t_ns
        self._drdy_count += 1
        if self._drdy_count >= self.samples_per_publish:
            self._drdy_count = 0
            self._drdy_seen = True
            self.schedule_now()

    # -- the state machine -------------------------------------------------------------------------

    def run(self) -> None:
        state = self.state
        if state == FIFO_READ:
            self._cycle()
        elif state == RESET:
            self.perf_reset.count()
            self.write_reg(PWR_MGMT_1, PWR_MGMT_1_DEVICE_RESET)
            if self._reset_failures == 0:
                self._reset_start_us = self.platform.time_us()
            self.state = WAIT_FOR_RESET
            self.schedule_delayed(100_000)
        elif state == WAIT_FOR_RESET:
            self._wait_for_reset()
        elif state == CONFIGURE:
            self._configure()

    def _wait_for_reset(self) -> None:
        who = self.read_reg(WHO_AM_I)
        pwr = self.read_reg(PWR_MGMT_1)
        if who == WHO_AM_I_VALUE and pwr == PWR_MGMT_1_RESET_VALUE:
            if self._reset_failures:
                self.platform.info(self.name, "reset succeeded")
            self._reset_failures = 0
            self.write_reg(PWR_MGMT_1, PWR_MGMT_1_CLKSEL_PLL_X)  # wake
            self.write_reg(SIGNAL_PATH_RESET, SIGNAL_PATH_RESET_GYRO_RESET
                           | SIGNAL_PATH_RESET_ACCEL_RESET | SIGNAL_PATH_RESET_TEMP_RESET)
            self.write_reg(USER_CTRL, USER_CTRL_SIG_COND_RESET | USER_CTRL_I2C_IF_DIS)
            self.state = CONFIGURE
            self._configure_failures = 0
            self.schedule_delayed(100_000)
            return
        if self.platform.time_us() - self._reset_start_us < 1_000_000:
            self.schedule_delayed(10_000)
            return
        self._reset_failures += 1
        self._error(self.perf_bad_register)
        if self._reset_failures == 1 or self._reset_failures % 10 == 0:
            self.platform.error(self.name, f"reset failed ({self._reset_failures}x): WHO_AM_I "
                                           f"0x{who:02X} PWR_MGMT_1 0x{pwr:02X}, expected "
                                           f"0x68/0x40; retrying")
        self._reset_start_us = self.platform.time_us()
        self.state = RESET
        self.schedule_delayed(100_000)

    def _configure(self) -> None:
        for reg, set_bits, clear_bits in REGISTER_CONFIG:
            self.modify_reg(reg, set_bits, clear_bits)
        bad = self._check_all()
        if bad is not None:
            self._configure_failures += 1
            if self._configure_failures < 5:
                self.schedule_delayed(10_000)
                return
            self._error(self.perf_bad_register)
            self.platform.error(self.name, f"configure failed: {bad}; resetting")
            self.state = RESET
            self.schedule_delayed(100_000)
            return
        self.state = FIFO_READ
        self._fifo_reset()
        now = self.platform.time_us()
        self._next_check_us = now + REGISTER_CHECK_US
        self._next_temp_us = now
        self._read_temperature()
        if self.drdy_pin is not None:
            self._polling_fallback = False
            self.schedule_delayed(4 * self.publish_interval_us)  # DRDY watchdog
        else:
            self.schedule_on_interval(self.publish_interval_us)

    def _check_reg(self, reg: int, set_bits: int, clear_bits: int) -> str | None:
        value = self.read_reg(reg)
        if reg == WHO_AM_I:
            ok = value == WHO_AM_I_VALUE
        else:
            ok = (value & set_bits) == set_bits and not value & clear_bits
        return None if ok else (f"register 0x{reg:02X} read 0x{value:02X} (set 0x{set_bits:02X}"
                                f" clear 0x{clear_bits:02X})")

    def _check_all(self) -> str | None:
        for row in REGISTER_CONFIG:
            bad = self._check_reg(*row)
            if bad is not None:
                return bad
        return None

    def _fifo_reset(self) -> None:
        """PX4's sequence: stop the sources, reset with the FIFO off, enable again."""
        self.perf_fifo_reset.count()
        self.write_reg(FIFO_EN, 0x00)
        self.write_reg(USER_CTRL, USER_CTRL_FIFO_RESET | USER_CTRL_I2C_IF_DIS)  # FIFO_EN off
        self.write_reg(FIFO_EN, FIFO_SOURCES)
        self.write_reg(USER_CTRL, USER_CTRL_FIFO_EN | USER_CTRL_I2C_IF_DIS)
        self._drdy_count = 0
        self._last_record = b""

    def _read_temperature(self) -> None:
        self._set_clock(DATA_CLOCK_HZ)
        r = self.spi.transfer(bytes((TEMP_OUT_H | DIR_READ, 0, 0)))
        raw = int.from_bytes(r[1:3], "big", signed=True)
        t = raw / 340.0 + 36.53
        if -40.0 <= t <= 85.0:
            self.temperature = t
            self._accel.temperature = self._gyro.temperature = t
        else:
            self._error(self.perf_bad_transfer)
        self._next_temp_us += TEMPERATURE_US

    def _reset_chip(self, why: str) -> None:
        self.platform.error(self.name, f"{why}; resetting")
        self.state = RESET
        self._reset_failures = 0
        self.schedule_clear()  # drop the poll interval or DRDY watchdog
        self.schedule_now()

    # -- FIFO_READ -------------------------------------------------------------------------------

    def _cycle(self) -> None:
        self.perf_interval.count()
        now = self.platform.time_us()
        if self.drdy_pin is not None:
            self._watchdog()
        self.perf_cycle.begin()
        try:
            self._read_fifo(now)
        finally:
            self.perf_cycle.end()
        if self.state != FIFO_READ:
            return
        now = self.platform.time_us()
        if now >= self._next_check_us:
            self._next_check_us = now + REGISTER_CHECK_US
            self._periodic_check()
        if self.state == FIFO_READ and now >= self._next_temp_us:
            self._read_temperature()

    def _watchdog(self) -> None:
        """Re-arm the DRDY timeout; a run without the ISR having asked for it is a timeout."""
        if self._drdy_seen:
            self._drdy_seen = False
            if self._polling_fallback:
                self._polling_fallback = False
                self.platform.info(self.name, "data-ready interrupts are back")
            self.schedule_delayed(4 * self.publish_interval_us)
            return
        self._error(self.perf_drdy_timeout)
        self.perf_missed.count()
        if not self._polling_fallback:
            self._polling_fallback = True
            self.platform.warn(self.name, f"no data-ready for {4 * self.publish_interval_us} us; "
                                          f"polling the FIFO every {self.publish_interval_us} us")
        self.schedule_delayed(self.publish_interval_us)

    def _periodic_check(self) -> None:
        """Re-read one configuration register (WHO_AM_I among them) per call."""
        rows = REGISTER_CONFIG + ((WHO_AM_I, WHO_AM_I_VALUE, 0),)
        row = rows[self._check_index % len(rows)]
        self._check_index += 1
        bad = self._check_reg(*row)
        if bad is not None:
            self._error(self.perf_bad_register)
            self._reset_chip(f"configuration lost: {bad}")

    def _no_answer_seen(self, what: str) -> None:
        self._error(self.perf_bad_transfer)
        self._no_answer += 1
        if self._no_answer >= NO_ANSWER_RESET:
            self._no_answer = 0
            self._reset_chip(f"no answer ({what} all 0xFF, {NO_ANSWER_RESET} times)")

    def _read_fifo(self, now_us: int) -> None:
        self._set_clock(DATA_CLOCK_HZ)
        transfer = self.spi.transfer
        r = transfer(_FIFO_COUNT_TX)  # FIFO_COUNTH | DIR_READ, then H and L
        count = (r[1] << 8) | r[2]
        if count == 0xFFFF:
            self._no_answer_seen("FIFO count")
            return
        if count == 0:
            self.perf_fifo_empty.count()
            return
        if count >= FIFO_SIZE:
            self._error(self.perf_fifo_overflow)
            self._fifo_reset()
            return
        n = count // RECORD_BYTES
        if n == 0:
            self.perf_fifo_empty.count()
            return
        tx = self._fifo_tx.get(n)
        if tx is None:
            tx = self._fifo_tx[n] = bytes((FIFO_R_W | DIR_READ,)) + bytes(n * RECORD_BYTES)
        data = transfer(tx)[1:]
        if not data.strip(b"\xff"):
            self._no_answer_seen("FIFO data")
            return
        self._no_answer = 0
        unpack = self._fifo_unpack.get(n)
        if unpack is None:
            unpack = self._fifo_unpack[n] = struct.Struct(f">{6 * n}h").unpack
        raw = unpack(data)
        if not self._accel_repeats(raw, n):
            self._error(self.perf_bad_transfer)
            self._corrupt += 1
            if self._corrupt == 1 or self._corrupt % 1000 == 0:
                self.platform.warn(self.name, f"corrupt FIFO data ({self._corrupt}x): accel "
                                              f"not repeating at 8 kHz; FIFO reset")
            self._fifo_reset()
            return
        self._check_stuck(data, n)
        self._publish(raw, n, now_us)

    @staticmethod
    def _accel_repeats(raw: tuple[int, ...], n: int) -> bool:
        """At 8 kHz the accelerometer (1 kHz) must repeat: at most one change per 8 records.
        Corrupt or random data fails this long before it fails anything else."""
        if n < 2:
            return True
        changes = 0  # consecutive records whose accel differs (an index loop: compiled, native)
        px, py, pz = raw[0], raw[1], raw[2]
        for i in range(6, 6 * n, 6):
            x, y, z = raw[i], raw[i + 1], raw[i + 2]
            if x != px or y != py or z != pz:
                changes += 1
                px, py, pz = x, y, z
        return changes <= n // 8 + 1

    def _check_stuck(self, data: bytes, n: int) -> None:
        last = data[-RECORD_BYTES:]
        same = last == self._last_record and data == last * n
        self._last_record = last
        if not same:
            if self._stuck_cycles >= STUCK_CYCLES:
                self.platform.info(self.name, "data is changing again")
            self._stuck_cycles = 0
            return
        self._stuck_cycles += 1
        if self._stuck_cycles == STUCK_CYCLES:
            self._error(self.perf_stuck)
            self.platform.warn(self.name, f"data stuck: {STUCK_CYCLES} FIFO reads of identical "
                                          f"samples")

    def _publish(self, raw: tuple[int, ...], n: int, now_us: int) -> None:
        sa = self.accel_scale / n
        sg = GYRO_SCALE / n
        # Per-axis sums in one index loop (native when compiled): exact integers, so the means
        # are those of sum() over slices.
        s0 = s1 = s2 = s3 = s4 = s5 = 0
        for i in range(0, 6 * n, 6):
            s0 += raw[i]
            s1 += raw[i + 1]
            s2 += raw[i + 2]
            s3 += raw[i + 3]
            s4 += raw[i + 4]
            s5 += raw[i + 5]
        ax, ay, az = s0 * sa, s1 * sa, s2 * sa
        gx, gy, gz = s3 * sg, s4 * sg, s5 * sg
        rot = self.rotation
        if rot is not None:
            (r0, r1, r2) = rot
            ax, ay, az = (r0[0] * ax + r0[1] * ay + r0[2] * az, r1[0] * ax + r1[1] * ay
                          + r1[2] * az, r2[0] * ax + r2[1] * ay + r2[2] * az)
            gx, gy, gz = (r0[0] * gx + r0[1] * gy + r0[2] * gz, r1[0] * gx + r1[1] * gy
                          + r1[2] * gz, r2[0] * gx + r2[1] * gy + r2[2] * gz)
        clipped = max(raw) >= 32767 or min(raw) <= -32767
        if clipped and not self._clipping:
            self.platform.warn(self.name, "clipping at full scale")
        self._clipping = clipped
        if self.drdy_pin is not None and not self._polling_fallback:
            t_sample = self._last_drdy_ns // 1000
        else:
            t_sample = now_us
        ts = self.platform.time_us()
        a = self._accel
        a.timestamp, a.timestamp_sample = ts, t_sample
        a.x, a.y, a.z = ax, ay, az
        a.error_count = self.error_count
        a.samples = n
        g = self._gyro
        g.timestamp, g.timestamp_sample = ts, t_sample
        g.x, g.y, g.z = gx, gy, gz
        g.error_count = self.error_count
        g.samples = n
        if clipped:  # samples at a rail, per sensor axis (PX4 counts both rails)
            c = [min(sum(1 for v in raw[i::6] if v >= 32767 or v <= -32767), 255)
                 for i in range(6)]
            a.clip_counter, g.clip_counter = c[:3], c[3:]
        else:
            a.clip_counter = g.clip_counter = [0, 0, 0]
        self._pub_accel.publish(a)
        self._pub_gyro.publish(g)
        self.publications += 1
