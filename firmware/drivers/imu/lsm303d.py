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
registers, wrong ID after reset (refused, retried every 100 ms). The life cycle, the bus
helpers and the error handling it shares with the L3GD20 driver live in
:mod:`firmware.drivers.imu.st_spi_driver`.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import Any, Final

from board.spi import SpiHandle
from firmware.drivers.device import BUS_TYPE_SPI, DeviceId
from firmware.drivers.imu.st_spi_driver import (
    STATE_READ,
    RegCheck,
    RepeatCounter,
    StSpiDriver,
    s16,
)
from firmware.platform import Platform
from firmware.platform.perf import PC_COUNT
from common.units import G0_M_S2

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

WHO_AM_I_VALUE: Final = 0x49

# Registers and bits, in the datasheet's names (reference sheet 3.3, 3.4).
TEMP_OUT_L: Final = 0x05            # TEMP_OUT_L, TEMP_OUT_H, STATUS_M, OUT_X_L_M .. OUT_Z_H_M
TEMP_OUT_H_TEMP: Final = 0x0F       # the 12-bit temperature's high nibble
STATUS_M_ZYXMDA: Final = 0x08
CTRL0: Final = 0x1F
CTRL0_BOOT: Final = 0x80
CTRL0_FIFO_EN: Final = 0x40
CTRL0_MUST_BE_0: Final = 0x18       # bits 4, 3
CTRL1: Final = 0x20
CTRL1_AODR: Final = 0xF0
CTRL1_AODR_1600HZ: Final = 0xA0
CTRL1_BDU: Final = 0x08
CTRL1_AZEN: Final = 0x04
CTRL2: Final = 0x21
CTRL2_ABW: Final = 0xC0             # 00: 773 Hz anti-alias
CTRL2_AFS: Final = 0x38
CTRL2_AFS_16G: Final = 0x20
CTRL2_MUST_BE_0: Final = 0x04
CTRL5: Final = 0x24
CTRL5_TEMP_EN: Final = 0x80
CTRL5_M_RES_HIGH: Final = 0x60
CTRL5_M_ODR: Final = 0x1C
CTRL5_M_ODR_50HZ: Final = 0x10
CTRL6: Final = 0x25
CTRL6_MFS_12GAUSS: Final = 0x60
CTRL7: Final = 0x26
CTRL7_MD: Final = 0x03              # 00: continuous conversion
OUT_X_L_A: Final = 0x28
FIFO_CTRL: Final = 0x2E
FIFO_CTRL_FM: Final = 0xE0
FIFO_CTRL_FM_FIFO: Final = 0x20
FIFO_CTRL_FTH: Final = 0x1F
FIFO_SRC: Final = 0x2F
FIFO_SRC_OVRN: Final = 0x40
FIFO_SRC_EMPTY: Final = 0x20
FIFO_SRC_FSS: Final = 0x1F

ACCEL_ODR_HZ: Final = 1600
ACCEL_INTERVAL_US: Final = 2500
SAMPLES_PER_CYCLE: Final = ACCEL_ODR_HZ * ACCEL_INTERVAL_US // 1_000_000   # 4 -> FIFO threshold
MAG_INTERVAL_US: Final = 20_000
CHECK_INTERVAL_US: Final = 100_000
ACCEL_SCALE_M_S2: Final = 0.732e-3 * G0_M_S2       # +-16 g: 0.732 mg/LSB
MAG_SCALE_GAUSS: Final = 0.479e-3                  # +-12 gauss: 0.479 mgauss/LSB
BOOT_WAIT_US: Final = 150_000

#: (register, set bits, clear bits): PX4 modern's configuration (sheet 3.7), resulting in
#: CTRL0 0x40, CTRL1 0xAF, CTRL2 0x20, CTRL5 0xF0, CTRL6 0x60, CTRL7 0x00, FIFO_CTRL 0x20 | FTH.
#: CTRL1 sets AZEN only, as PX4's header does: X and Y stay enabled from the reset value 0x07.
CONFIG: Final[tuple[RegCheck, ...]] = (
    (CTRL0, CTRL0_FIFO_EN, CTRL0_BOOT | CTRL0_MUST_BE_0),
    (CTRL1, CTRL1_AODR_1600HZ | CTRL1_BDU | CTRL1_AZEN, CTRL1_AODR & ~CTRL1_AODR_1600HZ),
    (CTRL2, CTRL2_AFS_16G, CTRL2_ABW | (CTRL2_AFS & ~CTRL2_AFS_16G) | CTRL2_MUST_BE_0),
    (CTRL5, CTRL5_TEMP_EN | CTRL5_M_RES_HIGH | CTRL5_M_ODR_50HZ,
     CTRL5_M_ODR & ~CTRL5_M_ODR_50HZ),
    (CTRL6, CTRL6_MFS_12GAUSS, 0x00),
    (CTRL7, 0x00, CTRL7_MD),
    (FIFO_CTRL, FIFO_CTRL_FM_FIFO | SAMPLES_PER_CYCLE,
     (FIFO_CTRL_FM & ~FIFO_CTRL_FM_FIFO) | (FIFO_CTRL_FTH & ~SAMPLES_PER_CYCLE)),
)

#: X/Y/Z little-endian int16 triples of a FIFO burst, one tuple per sample.
_iter_xyz_le: Final = struct.Struct("<3h").iter_unpack


