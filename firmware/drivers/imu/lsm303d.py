"""LSM303D accelerometer + magnetometer driver (SPI), in the shape of PX4's modern driver.

Flow (reference sheet 3.7): probe WHO_AM_I = 0x49; reset with CTRL0.BOOT and wait 150 ms;
configure every register read-modify-write (set bits / clear bits) and read it back: accel
1600 Hz, BDU, +-16 g, 773 Hz anti-alias, FIFO enabled in FIFO mode with the threshold at the
samples per cycle; temperature on, magnetometer high resolution, 50 Hz, +-12 gauss, continuous.
PX4 modern polls (no data-ready pins used), so does this driver:

* every ``ACCEL_INTERVAL_US`` (2.5 ms, 4 samples at 1600 Hz): read FIFO_SRC; on OVRN (the FIFO
  filled and stopped) reset the FIFO through Bypass mode and count the overflow; otherwise read
  FSS samples in ONE auto-increment burst from OUT_X_L_A (the chip wraps 0x2D -> 0x28) and
  publish their mean on ``sensor_accel`` (``samples`` = how many): 400 Hz;
* every 20 ms: one burst from TEMP_OUT_L (0xC5: temperature, STATUS_M, mag X/Y/Z), published on
  ``sensor_mag`` when ZYXMDA is set: 50 Hz;
* every 100 ms: one configuration register is checked; a mismatch is counted and the register
  rewritten; a wrong WHO_AM_I resets the chip.

What the driver notices: all-0xFF transfers (the chip is gone: bad transfer, 10 in a row reset
it), FIFO_SRC that cannot be (EMPTY with samples), temperature outside -40..85 degC (garbage),
frozen data (``STUCK_SAMPLES`` identical accel samples or mag samples: reset), FIFO overrun
(missed samples), samples at the 16-bit limit (clip counters, saturation warning), changed
registers, wrong ID after reset (refused, retried every 100 ms).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from typing import Any, Final

from board.spi import SpiHandle
from firmware.drivers.device import BUS_TYPE_SPI, DeviceId, SensorDriver
from firmware.drivers.imu.l3gd20 import sensor_to_board
from firmware.platform import Platform
from firmware.platform.perf import PC_COUNT

__all__ = [
    "DRV_ACC_DEVTYPE_LSM303D",
    "DRV_MAG_DEVTYPE_LSM303D",
    "SPI_DEVICE_ACCEL_MAG",
    "Lsm303dDriver",
]

#: PX4 drv_sensor.h device types.
DRV_ACC_DEVTYPE_LSM303D: Final = 0x11
DRV_MAG_DEVTYPE_LSM303D: Final = 0x02
#: Legacy PX4 device number of the LSM303D on SPI1 (reference sheet 7.3).
SPI_DEVICE_ACCEL_MAG: Final = 2

WHO_AM_I: Final = 0x0F
WHO_AM_I_VALUE: Final = 0x49
TEMP_OUT_L: Final = 0x05
CTRL0: Final = 0x1F
CTRL1: Final = 0x20
CTRL2: Final = 0x21
CTRL5: Final = 0x24
CTRL6: Final = 0x25
CTRL7: Final = 0x26
OUT_X_L_A: Final = 0x28
FIFO_CTRL: Final = 0x2E
FIFO_SRC: Final = 0x2F
DIR_READ: Final = 0x80
ADDR_INCREMENT: Final = 0x40
FIFO_SRC_OVRN: Final = 0x40
FIFO_SRC_EMPTY: Final = 0x20
FIFO_SRC_FSS: Final = 0x1F
STATUS_M_ZYXMDA: Final = 0x08

ACCEL_ODR_HZ: Final = 1600
ACCEL_INTERVAL_US: Final = 2500
SAMPLES_PER_CYCLE: Final = ACCEL_ODR_HZ * ACCEL_INTERVAL_US // 1_000_000   # 4 -> FIFO threshold
MAG_INTERVAL_US: Final = 20_000
CHECK_INTERVAL_US: Final = 100_000
ACCEL_SCALE_M_S2: Final = 0.732e-3 * 9.80665       # +-16 g: 0.732 mg/LSB
MAG_SCALE_GAUSS: Final = 0.479e-3                  # +-12 gauss: 0.479 mgauss/LSB
BOOT_WAIT_US: Final = 150_000
RESET_RETRY_US: Final = 100_000
BAD_TRANSFERS_RESET: Final = 10
STUCK_SAMPLES: Final = 50
REPORT_INTERVAL_US: Final = 10_000_000

#: (register, set bits, clear bits): PX4 modern's configuration (sheet 3.7).
CONFIG: Final[tuple[tuple[int, int, int], ...]] = (
    (CTRL0, 0x40, 0x98),
    (CTRL1, 0xAC, 0x50),
    (CTRL2, 0x20, 0xDC),
    (CTRL5, 0xF0, 0x0C),
    (CTRL6, 0x60, 0x00),
    (CTRL7, 0x00, 0x03),
    (FIFO_CTRL, 0x20 | SAMPLES_PER_CYCLE, 0xC0 | (0x1F & ~SAMPLES_PER_CYCLE)),
)

STATE_RESET, STATE_WAIT_FOR_RESET, STATE_CONFIGURE, STATE_READ = range(4)


#: X/Y/Z little-endian int16 triples of a FIFO burst, one tuple per sample.
_iter_xyz_le: Final = struct.Struct("<3h").iter_unpack


def _s16(lo: int, hi: int) -> int:
    v = lo | (hi << 8)
    return v - 0x10000 if v & 0x8000 else v


class Lsm303dDriver(SensorDriver):
    """PX4-style LSM303D driver on ``wq:SPI1``: publishes ``sensor_accel`` and ``sensor_mag``.

    ``spi`` is the handle on the chip select (PC15); ``rotation`` an optional PX4 rotation
    (enum, name or 3x3 sensor->board matrix) applied to both sensors before publication.
    """

    def __init__(self, platform: Platform, spi: SpiHandle,
                 rotation: int | str | Sequence[Sequence[float]] | None = None,
                 name: str = "lsm303d", bus: int = 1,
                 address: int = SPI_DEVICE_ACCEL_MAG) -> None:
        super().__init__(platform, name, "wq:SPI1")
        spi.mode = 3
        spi.max_speed_hz = 10_000_000
        self.spi = spi
        self.rotation = sensor_to_board(rotation, name)
        self.accel_device_id = DeviceId(BUS_TYPE_SPI, bus, address,
                                        DRV_ACC_DEVTYPE_LSM303D).value
        self.mag_device_id = DeviceId(BUS_TYPE_SPI, bus, address, DRV_MAG_DEVTYPE_LSM303D).value
        self.perf_fifo_overflow = self.perf_alloc(PC_COUNT, "FIFO overflow")
        self.perf_fifo_empty = self.perf_alloc(PC_COUNT, "FIFO empty")
        self.perf_mag_duplicate = self.perf_alloc(PC_COUNT, "mag duplicates")
        self.perf_stuck = self.perf_alloc(PC_COUNT, "stuck data")
        self.perf_reset = self.perf_alloc(PC_COUNT, "reset")
        orb = platform.orb
        self._accel_pub: Any = None
        self._mag_pub: Any = None
        self._accel_msg = orb.new("sensor_accel")
        self._mag_msg = orb.new("sensor_mag")
        self._state = STATE_RESET
        self._failures = 0
        self._bad_in_row = 0
        self._next_mag_us = 0
        self._next_check_us = 0
        self._check_i = 0
        self._last_accel: tuple[int, int, int] | None = None
        self._last_mag: tuple[int, int, int] | None = None
        self._same_accel = 0
        self._same_mag = 0
        self._reported: dict[str, int] = {}
        self.temperature_c = math.nan
        self.clip_total = [0, 0, 0]
        self.accel_published = 0
        self.mag_published = 0

    # -- bus helpers --------------------------------------------------------------------------

    def _read_reg(self, addr: int) -> int:
        return self.spi.transfer(bytes((addr | DIR_READ, 0)))[1]

    def _write_reg(self, addr: int, value: int) -> None:
        self.spi.transfer(bytes((addr, value)))

    def _modify_reg(self, addr: int, set_bits: int, clear_bits: int) -> None:
        v = self._read_reg(addr)
        self._write_reg(addr, (v & ~clear_bits & 0xFF) | set_bits)

    def _report(self, key: str, text: str, error: bool = False) -> None:
        """dmesg line, at most once per ``REPORT_INTERVAL_US`` per kind (faults repeat fast)."""
        now = self.platform.time_us()
        last = self._reported.get(key)
        if last is not None and now - last < REPORT_INTERVAL_US:
            return
        self._reported[key] = now
        (self.platform.error if error else self.platform.warn)(self.name, text)

    # -- life cycle ---------------------------------------------------------------------------

    def probe(self) -> str | None:
        who = self._read_reg(WHO_AM_I)
        if who != WHO_AM_I_VALUE:
            hint = " (no device answering: MISO reads high)" if who == 0xFF else ""
            return f"WHO_AM_I 0x{who:02X}, expected 0x{WHO_AM_I_VALUE:02X} (LSM303D){hint}"
        return None

    def _start(self) -> None:
        if self._accel_pub is None:
            self._accel_pub = self.advertise_multi("sensor_accel")
            self._mag_pub = self.advertise_multi("sensor_mag")
        self._state = STATE_RESET
        self.schedule_now()

    def _reset(self) -> None:
        self.perf_reset.count()
        self._state = STATE_RESET
        self.schedule_clear()
        self.schedule_now()

    def run(self) -> None:
        if not self.running:
            return
        state = self._state
        if state == STATE_RESET:
            self._modify_reg(CTRL0, 0x80, 0x00)  # BOOT
            self._state = STATE_WAIT_FOR_RESET
            self.schedule_delayed(BOOT_WAIT_US)
        elif state == STATE_WAIT_FOR_RESET:
            who = self._read_reg(WHO_AM_I)
            if who == WHO_AM_I_VALUE:
                self._failures = 0
                self._state = STATE_CONFIGURE
                self.schedule_now()
                return
            self._failures += 1
            self.error_count += 1
            self.perf_bad_register.count()
            hint = " (no device answering)" if who == 0xFF else ""
            self._report("reset", f"reset failed: WHO_AM_I 0x{who:02X}, expected "
                         f"0x{WHO_AM_I_VALUE:02X}{hint}; retrying", error=True)
            self._state = STATE_RESET
            self.schedule_delayed(RESET_RETRY_US)
        elif state == STATE_CONFIGURE:
            if self._configure():
                self._state = STATE_READ
                self._bad_in_row = 0
                self._last_accel = self._last_mag = None
                self._same_accel = self._same_mag = 0
                now = self.platform.time_us()
                self._next_mag_us = now + MAG_INTERVAL_US
                self._next_check_us = now + CHECK_INTERVAL_US
                self._reset_fifo()
                self.schedule_on_interval(ACCEL_INTERVAL_US)
            else:
                self.perf_bad_register.count()
                self.error_count += 1
                self._failures += 1
                if self._failures >= 3:
                    self._report("config", "configuration did not stick, resetting", True)
                    self._failures = 0
                    self._reset()
                else:
                    self.schedule_delayed(10_000)
        else:
            self._run_read()

    def _configure(self) -> bool:
        for addr, set_bits, clear_bits in CONFIG:
            self._modify_reg(addr, set_bits, clear_bits)
        return all(self._register_ok(addr, s, c)[0] for addr, s, c in CONFIG)

    def _register_ok(self, addr: int, set_bits: int, clear_bits: int) -> tuple[bool, int]:
        v = self._read_reg(addr)
        return (v & set_bits) == set_bits and not (v & clear_bits), v

    def _reset_fifo(self) -> None:
        """FIFO through Bypass mode and back: the only way out of a stopped FIFO mode."""
        self._write_reg(FIFO_CTRL, SAMPLES_PER_CYCLE)
        self._write_reg(FIFO_CTRL, 0x20 | SAMPLES_PER_CYCLE)

    # -- cycle ----------------------------------------------------------------------------------

    def _run_read(self) -> None:
        self.perf_interval.count()
        self.perf_cycle.begin()
        self._read_accel()
        now = self.platform.time_us()
        if self._state == STATE_READ and now >= self._next_mag_us:
            self._next_mag_us += MAG_INTERVAL_US
            if self._next_mag_us <= now:
                self._next_mag_us = now + MAG_INTERVAL_US
            self._read_mag()
        if self._state == STATE_READ and now >= self._next_check_us:
            self._next_check_us = now + CHECK_INTERVAL_US
            self._check_register()
        self.perf_cycle.end()

    def _bad_transfer(self, why: str) -> None:
        self.perf_bad_transfer.count()
        self.error_count += 1
        self._bad_in_row += 1
        if self._bad_in_row >= BAD_TRANSFERS_RESET:
            self._report("bad", f"{why}: {self._bad_in_row} bad transfers in a row, resetting",
                         error=True)
            self._bad_in_row = 0
            self._reset()

    def _stuck(self, what: str, raw: tuple[int, int, int]) -> None:
        self.perf_stuck.count()
        self.error_count += 1
        self._report("stuck", f"{what} data stuck at {raw} for {STUCK_SAMPLES} samples, "
                     f"resetting", error=True)
        self._reset()

    def _read_accel(self) -> None:
        src = self._read_reg(FIFO_SRC)
        n = src & FIFO_SRC_FSS
        if src == 0xFF or (src & FIFO_SRC_EMPTY and n):
            self._bad_transfer(f"FIFO_SRC 0x{src:02X} impossible")
            return
        if src & FIFO_SRC_OVRN:
            self.perf_fifo_overflow.count()
            self.perf_missed.count()
            self._report("ovrn", "accel FIFO overflow: samples lost, FIFO reset")
            self._reset_fifo()
            return
        if n == 0:
            self.perf_fifo_empty.count()
            return
        rx = self.spi.transfer(bytes((OUT_X_L_A | DIR_READ | ADDR_INCREMENT,)) + bytes(6 * n))
        now = self.platform.time_us()
        d = rx[1:]
        if d == b"\xff" * len(d):
            self._bad_transfer("accel burst all 0xFF")
            return
        self._bad_in_row = 0
        sx = sy = sz = 0
        clip = [0, 0, 0]
        # Samples as (x, y, z) little-endian int16 triples (what _s16 per byte pair gives).
        for raw in _iter_xyz_le(d):
            if raw == self._last_accel:
                self._same_accel += 1
                if self._same_accel >= STUCK_SAMPLES:
                    self._stuck("accel", raw)
                    return
            else:
                self._same_accel = 0
            self._last_accel = raw
            if 32767 in raw or -32768 in raw:
                for j in range(3):
                    if raw[j] in (32767, -32768):
                        clip[j] += 1
            sx += raw[0]
            sy += raw[1]
            sz += raw[2]
        if any(clip):
            for j in range(3):
                self.clip_total[j] += clip[j]
            self._report("clip", f"accel clipping at full scale: {clip} of {n} samples")
        k = ACCEL_SCALE_M_S2 / n
        x, y, z = self._rotate(sx * k, sy * k, sz * k)
        m = self._accel_msg
        m.timestamp_sample = now
        m.device_id = self.accel_device_id
        m.x, m.y, m.z = x, y, z
        m.temperature = self.temperature_c
        m.error_count = self.error_count
        m.clip_counter = [min(c, 255) for c in clip]
        m.samples = n
        m.timestamp = now
        self._accel_pub.publish(m)  # type: ignore[union-attr]
        self.accel_published += 1

    def _read_mag(self) -> None:
        rx = self.spi.transfer(bytes((TEMP_OUT_L | DIR_READ | ADDR_INCREMENT,)) + bytes(9))
        now = self.platform.time_us()
        d = rx[1:]
        if d == b"\xff" * 9:
            self._bad_transfer("mag burst all 0xFF")
            return
        t12 = ((d[1] & 0x0F) << 8) | d[0]
        if t12 & 0x800:
            t12 -= 0x1000
        temperature = t12 / 8.0 + 25.0
        if not -40.0 <= temperature <= 85.0:
            self._bad_transfer(f"temperature {temperature:.1f} degC out of range")
            return
        self.temperature_c = temperature
        if not d[2] & STATUS_M_ZYXMDA:
            self.perf_mag_duplicate.count()
            return
        raw = (_s16(d[3], d[4]), _s16(d[5], d[6]), _s16(d[7], d[8]))
        if raw == self._last_mag:
            self._same_mag += 1
            if self._same_mag >= STUCK_SAMPLES:
                self._stuck("mag", raw)
                return
        else:
            self._same_mag = 0
        self._last_mag = raw
        if any(v in (32767, -32768) for v in raw):
            self._report("magclip", f"mag clipping at full scale: raw {raw}")
        x, y, z = self._rotate(*(v * MAG_SCALE_GAUSS for v in raw))
        m = self._mag_msg
        m.timestamp_sample = now
        m.device_id = self.mag_device_id
        m.x, m.y, m.z = x, y, z
        m.temperature = temperature
        m.error_count = self.error_count
        m.is_external = False
        m.timestamp = now
        self._mag_pub.publish(m)  # type: ignore[union-attr]
        self.mag_published += 1

    def _rotate(self, x: float, y: float, z: float) -> tuple[float, float, float]:
        r = self.rotation
        if r is None:
            return x, y, z
        return (r[0][0] * x + r[0][1] * y + r[0][2] * z,
                r[1][0] * x + r[1][1] * y + r[1][2] * z,
                r[2][0] * x + r[2][1] * y + r[2][2] * z)

    def _check_register(self) -> None:
        checks = ((WHO_AM_I, WHO_AM_I_VALUE, 0xFF & ~WHO_AM_I_VALUE),) + CONFIG
        addr, set_bits, clear_bits = checks[self._check_i]
        self._check_i = (self._check_i + 1) % len(checks)
        ok, value = self._register_ok(addr, set_bits, clear_bits)
        if ok:
            return
        self.perf_bad_register.count()
        self.error_count += 1
        self._report(f"reg{addr}", f"register 0x{addr:02X} read 0x{value:02X} (set 0x{set_bits:02X}"
                     f" clear 0x{clear_bits:02X} expected)")
        if addr == WHO_AM_I:
            self._reset()
        else:
            self._write_reg(addr, (value & ~clear_bits & 0xFF) | set_bits)

    def status(self) -> str:
        extra = [self.perf_fifo_overflow, self.perf_fifo_empty, self.perf_mag_duplicate,
                 self.perf_stuck, self.perf_reset]
        head = (f"  accel published {self.accel_published}, mag published "
                f"{self.mag_published}, error_count {self.error_count}")
        return "\n".join([super().status(), head] + ["  " + p.summary() for p in extra])
