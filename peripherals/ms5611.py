"""MEAS MS5611-01BA barometer on SPI: commands, PROM, conversion timing, raw D1/D2 from physics.

The chip has no register file: every SPI selection starts with a one-byte command (reference
sheet section 4.3) and ADC / PROM reads keep clocking in the same selection. What the model does
so that a driver written against it would work on the real part:

* RESET (0x1E) aborts any conversion and reloads the PROM; for 2.8 ms the chip is busy: commands
  are ignored, PROM words read 0 and the ADC reads 0.
* CONVERT D1/D2 at OSR 256..4096 takes the datasheet conversion time. This chip's time is drawn
  once from the seeded generator between the datasheet minimum and maximum (real parts differ),
  so a driver must wait the maximum, as PX4 does.
* ADC READ (0x00) returns the 24-bit result once: a second read, or a read while the conversion
  runs, returns 0. A read during a conversion lets the conversion finish, but its result is
  wrong (sheet 4.3); a CONVERT during a conversion is ignored and also spoils the running one.
* PROM READ (0xA0 + 2n) returns word n, MSB first.

D1/D2 come from ``env.pressure_pa`` and ``env.board_temperature_c`` by inverting the datasheet's
first- and second-order compensation exactly (integer arithmetic), so a correct driver recovers
the input; noise per OSR follows the datasheet resolution table.
"""

from __future__ import annotations

import logging
import math
from typing import Final

import numpy as np

from board.kernel import NS_PER_MS, PRIO_HW, Event, Kernel
from board.spi import SpiTarget
from peripherals.errors import ScalarErrorModel
from peripherals.faults import FaultState
from peripherals.physics import Environment

__all__ = [
    "CONVERSION_TIME_MS",
    "DEFAULT_PROM",
    "NOISE_BY_OSR",
    "Ms5611",
    "compensate",
    "crc4",
    "prom_with_crc",
    "raw_from_physical",
]

log = logging.getLogger(__name__)

CMD_RESET: Final = 0x1E
CMD_ADC_READ: Final = 0x00
CMD_CONVERT_D1: Final = 0x40
CMD_CONVERT_D2: Final = 0x50
CMD_PROM_READ: Final = 0xA0
#: The command's high nibble (which command) and its bits 3:1 (OSR code, PROM address).
CMD_KIND: Final = 0xF0
CMD_ARG: Final = 0x07

#: Datasheet coefficients with words 0 and 7 = 0: a valid CRC-4 (fixtures README section 4).
DEFAULT_PROM: Final[tuple[int, ...]] = (0, 40127, 36924, 23317, 23282, 33464, 28312, 0)

#: OSR -> (min, typ, max) conversion time in ms (reference sheet 4.3).
CONVERSION_TIME_MS: Final[dict[int, tuple[float, float, float]]] = {
    256: (0.48, 0.54, 0.60),
    512: (0.95, 1.06, 1.17),
    1024: (1.88, 2.08, 2.28),
    2048: (3.72, 4.13, 4.54),
    4096: (7.40, 8.22, 9.04),
}

#: OSR -> (pressure RMS in Pa, temperature RMS in degC): the datasheet resolution table
#: (0.065 / 0.042 / 0.027 / 0.018 / 0.012 mbar; 0.012 / 0.008 / 0.005 / 0.003 / 0.002 degC).
NOISE_BY_OSR: Final[dict[int, tuple[float, float]]] = {
    256: (6.5, 0.012),
    512: (4.2, 0.008),
    1024: (2.7, 0.005),
    2048: (1.8, 0.003),
    4096: (1.2, 0.002),
}

_OSR_CODES: Final[tuple[int, ...]] = (256, 512, 1024, 2048, 4096)  # command bits 3:1 = 0..4
RESET_TIME_NS: Final = 2_800_000
_ADC_MAX: Final = (1 << 24) - 1


