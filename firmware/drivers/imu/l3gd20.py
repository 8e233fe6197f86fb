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
16-bit limits (clip counters, saturation warning), a missing data-ready interrupt.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from typing import Any, Final

from board.gpio import Pin
from board.spi import SpiHandle
from firmware.drivers.device import BUS_TYPE_SPI, DeviceId, SensorDriver
from firmware.drivers.imu import rotation_matrix
from firmware.platform import Platform
from firmware.platform.perf import PC_COUNT

__all__ = ["DRV_GYR_DEVTYPE_L3GD20", "SPI_DEVICE_GYRO", "L3gd20Driver"]

#: PX4 drv_sensor.h device type.
DRV_GYR_DEVTYPE_L3GD20: Final = 0x22
#: Legacy PX4 device number of the gyro on SPI1 (reference sheet 7.3), the id's address byte.
SPI_DEVICE_GYRO: Final = 1

WHO_AM_I: Final = 0x0F
CTRL_REG1: Final = 0x20
CTRL_REG2: Final = 0x21
CTRL_REG3: Final = 0x22
CTRL_REG4: Final = 0x23
CTRL_REG5: Final = 0x24
FIFO_CTRL_REG: Final = 0x2E
LOW_ODR: Final = 0x39
I2C_DISABLE_REG: Final = 0x05
DIR_READ: Final = 0x80
ADDR_INCREMENT: Final = 0x40
STATUS_ZYXDA: Final = 0x08
STATUS_ZYXOR: Final = 0x80

ACCEPTED_IDS: Final = {0xD4: "L3GD20", 0xD7: "L3GD20H", 0xD3: "L3G4200D"}
#: PX4's configuration sequence (sheet 2.8 step 3), in order.
CONFIG_SEQUENCE = ((CTRL_REG1, 0x0F), (CTRL_REG2, 0x00), (CTRL_REG3, 0x08), (CTRL_REG4, 0x80),
                   (CTRL_REG5, 0x00), (CTRL_REG5, 0x40), (FIFO_CTRL_REG, 0x00),
                   (CTRL_REG1, 0xEF), (CTRL_REG4, 0xB0))
#: Registers checked one per cycle, with their expected values (WHO_AM_I added at probe).
CHECKED = ((CTRL_REG1, 0xEF), (CTRL_REG2, 0x00), (CTRL_REG3, 0x08), (CTRL_REG4, 0xB0),
           (CTRL_REG5, 0x40), (FIFO_CTRL_REG, 0x00), (LOW_ODR, 0x08))

ODR_HZ: Final = 760
SCALE_RAD_S: Final = 70e-3 * math.pi / 180.0     # 2000 dps: 70 mdps per digit
POLL_US: Final = 715                              # PX4: 1/760 s - 600 us
BOOT_WAIT_US: Final = 10_000
RESET_RETRY_US: Final = 100_000
DRDY_TIMEOUT_US: Final = 3 * 1_000_000 // ODR_HZ  # three sample periods without an edge
BAD_TRANSFERS_RESET: Final = 10
STUCK_SAMPLES: Final = 50
REPORT_INTERVAL_US: Final = 10_000_000            # repeat a dmesg line at most every 10 s

STATE_RESET, STATE_WAIT_FOR_RESET, STATE_CONFIGURE, STATE_READ = range(4)


def sensor_to_board(rotation: int | str | Sequence[Sequence[float]] | None,
                    where: str) -> tuple[tuple[float, ...], ...] | None:
    """A PX4 rotation enum/name or a 3x3 sensor->board matrix as a matrix (None: identity)."""
    if rotation is None or isinstance(rotation, (int, str)):
        return None if rotation is None else rotation_matrix(rotation)
    rows = tuple(tuple(float(v) for v in row) for row in rotation)
    if len(rows) != 3 or any(len(r) != 3 for r in rows):
        raise ValueError(f"{where}: rotation must be a PX4 enum or a 3x3 sensor->board matrix, "
                         f"got {rotation!r}")
    return rows


#: Three little-endian int16 from an offset: the X/Y/Z output block in one C call.
_XYZ_LE: Final = struct.Struct("<3h").unpack_from


def _s16(lo: int, hi: int) -> int:
    v = lo | (hi << 8)
    return v - 0x10000 if v & 0x8000 else v


