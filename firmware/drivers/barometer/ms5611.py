"""MS5611 barometer driver (SPI), in the shape of PX4's: reset, PROM, then convert/collect.

Flow (reference sheet 4.7): RESET, wait 3 ms, read the eight PROM words, check CRC-4 and the
all-zero case, then every ``interval_us`` (10 ms) collect the conversion started on the previous
run and start the next one: phase 0 converts D2 (temperature), phases 1-3 convert D1 (pressure).
Every pressure result is compensated with the datasheet's integer arithmetic (first and second
order) using the latest temperature and published on ``sensor_baro``: 75 Hz at the default
10 ms cycle.

What the driver notices (each one counted and added to ``error_count``):

* an ADC read of 0xFFFFFF: MISO stuck high, the chip is gone (bad transfer);
* an ADC read of 0: the chip had no result (it was reset, power-cycled, or read too early);
* a result outside the datasheet's valid ranges (TEMP -40..85 degC, P 10..1200 mbar);
* a pressure word identical for ``STUCK_SAMPLES`` results in a row (a frozen sensor: real
  results carry hundreds of counts of noise);
* a pressure step larger than ``STEP_LIMIT_PA`` between two results (a bias step or a glitch).

The driver holds an ``SpiDeviceHandle`` (firmware/drivers/device.py): the emulated SPI1's chip
select, or a Linux ``spidev`` through ``hil/hostbus.py``; a failed host transfer reads as an idle
(all 0xFF) MISO, i.e. a bad transfer below.

The first two make the driver re-issue RESET, as PX4 does on any collection error, and wait
3 ms (PX4: 2.8 ms; the chip counts its 2.8 ms from the end of the command byte) before the next
conversion.
"""

from __future__ import annotations

from typing import Final

from firmware.drivers.device import BUS_TYPE_SPI, DeviceId, SensorDriver, SpiDeviceHandle
from firmware.platform import Platform
from firmware.platform.perf import PC_COUNT
from firmware.platform.uorb import Publication

__all__ = ["DRV_BARO_DEVTYPE_MS5611", "Ms5611Driver", "compensate", "crc4"]

DRV_BARO_DEVTYPE_MS5611: Final = 0x3D
#: Legacy PX4 device number of the barometer on SPI1 (reference sheet 7.3).
SPI_DEVICE_BARO: Final = 3

CMD_RESET: Final = 0x1E
CMD_ADC_READ: Final = 0x00
CMD_PROM_READ: Final = 0xA0
CMD_CONVERT_D1: Final = 0x40        # pressure; | OSR code << 1
CMD_CONVERT_D2: Final = 0x50        # temperature; | OSR code << 1
_OSR_BITS: Final = {256: 0, 512: 1, 1024: 2, 2048: 3, 4096: 4}
#: Datasheet maximum conversion time per OSR, in us.
_CONV_MAX_US: Final = {256: 600, 512: 1170, 1024: 2280, 2048: 4540, 4096: 9040}

RESET_WAIT_US: Final = 3000        # PX4 waits 3 ms after RESET before reading the PROM
RESET_RECOVER_US: Final = 3000     # after a RESET on a collection error (PX4: 2.8 ms; +margin, the
                            # chip counts its 2.8 ms from the end of the command byte)
STUCK_SAMPLES: Final = 10
STEP_LIMIT_PA: Final = 500.0       # ~40 m in one 10-40 ms step: not an aircraft


def crc4(words: list[int]) -> int:
    """CRC-4 of the PROM (TE AN520; the low byte of word 7 counts as zero)."""
    r = 0
    for i, word in enumerate(words):
        if i == 7:
            word &= 0xFF00
        for byte in (word >> 8, word & 0xFF):
            r ^= byte
            for _ in range(8):
                r = (r << 1) ^ 0x3000 if r & 0x8000 else r << 1
                r &= 0xFFFF
    return r >> 12