def crc4(words: tuple[int, ...] | list[int]) -> int:
    """CRC-4 of the eight PROM words (TE AN520, as PX4 implements it; sheet 4.4).

    The low byte of word 7 (which holds the CRC nibble) counts as zero.
    """
    data = list(words[:8])
    data[7] &= 0xFF00
    r = 0
    for word in data:
        for byte in (word >> 8, word & 0xFF):
            r ^= byte
            for _ in range(8):
                r = ((r << 1) ^ 0x3000) & 0xFFFF if r & 0x8000 else (r << 1) & 0xFFFF
    return (r >> 12) & 0xF


def prom_with_crc(words: tuple[int, ...] | list[int]) -> tuple[int, ...]:
    """The same PROM with the CRC nibble of word 7 made valid (for building test chips)."""
    w = [int(x) & 0xFFFF for x in words[:8]]
    w[7] = (w[7] & 0xFFF0) | crc4(w)
    return tuple(w)


def compensate(c: tuple[int, ...] | list[int], d1: int, d2: int) -> tuple[int, int, int, int]:
    """Datasheet first- and second-order compensation: returns (TEMP, P, OFF, SENS).

    ``c`` is the PROM (index 1..6 = C1..C6). Divisions by powers of two are arithmetic shifts.
    The model keeps its own copy of this arithmetic (the driver has another) so that each checks
    the other.
    """
    dt = d2 - (c[5] << 8)
    temp = 2000 + ((dt * c[6]) >> 23)
    off = (c[2] << 16) + ((c[4] * dt) >> 7)
    sens = (c[1] << 15) + ((c[3] * dt) >> 8)
    if temp < 2000:
        t2 = (dt * dt) >> 31
        low = (temp - 2000) ** 2
        off2 = (5 * low) >> 1
        sens2 = (5 * low) >> 2
        if temp < -1500:
            very = (temp + 1500) ** 2
            off2 += 7 * very
            sens2 += (11 * very) >> 1
        temp -= t2
        off -= off2
        sens -= sens2
    p = (((d1 * sens) >> 21) - off) >> 15
    return temp, p, off, sens