class L3gd20Driver(SensorDriver):
    """PX4-style L3GD20 driver on ``wq:SPI1``.

    ``spi`` is the handle on the gyro's chip select (PC13); ``rotation`` an optional PX4 rotation
    (enum, name, or 3x3 sensor->board matrix) applied before publication (PX4's ``-R``; FMUv2
    mounts the L3GD20 at ROTATION_YAW_270, the board spec passes it).
    """

    def __init__(self, platform: Platform, spi: SpiHandle, drdy_pin: Pin | None = None,
                 rotation: int | str | Sequence[Sequence[float]] | None = None,
                 name: str = "l3gd20",
                 bus: int = 1, address: int = SPI_DEVICE_GYRO) -> None:
        super().__init__(platform, name, "wq:SPI1")
        spi.mode = 3
        spi.max_speed_hz = 10_000_000
        self.spi = spi
        self.drdy_pin = drdy_pin
        self.rotation = sensor_to_board(rotation, name)
        self.device_id = DeviceId(BUS_TYPE_SPI, bus, address, DRV_GYR_DEVTYPE_L3GD20).value
        self.perf_duplicate = self.perf_alloc(PC_COUNT, "duplicates")
        self.perf_drdy_timeout = self.perf_alloc(PC_COUNT, "DRDY timeout")
        self.perf_stuck = self.perf_alloc(PC_COUNT, "stuck data")
        self.perf_reset = self.perf_alloc(PC_COUNT, "reset")
        self._pub: Any = None
        self._msg = platform.orb.new("sensor_gyro")
        self._state = STATE_RESET
        self._whoami = 0xD4
        self._checked: tuple[tuple[int, int], ...] = CHECKED
        self._check_i = 0
        self._failures = 0
        self._bad_in_row = 0
        self._last_raw: tuple[int, int, int] | None = None
        self._same = 0
        self._drdy_pending = False
        self._drdy_t_us = 0
        self._polling = False
        self._reported: dict[str, int] = {}
        self.temperature_c = math.nan
        self.clip_total = [0, 0, 0]
        self.published = 0

    # -- bus helpers --------------------------------------------------------------------------

    def _read_reg(self, addr: int) -> int:
        return self.spi.transfer(bytes((addr | DIR_READ, 0)))[1]

    def _write_reg(self, addr: int, value: int) -> None:
        self.spi.transfer(bytes((addr, value)))

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
        self._read_reg(WHO_AM_I)  # dummy read: the first transfer after power-up
        who = self._read_reg(WHO_AM_I)
        if who not in ACCEPTED_IDS:
            hint = " (no device answering: MISO reads high)" if who == 0xFF else ""
            return (f"WHO_AM_I 0x{who:02X}, expected 0xD4 (L3GD20; 0xD7 L3GD20H and 0xD3 "
                    f"L3G4200D also accepted){hint}")
        self._whoami = who
        self._checked = ((WHO_AM_I, who),) + CHECKED
        return None

    def _start(self) -> None:
        if self._pub is None:
            self._pub = self.advertise_multi("sensor_gyro")
        if self.drdy_pin is not None:
            self.drdy_pin.attach_interrupt(self._drdy_isr, rising=True)
        self._state = STATE_RESET
        self.schedule_now()

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
        self.perf_reset.count()
        self._state = STATE_RESET
        self._drdy_pending = False
        self.schedule_clear()  # drop the polling interval / DRDY watchdog
        self.schedule_now()

    def run(self) -> None:
        if not self.running:
            return
        state = self._state
        if state == STATE_RESET:
            self._write_reg(CTRL_REG5, 0x80)  # BOOT: reboot memory content
            self._state = STATE_WAIT_FOR_RESET
            self.schedule_delayed(BOOT_WAIT_US)
        elif state == STATE_WAIT_FOR_RESET:
            who = self._read_reg(WHO_AM_I)
            if who == self._whoami and self._disable_i2c():
                self._failures = 0
                self._state = STATE_CONFIGURE
                self.schedule_now()
                return
            self._failures += 1
            self.error_count += 1
            self.perf_bad_register.count()
            hint = " (no device answering)" if who == 0xFF else ""
            self._report("reset", f"reset failed: WHO_AM_I 0x{who:02X}, expected "
                         f"0x{self._whoami:02X}{hint}; retrying", error=True)
            self._state = STATE_RESET
            self.schedule_delayed(RESET_RETRY_US)
        elif state == STATE_CONFIGURE:
            if self._configure():
                self._state = STATE_READ
                self._enter_read()
            else:
                self.perf_bad_register.count()
                self.error_count += 1
                self._failures += 1
                if self._failures >= 3:
                    self._report("config", "configuration did not stick, resetting", True)
                    self._failures = 0
                    self._reset()
                else:
                    self.schedule_delayed(BOOT_WAIT_US)
        else:
            self._run_read()

    def _disable_i2c(self) -> bool:
        for _ in range(10):
            v = self._read_reg(I2C_DISABLE_REG)
            self._write_reg(I2C_DISABLE_REG, v | 0x20)
            if self._read_reg(I2C_DISABLE_REG) == v | 0x20:
                self._write_reg(LOW_ODR, 0x08)
                return True
        return False

    def _configure(self) -> bool:
        for addr, value in CONFIG_SEQUENCE:
            self._write_reg(addr, value)
        return all(self._read_reg(addr) == value for addr, value in CHECKED)

    def _enter_read(self) -> None:
        self._bad_in_row = 0
        self._same = 0
        self._last_raw = None
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

    def _bad_transfer(self, why: str) -> None:
        self.perf_bad_transfer.count()
        self.error_count += 1
        self._bad_in_row += 1
        if self._bad_in_row >= BAD_TRANSFERS_RESET:
            self._report("bad", f"{why}: {self._bad_in_row} bad transfers in a row, resetting",
                         error=True)
            self._bad_in_row = 0
            self._reset()

    def _read_sample(self, publish: bool, t_sample_us: int | None = None) -> None:
        self.perf_cycle.begin()
        rx = self.spi.transfer(bytes((0x26 | DIR_READ | ADDR_INCREMENT,)) + bytes(8))
        self.perf_cycle.end()
        now = self.platform.time_us()
        d = rx[1:]
        if d == b"\xff" * 8:
            self._bad_transfer("all bytes 0xFF")
            return
        temp_raw = d[0] - 256 if d[0] & 0x80 else d[0]
        temperature = 40.0 - temp_raw
        status = d[1]
        if not -40.0 <= temperature <= 85.0:
            self._bad_transfer(f"temperature {temperature:.0f} degC out of range")
            return
        if not status & STATUS_ZYXDA:
            self.perf_duplicate.count()
            return
        self._bad_in_row = 0
        if status & STATUS_ZYXOR:
            self.perf_missed.count()
        raw = _XYZ_LE(d, 2)  # OUT_X_L .. OUT_Z_H: three little-endian int16 (as _s16)
        if not publish:
            self._last_raw = raw
            return
        if raw == self._last_raw:
            self._same += 1
            if self._same >= STUCK_SAMPLES:
                self.perf_stuck.count()
                self.error_count += 1
                self._report("stuck", f"data stuck at {raw} for {self._same} samples, resetting",
                             error=True)
                self._same = 0
                self._reset()
                return
        else:
            self._same = 0
        self._last_raw = raw
        clip = [1 if v in (32767, -32768) else 0 for v in raw]
        if any(clip):
            for j in range(3):
                self.clip_total[j] += clip[j]
            self._report("clip", f"gyro clipping at full scale: raw {raw}")
        self.temperature_c = temperature
        self._publish(raw, clip, temperature, now if t_sample_us is None else t_sample_us, now)

    def _publish(self, raw: tuple[int, int, int], clip: list[int], temperature: float,
                 t_sample_us: int, now_us: int) -> None:
        x, y, z = raw[0] * SCALE_RAD_S, raw[1] * SCALE_RAD_S, raw[2] * SCALE_RAD_S
        r = self.rotation
        if r is not None:
            x, y, z = (r[0][0] * x + r[0][1] * y + r[0][2] * z,
                       r[1][0] * x + r[1][1] * y + r[1][2] * z,
                       r[2][0] * x + r[2][1] * y + r[2][2] * z)
        m = self._msg
        m.timestamp_sample = t_sample_us
        m.device_id = self.device_id
        m.x, m.y, m.z = x, y, z
        m.temperature = temperature
        m.error_count = self.error_count
        m.clip_counter = clip
        m.samples = 1
        m.timestamp = now_us
        self._pub.publish(m)  # type: ignore[union-attr]
        self.published += 1

    def _check_register(self) -> None:
        addr, expected = self._checked[self._check_i]
        self._check_i = (self._check_i + 1) % len(self._checked)
        value = self._read_reg(addr)
        if value == expected:
            return
        self.perf_bad_register.count()
        self.error_count += 1
        self._report(f"reg{addr}", f"register 0x{addr:02X} read 0x{value:02X}, expected "
                     f"0x{expected:02X}")
        if addr == WHO_AM_I:
            self._reset()
        else:
            self._write_reg(addr, expected)

    def status(self) -> str:
        extra = [self.perf_duplicate, self.perf_drdy_timeout, self.perf_stuck, self.perf_reset]
        mode = "DRDY" if self.drdy_pin is not None and not self._polling else "polling"
        head = f"  mode: {mode}, published {self.published}, error_count {self.error_count}"
        return "\n".join([super().status(), head] + ["  " + p.summary() for p in extra])