class Lsm303dDriver(StSpiDriver):
    """PX4-style LSM303D driver on ``wq:SPI1``: publishes ``sensor_accel`` and ``sensor_mag``.

    ``spi`` is the handle on the chip select (PC15); ``rotation`` an optional PX4 rotation
    (enum, name or 3x3 sensor->board matrix) applied to both sensors before publication.
    """

    def __init__(self, platform: Platform, spi: SpiHandle,
                 rotation: int | str | Sequence[Sequence[float]] | None = None,
                 name: str = "lsm303d", bus: int = 1,
                 address: int = SPI_DEVICE_ACCEL_MAG) -> None:
        super().__init__(platform, spi, name, rotation, {WHO_AM_I_VALUE: "LSM303D"},
                         f"0x{WHO_AM_I_VALUE:02X} (LSM303D)", BOOT_WAIT_US, CONFIG)
        self.accel_device_id = DeviceId(BUS_TYPE_SPI, bus, address,
                                        DRV_ACC_DEVTYPE_LSM303D).value
        self.mag_device_id = DeviceId(BUS_TYPE_SPI, bus, address, DRV_MAG_DEVTYPE_LSM303D).value
        orb = platform.orb
        self._accel_pub: Any = None
        self._mag_pub: Any = None
        self._accel_msg = orb.new("sensor_accel")
        self._mag_msg = orb.new("sensor_mag")
        self._next_mag_us = 0
        self._next_check_us = 0
        self._accel_repeats = RepeatCounter()
        self._mag_repeats = RepeatCounter()
        self.accel_published = 0
        self.mag_published = 0

    def _alloc_perf(self) -> None:
        self.perf_fifo_overflow = self.perf_alloc(PC_COUNT, "FIFO overflow")
        self.perf_fifo_empty = self.perf_alloc(PC_COUNT, "FIFO empty")
        self.perf_mag_duplicate = self.perf_alloc(PC_COUNT, "mag duplicates")

    # -- life cycle ---------------------------------------------------------------------------

    def _start(self) -> None:
        if self._accel_pub is None:
            self._accel_pub = self.advertise_multi("sensor_accel")
            self._mag_pub = self.advertise_multi("sensor_mag")
        super()._start()

    def _boot(self) -> None:
        self._modify_reg(CTRL0, CTRL0_BOOT, 0x00)

    def _configure(self) -> bool:
        for addr, set_bits, clear_bits in CONFIG:
            self._modify_reg(addr, set_bits, clear_bits)
        return self._config_ok()

    def _enter_read(self) -> None:
        self._bad_in_row = 0
        self._accel_repeats.clear()
        self._mag_repeats.clear()
        now = self.platform.time_us()
        self._next_mag_us = now + MAG_INTERVAL_US
        self._next_check_us = now + CHECK_INTERVAL_US
        self._reset_fifo()
        self.schedule_on_interval(ACCEL_INTERVAL_US)

    def _reset_fifo(self) -> None:
        """FIFO through Bypass mode and back: the only way out of a stopped FIFO mode."""
        self._write_reg(FIFO_CTRL, SAMPLES_PER_CYCLE)
        self._write_reg(FIFO_CTRL, FIFO_CTRL_FM_FIFO | SAMPLES_PER_CYCLE)

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
        d = self._read_burst(OUT_X_L_A, 6 * n)
        now = self.platform.time_us()
        if d == b"\xff" * len(d):
            self._bad_transfer("accel burst all 0xFF")
            return
        self._bad_in_row = 0
        sx = sy = sz = 0
        clip = [0, 0, 0]
        # Samples as (x, y, z) little-endian int16 triples.
        repeats = self._accel_repeats
        for raw in _iter_xyz_le(d):
            if repeats.seen(raw):
                self._stuck("accel data", raw)
                return
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
        m = self._accel_msg
        self._fill(m, self.accel_device_id, (sx * k, sy * k, sz * k), self.temperature_c,
                   now, now)
        m.clip_counter = [min(c, 255) for c in clip]
        m.samples = n
        self._accel_pub.publish(m)  # type: ignore[union-attr]
        self.accel_published += 1

    def _read_mag(self) -> None:
        d = self._read_burst(TEMP_OUT_L, 9)
        now = self.platform.time_us()
        if d == b"\xff" * 9:
            self._bad_transfer("mag burst all 0xFF")
            return
        t12 = ((d[1] & TEMP_OUT_H_TEMP) << 8) | d[0]
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
        raw = (s16(d[3], d[4]), s16(d[5], d[6]), s16(d[7], d[8]))
        if self._mag_repeats.seen(raw):
            self._stuck("mag data", raw)
            return
        if any(v in (32767, -32768) for v in raw):
            self._report("magclip", f"mag clipping at full scale: raw {raw}")
        m = self._mag_msg
        self._fill(m, self.mag_device_id, (raw[0] * MAG_SCALE_GAUSS, raw[1] * MAG_SCALE_GAUSS,
                                           raw[2] * MAG_SCALE_GAUSS), temperature, now, now)
        m.is_external = False
        self._mag_pub.publish(m)  # type: ignore[union-attr]
        self.mag_published += 1

    def status(self) -> str:
        return self._status_lines(
            f"accel published {self.accel_published}, mag published {self.mag_published}, "
            f"error_count {self.error_count}",
            [self.perf_fifo_overflow, self.perf_fifo_empty, self.perf_mag_duplicate,
             self.perf_stuck, self.perf_reset])