def compensate(c: list[int], d1: int, d2: int) -> tuple[int, int]:
    """(TEMP in 0.01 degC, P in Pa) from raw D1/D2 with the datasheet's integer math.

    64-bit intermediates in C; Python integers are exact, and ``>>`` rounds towards minus
    infinity like the arithmetic shifts PX4 uses. Second order below 20 degC (and -15 degC)
    uses the first-order TEMP inside the squares.
    """
    dt = d2 - c[5] * 256
    temp = 2000 + ((dt * c[6]) >> 23)
    off = c[2] * 65536 + ((c[4] * dt) >> 7)
    sens = c[1] * 32768 + ((c[3] * dt) >> 8)
    if temp < 2000:
        t2 = (dt * dt) >> 31
        sq = (temp - 2000) * (temp - 2000)
        off2 = (5 * sq) >> 1
        sens2 = (5 * sq) >> 2
        if temp < -1500:
            sq = (temp + 1500) * (temp + 1500)
            off2 += 7 * sq
            sens2 += (11 * sq) >> 1
        temp -= t2
        off -= off2
        sens -= sens2
    p = (((d1 * sens) >> 21) - off) >> 15
    return temp, p


class Ms5611Driver(SensorDriver):
    """Reads an MS5611 on ``spi`` (SPI mode 3, 20 MHz requested) and publishes ``sensor_baro``."""

    def __init__(self, platform: Platform, spi: SpiDeviceHandle, name: str = "ms5611", bus: int = 1,
                 osr: int = 1024, interval_us: int = 10_000) -> None:
        if osr not in _OSR_BITS:
            raise ValueError(f"{name}: OSR must be one of {sorted(_OSR_BITS)}, got {osr!r}")
        if interval_us <= _CONV_MAX_US[osr]:
            raise ValueError(f"{name}: interval {interval_us} us is shorter than the "
                             f"{_CONV_MAX_US[osr]} us maximum conversion time at OSR {osr}")
        super().__init__(platform, name, "wq:SPI1")
        self.spi = spi
        self.osr = osr
        self.cycle_us = interval_us
        self.device_id = DeviceId(BUS_TYPE_SPI, bus, SPI_DEVICE_BARO, DRV_BARO_DEVTYPE_MS5611)
        self.perf_not_ready = self.perf_alloc(PC_COUNT, "conversion not ready")
        self.perf_range = self.perf_alloc(PC_COUNT, "out of range")
        self.perf_stuck = self.perf_alloc(PC_COUNT, "stuck")
        self.perf_step = self.perf_alloc(PC_COUNT, "pressure step")
        self.perf_reset = self.perf_alloc(PC_COUNT, "reset")
        self.prom: list[int] = []
        self.stuck = False
        self._phase = 0
        self._collect: int | None = None    # 1: D1 pending, 2: D2 pending
        self._d2: int | None = None
        self._last_d1: int | None = None
        self._same_d1 = 0
        self._last_p: float | None = None
        self._pub: Publication | None = None  # advertised when the driver starts
        self._msg = platform.orb.new("sensor_baro")
        self.last_pressure_pa = float("nan")
        self.last_temperature_c = float("nan")

    # -- bus helpers ---------------------------------------------------------------------------

    def _command(self, cmd: int) -> None:
        self.spi.transfer(bytes((cmd,)))

    def _sleep_us(self, us: int) -> None:
        """px4_usleep in the calling context: the thread is blocked, virtual time moves on."""
        self.platform.kernel.busy_ns += us * 1000

    # -- probe and start -----------------------------------------------------------------------

    def probe(self) -> str | None:
        self.spi.mode = 3
        self.spi.max_speed_hz = 20_000_000
        self._command(CMD_RESET)
        self._sleep_us(RESET_WAIT_US)
        words = []
        for i in range(8):
            rx = self.spi.transfer(bytes((CMD_PROM_READ + 2 * i, 0, 0)))
            words.append(rx[1] << 8 | rx[2])
        if all(w == 0xFFFF for w in words):
            return "PROM reads all 0xFFFF (no device answering on the bus)"
        if all(w == 0 for w in words):
            return "PROM reads all zero (device not answering or not reset)"
        crc = crc4(words)
        if crc != words[7] & 0xF:
            return (f"PROM CRC-4 mismatch: computed 0x{crc:X}, word 7 holds 0x{words[7] & 0xF:X} "
                    f"(PROM {' '.join(f'{w:04X}' for w in words)})")
        self.prom = words
        return None

    def _start(self) -> None:
        self._pub = self.advertise_multi("sensor_baro")
        self._phase = 0
        self._collect = None
        self.schedule_now()

    # -- the cycle -----------------------------------------------------------------------------

    def run(self) -> None:
        if not self.running:
            return
        self.perf_interval.count()
        self.perf_cycle.begin()
        if self._collect is not None:
            kind, self._collect = self._collect, None
            if not self._collect_sample(kind):
                self._error_reset()
                self.perf_cycle.end()
                return
        cmd = ((CMD_CONVERT_D2 if self._phase == 0 else CMD_CONVERT_D1)
               | (_OSR_BITS[self.osr] << 1))
        self._command(cmd)
        self._collect = 2 if self._phase == 0 else 1
        self._phase = (self._phase + 1) % 4
        self.perf_cycle.end()
        self.schedule_delayed(self.cycle_us)

    def _error_reset(self) -> None:
        """Re-issue RESET and start over once the chip has reloaded its PROM with a temperature conversion."""
        self.perf_reset.count()
        self._command(CMD_RESET)
        self._phase = 0
        self._d2 = None
        self.schedule_delayed(RESET_RECOVER_US)

    def _count_error(self) -> None:
        self.error_count += 1

    def _collect_sample(self, kind: int) -> bool:
        rx = self.spi.transfer(b"\x00\x00\x00\x00")
        raw = int.from_bytes(rx[1:4], "big")
        if raw == 0xFFFFFF:
            self.perf_bad_transfer.count()
            self._count_error()
            return False
        if raw == 0:
            self.perf_not_ready.count()
            self._count_error()
            return False
        if kind == 2:
            self._d2 = raw
            return True
        if self._d2 is None:
            return True  # no temperature yet to compensate with
        temp, p = compensate(self.prom, raw, self._d2)
        if not (-4000 <= temp <= 8500 and 1000 <= p <= 120000):
            self.perf_range.count()
            self._count_error()
            return True
        self._check_stuck(raw)
        self._check_step(float(p))
        self._publish(float(p), temp / 100.0)
        return True

    def _check_stuck(self, d1: int) -> None:
        if d1 == self._last_d1:
            self._same_d1 += 1
            if self._same_d1 >= STUCK_SAMPLES - 1:
                self.perf_stuck.count()
                self._count_error()
                if not self.stuck:
                    self.stuck = True
                    self.platform.error(self.name, f"pressure stuck: {STUCK_SAMPLES} identical "
                                                   f"conversions (D1 = {d1})")
        else:
            if self.stuck:
                self.platform.info(self.name, "pressure moving again")
            self.stuck = False
            self._same_d1 = 0
        self._last_d1 = d1

    def _check_step(self, p: float) -> None:
        last = self._last_p
        self._last_p = p
        if last is not None and abs(p - last) > STEP_LIMIT_PA:
            self.perf_step.count()
            self._count_error()
            self.platform.warn(self.name, f"pressure step {p - last:+.0f} Pa between samples")

    def _publish(self, pressure_pa: float, temperature_c: float) -> None:
        self.last_pressure_pa = pressure_pa
        self.last_temperature_c = temperature_c
        now = self.platform.time_us()
        msg = self._msg
        msg.timestamp = now
        msg.timestamp_sample = now
        msg.device_id = self.device_id.value
        msg.pressure = pressure_pa
        msg.temperature = temperature_c
        msg.error_count = self.error_count
        if self._pub is not None:
            self._pub.publish(msg)

    def status(self) -> str:
        extra = [self.perf_not_ready, self.perf_range, self.perf_stuck, self.perf_step,
                 self.perf_reset]
        lines = [super().status()] + ["  " + pc.summary() for pc in extra]
        lines.append(f"  OSR {self.osr}, cycle {self.cycle_us} us, last "
                     f"{self.last_pressure_pa:.0f} Pa {self.last_temperature_c:.2f} degC, "
                     f"errors {self.error_count}")
        return "\n".join(lines)
