"""What the drivers of the ST MEMS parts on SPI1 (L3GD20 gyro, LSM303D accel/mag) share.

Both chips speak one SPI protocol (reference sheet 2.3, 3.2): the command byte carries the read
bit (7), the auto-increment bit MS (6) and the register address (5:0); both answer WHO_AM_I at
0x0F, reboot with a BOOT bit, and PX4 drives both with the same life cycle, which lives here so
the two drivers only say what differs (the model side has the same split in
``peripherals/st_spi.py``):

* ``probe()``: WHO_AM_I against the part's accepted identities (optionally after one dummy read);
* the state machine RESET -> WAIT_FOR_RESET -> CONFIGURE -> READ: ``_boot()`` sets the part's BOOT
  bit, after ``boot_wait_us`` WHO_AM_I must read back (retried every ``RESET_RETRY_US``, reported
  once per ``REPORT_INTERVAL_US``), ``_configure()`` writes and reads back the configuration
  (retried every ``CONFIGURE_RETRY_US``; ``CONFIGURE_FAILURES_RESET`` failures reboot the chip),
  ``_enter_read()`` and ``_run_read()`` are the part's sample cycle;
* errors as results: a bad transfer (all 0xFF, impossible values) is counted, and
  ``BAD_TRANSFERS_RESET`` in a row reset the chip; frozen data (``STUCK_SAMPLES`` identical
  samples) resets it; one checked register per call of ``_check_register()`` is re-read, a
  mismatch counted and rewritten (WHO_AM_I: reset). dmesg lines are throttled per kind.

Registers are checked as ``(address, bits that must be set, bits that must be clear)`` (PX4
modern's ``register_config_t``); :func:`exact` makes the triple of a register that must read one
value.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Final

from mypy_extensions import mypyc_attr

from firmware.drivers.device import SensorDriver, SpiDeviceHandle
from common.rotation import rotation_matrix
from firmware.platform import Platform
from firmware.platform.perf import PC_COUNT, PerfCounter

__all__ = [
    "ADDR_INCREMENT", "DIR_READ", "RegCheck", "RepeatCounter", "StSpiDriver", "WHO_AM_I",
    "exact", "s16", "sensor_to_board",
]

#: Command byte bits: read, and MS (auto-increment the address for every further byte).
DIR_READ: Final = 0x80
ADDR_INCREMENT: Final = 0x40
#: WHO_AM_I of both parts.
WHO_AM_I: Final = 0x0F
#: SPI mode 3 at 10 MHz, the parts' limit (sheet 2.3, 3.2).
SPI_MODE: Final = 3
SPI_CLOCK_HZ: Final = 10_000_000

RESET_RETRY_US: Final = 100_000
CONFIGURE_RETRY_US: Final = 10_000
CONFIGURE_FAILURES_RESET: Final = 3
BAD_TRANSFERS_RESET: Final = 10
STUCK_SAMPLES: Final = 50
REPORT_INTERVAL_US: Final = 10_000_000            # repeat a dmesg line at most every 10 s

STATE_RESET, STATE_WAIT_FOR_RESET, STATE_CONFIGURE, STATE_READ = range(4)

#: (register, bits that must be set, bits that must be clear).
RegCheck = tuple[int, int, int]


def exact(addr: int, value: int) -> RegCheck:
    """The check of a register that must read exactly ``value``."""
    return (addr, value, ~value & 0xFF)


def s16(lo: int, hi: int) -> int:
    """A little-endian int16 from its two bytes."""
    v = lo | (hi << 8)
    return v - 0x10000 if v & 0x8000 else v


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


class RepeatCounter:
    """Frozen data: counts samples equal to the one before; :meth:`seen` is True at the
    ``STUCK_SAMPLES``-th repeat (and starts counting again)."""

    def __init__(self) -> None:
        self.last: tuple[int, ...] | None = None
        self.same = 0

    def clear(self) -> None:
        self.last = None
        self.same = 0

    def seen(self, raw: tuple[int, ...]) -> bool:
        if raw == self.last:
            self.same += 1
            if self.same >= STUCK_SAMPLES:
                self.same = 0
                return True
        else:
            self.same = 0
        self.last = raw
        return False


@mypyc_attr(allow_interpreted_subclasses=True)
class StSpiDriver(SensorDriver):
    """Base of the ST SPI sensor drivers on ``wq:SPI1``.

    ``accepted_ids`` maps the WHO_AM_I values the driver takes to part names (the first is the
    one expected before the probe); ``id_text`` says them in a refusal; ``dummy_read`` makes the
    probe read WHO_AM_I once before the read that counts (the L3GD20's first transfer after
    power-up); ``boot_wait_us`` is the wait after BOOT. ``checks`` are the configuration
    registers re-read one per :meth:`_check_register` call, after WHO_AM_I.

    Subclasses allocate their own perf counters in :meth:`_alloc_perf` (allocation order is
    observable: ``perf`` lists it) and implement ``_boot``, ``_configure``, ``_enter_read`` and
    ``_run_read``.
    """

    def __init__(self, platform: Platform, spi: SpiDeviceHandle, name: str,
                 rotation: int | str | Sequence[Sequence[float]] | None,
                 accepted_ids: dict[int, str], id_text: str, boot_wait_us: int,
                 checks: tuple[RegCheck, ...], dummy_read: bool = False) -> None:
        super().__init__(platform, name, "wq:SPI1")
        spi.mode = SPI_MODE
        spi.max_speed_hz = SPI_CLOCK_HZ
        self.spi = spi
        self.rotation = sensor_to_board(rotation, name)
        self._alloc_perf()
        self.perf_stuck = self.perf_alloc(PC_COUNT, "stuck data")
        self.perf_reset = self.perf_alloc(PC_COUNT, "reset")
        self._accepted_ids = accepted_ids
        self._id_text = id_text
        self._dummy_read = dummy_read
        self._boot_wait_us = boot_wait_us
        self._config_checks = checks
        self._whoami = next(iter(accepted_ids))
        self._checks: tuple[RegCheck, ...] = (exact(WHO_AM_I, self._whoami),) + checks
        self._check_i = 0
        self._state = STATE_RESET
        self._failures = 0
        self._bad_in_row = 0
        self._reported: dict[str, int] = {}
        self.temperature_c = math.nan
        self.clip_total = [0, 0, 0]

    # -- subclass hooks ----------------------------------------------------------------------

    def _alloc_perf(self) -> None:
        """Allocate the part's own perf counters (before the shared stuck/reset ones)."""

    def _boot(self) -> None:  # pragma: no cover - abstract
        """Set the part's BOOT bit (reboot memory content)."""
        raise NotImplementedError

    def _after_boot(self) -> bool:
        """Steps between a good WHO_AM_I after BOOT and configuring; False: reset again."""
        return True

    def _configure(self) -> bool:  # pragma: no cover - abstract
        """Write the configuration and read it back; True when it stuck."""
        raise NotImplementedError

    def _enter_read(self) -> None:  # pragma: no cover - abstract
        """The configuration stuck: start the sample cycle (schedule the first read)."""
        raise NotImplementedError

    def _run_read(self) -> None:  # pragma: no cover - abstract
        """One sample cycle."""
        raise NotImplementedError

    # -- bus helpers --------------------------------------------------------------------------

    def _read_reg(self, addr: int) -> int:
        return self.spi.transfer(bytes((addr | DIR_READ, 0)))[1]

    def _write_reg(self, addr: int, value: int) -> None:
        self.spi.transfer(bytes((addr, value)))

    def _modify_reg(self, addr: int, set_bits: int, clear_bits: int) -> None:
        v = self._read_reg(addr)
        self._write_reg(addr, (v & ~clear_bits & 0xFF) | set_bits)

    def _read_burst(self, addr: int, n: int) -> bytes:
        """``n`` registers from ``addr`` in one auto-incrementing read (the data bytes only)."""
        return self.spi.transfer(bytes((addr | DIR_READ | ADDR_INCREMENT,)) + bytes(n))[1:]

    def _register_ok(self, addr: int, set_bits: int, clear_bits: int) -> tuple[bool, int]:
        v = self._read_reg(addr)
        return (v & set_bits) == set_bits and not (v & clear_bits), v

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
        if self._dummy_read:
            self._read_reg(WHO_AM_I)  # the first transfer after power-up
        who = self._read_reg(WHO_AM_I)
        if who not in self._accepted_ids:
            hint = " (no device answering: MISO reads high)" if who == 0xFF else ""
            return f"WHO_AM_I 0x{who:02X}, expected {self._id_text}{hint}"
        self._whoami = who
        self._checks = (exact(WHO_AM_I, who),) + self._config_checks
        return None

    def _start(self) -> None:
        self._state = STATE_RESET
        self.schedule_now()

    def _reset(self) -> None:
        self.perf_reset.count()
        self._state = STATE_RESET
        self.schedule_clear()  # drop the polling interval / watchdog
        self.schedule_now()

    def run(self) -> None:
        if not self.running:
            return
        state = self._state
        if state == STATE_RESET:
            self._boot()
            self._state = STATE_WAIT_FOR_RESET
            self.schedule_delayed(self._boot_wait_us)
        elif state == STATE_WAIT_FOR_RESET:
            who = self._read_reg(WHO_AM_I)
            if who == self._whoami and self._after_boot():
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
                if self._failures >= CONFIGURE_FAILURES_RESET:
                    self._report("config", "configuration did not stick, resetting", True)
                    self._failures = 0
                    self._reset()
                else:
                    self.schedule_delayed(CONFIGURE_RETRY_US)
        else:
            self._run_read()

    # -- errors --------------------------------------------------------------------------------

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
        """``STUCK_SAMPLES`` identical samples of ``what``: frozen data, reset the chip."""
        self.perf_stuck.count()
        self.error_count += 1
        self._report("stuck", f"{what} stuck at {raw} for {STUCK_SAMPLES} samples, resetting",
                     error=True)
        self._reset()

    def _check_register(self) -> None:
        """Re-read the next checked register; rewrite a changed one, reset on a wrong ID."""
        checks = self._checks
        addr, set_bits, clear_bits = checks[self._check_i]
        self._check_i = (self._check_i + 1) % len(checks)
        ok, value = self._register_ok(addr, set_bits, clear_bits)
        if ok:
            return
        self.perf_bad_register.count()
        self.error_count += 1
        if set_bits | clear_bits == 0xFF:
            expected = f", expected 0x{set_bits:02X}"
        else:
            expected = f" (set 0x{set_bits:02X} clear 0x{clear_bits:02X} expected)"
        self._report(f"reg{addr}", f"register 0x{addr:02X} read 0x{value:02X}{expected}")
        if addr == WHO_AM_I:
            self._reset()
        else:
            self._write_reg(addr, (value & ~clear_bits & 0xFF) | set_bits)

    # -- data -----------------------------------------------------------------------------------

    def _fill(self, m: Any, device_id: int, xyz: tuple[float, float, float],
              temperature: float, t_sample_us: int, now_us: int) -> None:
        """The fields every ``sensor_*`` message of these drivers carries; ``xyz`` in sensor
        axes (rotated here)."""
        m.timestamp_sample = t_sample_us
        m.device_id = device_id
        m.x, m.y, m.z = self._rotate(xyz[0], xyz[1], xyz[2])
        m.temperature = temperature
        m.error_count = self.error_count
        m.timestamp = now_us

    def _rotate(self, x: float, y: float, z: float) -> tuple[float, float, float]:
        """Sensor axes to board axes (the mounting rotation, PX4's ``-R``)."""
        r = self.rotation
        if r is None:
            return x, y, z
        return (r[0][0] * x + r[0][1] * y + r[0][2] * z,
                r[1][0] * x + r[1][1] * y + r[1][2] * z,
                r[2][0] * x + r[2][1] * y + r[2][2] * z)

    def _config_ok(self) -> bool:
        """Every configuration register reads back as checked (stops at the first that
        does not)."""
        return all(self._register_ok(a, s, c)[0] for a, s, c in self._config_checks)

    def _status_lines(self, head: str, extra: Sequence[PerfCounter]) -> str:
        """``status`` output: the shared counters, the part's line, its own counters."""
        return "\n".join([super().status(), "  " + head] + ["  " + p.summary() for p in extra])
