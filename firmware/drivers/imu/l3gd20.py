"""L3GD20 gyro driver (SPI), in the shape of PX4's: reset -> wait -> configure -> read.

Flow (reference sheet 2.8): probe WHO_AM_I (a dummy read first; 0xD4 L3GD20, 0xD7 L3GD20H and
0xD3 L3G4200D are accepted as PX4 does); reboot (CTRL_REG5.BOOT) and wait; "disable I2C" (read
0x05, write it back with bit 5 set, read back; then LOW_ODR = 0x08); configure with PX4's
sequence ending in 760 Hz ODR / 50 Hz bandwidth, BDU, 2000 dps, FIFO enabled in Bypass mode,
data-ready on DRDY/INT2; then read one 8-byte burst (0xE6: OUT_TEMP, STATUS_REG, X, Y, Z) per
sample and publish ``sensor_gyro`` at the ODR (760 Hz).

Scheduling: with ``drdy_pin`` (PB0 on FMUv2) each rising edge schedules a read, and a watchdog
notices a silent DRDY line and falls back to polling (and back when edges return). Without it
the driver polls every 715 us (1/760 s - 600 us) as PX4 does; a read whose STATUS lacks ZYXDA is
a duplicate and is dropped.

What the driver notices (counted in perf counters and ``error_count``, reported in dmesg):
a burst of all 0xFF (bad transfer: the chip is gone; 10 in a row reset it), a temperature
outside -40..85 degC (garbage data), a configuration register that changed (rewritten) or a
wrong WHO_AM_I (reset; refused after the reset if it stays wrong), identical samples for
``STUCK_SAMPLES`` reads (frozen data: reset), STATUS overrun (missed samples), samples at the
16-bit limits (clip counters, saturation warning), a missing data-ready interrupt. The life
cycle, the bus helpers and the error handling it shares with the LSM303D driver live in
:mod:`firmware.drivers.imu.st_spi_driver`.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from typing import Any, Final

from board.gpio import Pin
from board.spi import SpiHandle
from firmware.drivers.device import BUS_TYPE_SPI, DeviceId
from firmware.drivers.imu.st_spi_driver import (
    STATE_READ,
    RegCheck,
    RepeatCounter,
    StSpiDriver,
    exact,
)
from firmware.platform import Platform
from firmware.platform.perf import PC_COUNT

__all__ = ["DRV_GYR_DEVTYPE_L3GD20", "SPI_DEVICE_GYRO", "L3gd20Driver"]

#: PX4 drv_sensor.h device type.
DRV_GYR_DEVTYPE_L3GD20: Final = 0x22
#: Legacy PX4 device number of the gyro on SPI1 (reference sheet 7.3), the id's address byte.
SPI_DEVICE_GYRO: Final = 1

# Registers and bits, in the datasheet's names (reference sheet 2.4, 2.5).
CTRL_REG1: Final = 0x20
CTRL_REG1_DR_760HZ: Final = 0xC0                  # DR = 11
CTRL_REG1_BW_50HZ: Final = 0x20                   # BW = 10: 50 Hz cut-off at 760 Hz
CTRL_REG1_PD: Final = 0x08                        # normal mode (not power-down)
CTRL_REG1_XYZ_EN: Final = 0x07                    # Zen | Xen | Yen
CTRL_REG2: Final = 0x21
CTRL_REG3: Final = 0x22
CTRL_REG3_I2_DRDY: Final = 0x08                   # data-ready on DRDY/INT2
CTRL_REG4: Final = 0x23
CTRL_REG4_BDU: Final = 0x80
CTRL_REG4_FS_2000DPS: Final = 0x30                # FS = 11
CTRL_REG5: Final = 0x24
CTRL_REG5_BOOT: Final = 0x80
CTRL_REG5_FIFO_EN: Final = 0x40
OUT_TEMP: Final = 0x26                            # OUT_TEMP, STATUS_REG, OUT_X_L .. OUT_Z_H
STATUS_REG_ZYXDA: Final = 0x08
STATUS_REG_ZYXOR: Final = 0x80
FIFO_CTRL_REG: Final = 0x2E
FIFO_CTRL_REG_FM_BYPASS: Final = 0x00
#: L3GD20H registers PX4 writes on any part ("disable I2C", sheet 2.8): bit 5 of 0x05, and
#: LOW_ODR.I2C_dis; the L3GD20 stores them silently.
I2C_DISABLE_REG: Final = 0x05
I2C_DISABLE_BIT: Final = 0x20
LOW_ODR: Final = 0x39
LOW_ODR_I2C_DIS: Final = 0x08

ACCEPTED_IDS: Final = {0xD4: "L3GD20", 0xD7: "L3GD20H", 0xD3: "L3G4200D"}
#: PX4's configuration sequence (sheet 2.8 step 3), in order: 0x0F, 0x00, 0x08, 0x80, 0x00,
#: 0x40, 0x00, then 0xEF (760 Hz / 50 Hz) and 0xB0 (BDU, 2000 dps).
CONFIG_SEQUENCE: Final[tuple[tuple[int, int], ...]] = (
    (CTRL_REG1, CTRL_REG1_PD | CTRL_REG1_XYZ_EN),
    (CTRL_REG2, 0x00),
    (CTRL_REG3, CTRL_REG3_I2_DRDY),
    (CTRL_REG4, CTRL_REG4_BDU),
    (CTRL_REG5, 0x00),
    (CTRL_REG5, CTRL_REG5_FIFO_EN),
    (FIFO_CTRL_REG, FIFO_CTRL_REG_FM_BYPASS),
    (CTRL_REG1, CTRL_REG1_DR_760HZ | CTRL_REG1_BW_50HZ | CTRL_REG1_PD | CTRL_REG1_XYZ_EN),
    (CTRL_REG4, CTRL_REG4_BDU | CTRL_REG4_FS_2000DPS),
)
#: Registers checked one per cycle, each against the last value the sequence (or the I2C
#: disabling) wrote (WHO_AM_I is added at probe).
CHECKED: Final[tuple[RegCheck, ...]] = tuple(
    exact(addr, value) for addr, value in dict(CONFIG_SEQUENCE).items()
) + (exact(LOW_ODR, LOW_ODR_I2C_DIS),)

ODR_HZ: Final = 760
SCALE_RAD_S: Final = 70e-3 * math.pi / 180.0     # 2000 dps: 70 mdps per digit
POLL_US: Final = 715                              # PX4: 1/760 s - 600 us
BOOT_WAIT_US: Final = 10_000
DRDY_TIMEOUT_US: Final = 3 * 1_000_000 // ODR_HZ  # three sample periods without an edge

#: Three little-endian int16 from an offset: the X/Y/Z output block in one C call.
_XYZ_LE: Final = struct.Struct("<3h").unpack_from


class L3gd20Driver(StSpiDriver):
    """PX4-style L3GD20 driver on ``wq:SPI1``.

    ``spi`` is the handle on the gyro's chip select (PC13); ``rotation`` an optional PX4 rotation
    (enum, name, or 3x3 sensor->board matrix) applied before publication (PX4's ``-R``; FMUv2
    mounts the L3GD20 at ROTATION_YAW_270, the board spec passes it).
    """

    def __init__(self, platform: Platform, spi: SpiHandle, drdy_pin: Pin | None = None,
                 rotation: int | str | Sequence[Sequence[float]] | None = None,
                 name: str = "l3gd20",
                 bus: int = 1, address: int = SPI_DEVICE_GYRO) -> None:
        super().__init__(platform, spi, name, rotation, ACCEPTED_IDS,
                         "0xD4 (L3GD20; 0xD7 L3GD20H and 0xD3 L3G4200D also accepted)",
                         BOOT_WAIT_US, CHECKED, dummy_read=True)
        self.drdy_pin = drdy_pin
        self.device_id = DeviceId(BUS_TYPE_SPI, bus, address, DRV_GYR_DEVTYPE_L3GD20).value
        self._pub: Any = None
        self._msg = platform.orb.new("sensor_gyro")
        self._repeats = RepeatCounter()
        self._drdy_pending = False
        self._drdy_t_us = 0
        self._polling = False
        self.published = 0

    def _alloc_perf(self) -> None:
        self.perf_duplicate = self.perf_alloc(PC_COUNT, "duplicates")
        self.perf_drdy_timeout = self.perf_alloc(PC_COUNT, "DRDY timeout")

    # -- life cycle ---------------------------------------------------------------------------

    def _start(self) -> None:
        if self._pub is None:
            self._pub = self.advertise_multi("sensor_gyro")
        if self.drdy_pin is not None:
            self.drdy_pin.attach_interrupt(self._drdy_isr, rising=True)
        super()._start()

    def stop(self) -> None:
        if self.drdy_pin is not None and self.running:
            try:
                self.drdy_pin.detach_interrupt()
            except ValueError:
                pass  # the EXTI line was re-routed to another port's pin meanwhile
        super().stop()

    def _drdy_isr(self, pin: Pin, t_ns: int) -> None:
        # Interrupt context: note the sample time and wake the work item, nothing more.
        if self._state == STATE_READ and self.running:
            self._drdy_pending = True
            self._drdy_t_us = t_ns // 1000
            self.schedule_now()

    def _reset(self) -> None:
        self._drdy_pending = False
        super()._reset()

    def _boot(self) -> None:
        self._write_reg(CTRL_REG5, CTRL_REG5_BOOT)

    def _after_boot(self) -> bool:
        """PX4's "disable I2C" (sheet 2.8 step 2), up to 10 tries."""
        for _ in range(10):
            v = self._read_reg(I2C_DISABLE_REG)
            self._write_reg(I2C_DISABLE_REG, v | I2C_DISABLE_BIT)
            if self._read_reg(I2C_DISABLE_REG) == v | I2C_DISABLE_BIT:
                self._write_reg(LOW_ODR, LOW_ODR_I2C_DIS)
                return True
        return False

    def _configure(self) -> bool:
        for addr, value in CONFIG_SEQUENCE:
            self._write_reg(addr, value)
        return self._config_ok()

    def _enter_read(self) -> None:
        self._bad_in_row = 0
        self._repeats.clear()
        self._read_sample(publish=False)  # clears data-ready so the next sample makes an edge
        if self.drdy_pin is not None:
            self._polling = False
            self.schedule_delayed(DRDY_TIMEOUT_US)
        else:
            self.schedule_on_interval(POLL_US)

    def _run_read(self) -> None:
        self.perf_interval.count()
        t_sample = None
        if self.drdy_pin is not None:
            if self._drdy_pending:
                self._drdy_pending = False
                t_sample = self._drdy_t_us
                if self._polling:
                    self._polling = False
                    self.platform.info(self.name, "data-ready interrupts back")
                self.schedule_delayed(DRDY_TIMEOUT_US)
            elif not self._polling:
                self.perf_drdy_timeout.count()
                self.error_count += 1
                self._report("drdy", f"no data-ready interrupt for {DRDY_TIMEOUT_US} us; "
                             f"polling every {POLL_US} us")
                self._polling = True
                self.schedule_on_interval(POLL_US)
        self._read_sample(publish=True, t_sample_us=t_sample)
        if self._state == STATE_READ:
            self._check_register()

    # -- one sample ---------------------------------------------------------------------------

    def _read_sample(self, publish: bool, t_sample_us: int | None = None) -> None:
        self.perf_cycle.begin()
        d = self._read_burst(OUT_TEMP, 8)
        self.perf_cycle.end()
        now = self.platform.time_us()
        if d == b"\xff" * 8:
            self._bad_transfer("all bytes 0xFF")
            return
        temp_raw = d[0] - 256 if d[0] & 0x80 else d[0]
        temperature = 40.0 - temp_raw
        status = d[1]
        if not -40.0 <= temperature <= 85.0:
            self._bad_transfer(f"temperature {temperature:.0f} degC out of range")
            return
        if not status & STATUS_REG_ZYXDA:
            self.perf_duplicate.count()
            return
        self._bad_in_row = 0
        if status & STATUS_REG_ZYXOR:
            self.perf_missed.count()
        raw = _XYZ_LE(d, 2)  # OUT_X_L .. OUT_Z_H: three little-endian int16
        if not publish:
            self._repeats.last = raw
            return
        if self._repeats.seen(raw):
            self._stuck("data", raw)
            return
        clip = [1 if v in (32767, -32768) else 0 for v in raw]
        if any(clip):
            for j in range(3):
                self.clip_total[j] += clip[j]
            self._report("clip", f"gyro clipping at full scale: raw {raw}")
        self.temperature_c = temperature
        self._publish(raw, clip, temperature, now if t_sample_us is None else t_sample_us, now)

    def _publish(self, raw: tuple[int, int, int], clip: list[int], temperature: float,
                 t_sample_us: int, now_us: int) -> None:
        m = self._msg
        self._fill(m, self.device_id, (raw[0] * SCALE_RAD_S, raw[1] * SCALE_RAD_S,
                                       raw[2] * SCALE_RAD_S), temperature, t_sample_us, now_us)
        m.clip_counter = clip
        m.samples = 1
        self._pub.publish(m)  # type: ignore[union-attr]
        self.published += 1

    def status(self) -> str:
        mode = "DRDY" if self.drdy_pin is not None and not self._polling else "polling"
        return self._status_lines(
            f"mode: {mode}, published {self.published}, error_count {self.error_count}",
            [self.perf_duplicate, self.perf_drdy_timeout, self.perf_stuck, self.perf_reset])