def raw_from_physical(c: tuple[int, ...], pressure_pa: float,
                      temperature_c: float) -> tuple[int, int]:
    """(D1, D2) that a correct driver turns back into ``pressure_pa`` and ``temperature_c``.

    Temperature: the continuous inverse of TEMP = 2000 + dT*C6/2^23 (minus dT^2/2^31 when cold),
    aimed half a 0.01 degC step high so that the driver's rounding down lands on the nearest
    value; dT is not snapped to whole 0.01 degC steps, so D2 keeps the finer resolution of the
    real ADC (and its noise reaches the pressure through OFF/SENS, as on the chip). Pressure:
    with the final OFF/SENS of that dT, D1 = ((P + 0.5)*2^15 + OFF)*2^21 / SENS in integers.
    Results outside the 24-bit ADC range clip, as a saturated ADC does.
    """
    c6 = c[6] or 1
    a = c6 / float(1 << 23)
    aim = temperature_c * 100.0 + 0.5 - 2000.0
    dt_f = aim / a
    if aim < 0.0:
        # TEMP1 - dT^2/2^31 = 2000 + aim  ->  dT^2/2^31 - a dT + aim = 0, root near aim/a.
        k = 1.0 / float(1 << 31)
        dt_f = (a - math.sqrt(a * a - 4.0 * k * aim)) / (2.0 * k)
    dt = round(dt_f)
    d2 = min(max((c[5] << 8) + dt, 0), _ADC_MAX)
    _, _, off, sens = compensate(c, 0, d2)
    if sens <= 0:
        return _ADC_MAX, d2
    pq = round((pressure_pa + 0.5) * (1 << 15))
    d1 = (((pq + off) << 21) + sens // 2) // sens
    return min(max(d1, 0), _ADC_MAX), d2


class Ms5611(SpiTarget):
    """The MS5611 on an SPI chip select. ``faults`` (a :class:`FaultState`) acts on the wire:

    * ``absent``: MISO floats high (every byte 0xFF), commands are not seen;
    * ``wrong_id``: the chip has no ID register, so this corrupts PROM word 7 (serial and CRC
      read this value) and a driver's CRC check refuses the part;
    * ``frozen``: conversions keep returning the last D1/D2;
    * ``random_data``: conversions return random 24-bit words;
    * ``saturate``: the ADC reads full scale (0xFFFFFF);
    * ``bias_step[0]``: added to the pressure in Pa (``bias_step[1]`` to the temperature, degC).
    """

    max_clock_hz: int | None = 20_000_000

    def __init__(self, kernel: Kernel, env: Environment, rng: np.random.Generator,
                 name: str = "ms5611", prom: tuple[int, ...] | list[int] | None = None) -> None:
        self.kernel = kernel
        self.env = env
        self.rng = rng
        self.name = name
        words = tuple(DEFAULT_PROM if prom is None else prom)
        if len(words) != 8 or any(type(w) is not int or not 0 <= w <= 0xFFFF for w in words):
            raise ValueError(f"{name}: PROM must be eight 16-bit words, got {prom!r}")
        self.prom = words
        self.faults = FaultState()
        self.pressure_errors = ScalarErrorModel(0.0, 0.0, rng)
        self.temperature_errors = ScalarErrorModel(0.0, 0.0, rng)
        # This part's oscillator: one factor within the datasheet's min..max spread.
        self.timing_factor = float(np.clip(1.0 + 0.03 * rng.standard_normal(), 0.9, 1.1))
        self.commands = 0
        self.ignored_commands = 0
        self.corrupted_conversions = 0
        self.early_reads = 0
        self._reset_until_ns = -1
        self._conv_entry: Event | None = None
        self.powered = True
        self._conv_end_ns = -1
        self._conv_kind = 0       # 1 = D1, 2 = D2
        self._conv_osr = 0
        self._conv_bad = False
        self._result: int | None = None  # None: nothing to read (ADC read gives 0)
        self._last = {1: 0, 2: 0}
        self._cmd: int | None = None
        self._out = b""
        self._pos = 0
        self._warned: set[int] = set()

    # -- timing --------------------------------------------------------------------------------

    def conversion_time_ns(self, osr: int) -> int:
        """This chip's conversion time at ``osr`` (within the datasheet's min..max)."""
        lo, typ, hi = CONVERSION_TIME_MS[osr]
        ms = min(max(typ * self.timing_factor, lo), hi)
        return round(ms * NS_PER_MS)

    @property
    def converting(self) -> bool:
        return Kernel.pending(self._conv_entry)

    def set_power(self, on: bool) -> None:
        """The supply rail: off, conversions stop and MISO floats high; on is a power-on reset
        (the PROM reloads for 2.8 ms, as after RESET)."""
        if on and not self.powered:
            self.powered = True
            self._do_reset(self.kernel.context_ns)
        elif not on and self.powered:
            self.powered = False
            self.kernel.cancel(self._conv_entry)
            self._conv_entry = None
            self._result = None

    def power_cycle(self, t_ns: int | None = None) -> None:
        """Sensor rail off and on (PX4's SPI1 bus reset): as after a RESET command."""
        self._do_reset(self.kernel.context_ns if t_ns is None else t_ns)

    # -- SPI hooks -----------------------------------------------------------------------------

    def _select(self, t_ns: int, mode: int, clock_hz: int) -> None:
        self._cmd = None
        self._out = b""
        self._pos = 0

    def _exchange(self, t_ns: int, tx: bytes) -> bytes:
        if self.faults.absent or not self.powered:
            return b"\xff" * len(tx)
        rx = bytearray(len(tx))
        start = 0
        if self._cmd is None and tx:
            self._cmd = tx[0]
            byte_ns = 8_000_000_000 // max(self.clock_hz, 1)
            self._out = self._command(tx[0], t_ns, t_ns + byte_ns)
            start = 1
        out = self._out
        for i in range(start, len(tx)):
            p = self._pos
            rx[i] = out[p] if p < len(out) else 0x00
            self._pos = p + 1
        return bytes(rx)

    # -- commands ------------------------------------------------------------------------------

    def _command(self, cmd: int, t_ns: int, t_end_ns: int) -> bytes:
        """Act on a command byte; returns what the chip shifts out after it."""
        self.commands += 1
        if t_ns < self._reset_until_ns:
            self.ignored_commands += 1
            if cmd == CMD_RESET:
                self._do_reset(t_end_ns)
            return b""  # PROM not loaded yet, ADC idle: zeros
        if cmd == CMD_RESET:
            self._do_reset(t_end_ns)
            return b""
        if cmd == CMD_ADC_READ:
            return self._adc_read(t_ns)
        hi = cmd & CMD_KIND
        osr_bits = (cmd >> 1) & CMD_ARG
        if hi in (CMD_CONVERT_D1, CMD_CONVERT_D2) and osr_bits < 5 and not cmd & 1:
            self._convert(1 if hi == CMD_CONVERT_D1 else 2, _OSR_CODES[osr_bits], t_end_ns)
            return b""
        if hi == CMD_PROM_READ:
            word = self.prom[(cmd >> 1) & CMD_ARG]
            if (cmd >> 1) & CMD_ARG == 7 and self.faults.wrong_id is not None:
                word = self.faults.wrong_id & 0xFFFF
            return bytes((word >> 8, word & 0xFF))
        self.ignored_commands += 1
        if cmd not in self._warned:
            self._warned.add(cmd)
            log.warning("%s: unknown command 0x%02X ignored", self.name, cmd)
        return b""

    def _do_reset(self, t_ns: int) -> None:
        self.kernel.cancel(self._conv_entry)
        self._conv_entry = None
        self._result = None
        self._reset_until_ns = t_ns + RESET_TIME_NS

    def _convert(self, kind: int, osr: int, t_ns: int) -> None:
        if self.converting:
            # The datasheet: a command during a conversion gives an incorrect result. The chip
            # keeps converting what it started; the new command is lost.
            self._conv_bad = True
            self.ignored_commands += 1
            return
        self._conv_kind = kind
        self._conv_osr = osr
        self._conv_bad = False
        self._result = None
        self._conv_end_ns = t_ns + self.conversion_time_ns(osr)
        self._conv_entry = self.kernel.call_at(self._conv_end_ns, self._finish, priority=PRIO_HW)

    def _adc_read(self, t_ns: int) -> bytes:
        if self.converting:
            self.early_reads += 1
            self._conv_bad = True  # it completes, but with a wrong result
            return b"\x00\x00\x00"
        value = self._result
        self._result = None
        if value is None:
            return b"\x00\x00\x00"
        if self.faults.saturate:
            value = _ADC_MAX
        return value.to_bytes(3, "big")

    def _finish(self) -> None:
        """End of a conversion: latch the ADC result from the physical input at this instant."""
        self._conv_entry = None
        kind = self._conv_kind
        f = self.faults
        if self._conv_bad:
            self.corrupted_conversions += 1
            value = int(self.rng.integers(0, 1 << 24))
        elif f.frozen and self._last[kind]:
            value = self._last[kind]
        elif f.random_data:
            value = int(self.rng.integers(0, 1 << 24))
        else:
            value = self._sample(kind)
        self._last[kind] = value
        self._result = value

    def _sample(self, kind: int) -> int:
        p_sigma, t_sigma = NOISE_BY_OSR[self._conv_osr]
        env = self.env
        bias = self.faults.bias_step
        if kind == 2:
            self.temperature_errors.sigma = t_sigma
            temp = self.temperature_errors.apply(env.board_temperature_c) + bias[1]
            return raw_from_physical(self.prom, env.pressure_pa, temp)[1]
        # The pressure element is compensated with the die temperature itself (no ADC noise).
        temp = env.board_temperature_c + bias[1]
        self.pressure_errors.sigma = p_sigma
        pressure = self.pressure_errors.apply(env.pressure_pa) + bias[0]
        nz = self.faults.noise
        if nz and nz.get("pressure"):
            pressure += nz["pressure"] * float(self.rng.standard_normal())
        return raw_from_physical(self.prom, pressure, temp)[0]

    def __repr__(self) -> str:
        return f"<Ms5611 {self.name}>"
