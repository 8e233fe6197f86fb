"""Honeywell HMC5883L 3-axis magnetometer on I2C (address 0x1E): registers, modes, timing.

The register file is data (reference sheet 5.3/5.4); the behaviour behind it:

* Pointer auto-increment after every byte read or written, with the datasheet's two
  exceptions: from 0x0C or above the pointer goes to 0x00, and from 0x08 (the last data byte)
  back to 0x03, so repeated 6-byte reads from 0x03 keep returning the data block. Addresses
  without a register read 0 and ignore writes.
* Measurements: single (MD = 01: one measurement of ~6 ms, then the mode register reads idle)
  and continuous (MD = 00: first result 2/f_DO after the mode or a configuration write, then
  every 1/f_DO). Idle (MD = 1x) measures nothing.
* Output: field (gauss, from ``env.mag_gauss``) times the gain of CRB.GN, big-endian in the
  order X, Z, Y; an axis outside -2048..2047 reads -4096 (overflow). A gain change takes effect
  from the measurement after next.
* Self-test: CRA.MS = 01 adds (+1.16, +1.16, +1.08) Ga on X, Y, Z, 10 subtracts it (the values
  the reference recommends so both PX4's and ArduPilot's checks pass; open point 6).
* STATUS: RDY set when all six data bytes hold a new measurement, cleared when the chip starts
  writing new data (250 us before it lands) and when all six have been read; LOCK set while some
  but not all six have been read (or after reading MR), during which new results are dropped.
  DRDY (optional pin) pulses low for 250 us when new data land.

Faults: ``absent`` NAKs the address; ``wrong_id`` replaces the three ID bytes; ``frozen`` keeps
the last result; ``random_data`` puts random counts; ``saturate`` reads the overflow value on
every axis; ``drdy_stuck`` silences DRDY; ``bias_step`` adds gauss.
"""

from __future__ import annotations

import logging
from typing import Final

import numpy as np

from board.gpio import Pin
from board.i2c import I2cTarget
from board.kernel import NS_PER_US, PRIO_HW, Kernel
from peripherals.errors import AxisErrors, ImuErrorModel
from peripherals.faults import FaultState
from peripherals.physics import Environment
from peripherals.regs import Field, Reg, RegisterFile

__all__ = [
    "DATA_RATE_HZ",
    "GAIN_LSB_PER_GA",
    "I2C_ADDRESS",
    "OVERFLOW",
    "REGISTERS",
    "SELF_TEST_GA",
    "Hmc5883",
]

log = logging.getLogger(__name__)

I2C_ADDRESS: Final = 0x1E

REGISTERS: Final = [
    Reg(0x00, "CRA", reset=0x10, fields=[Field("MA", 5, 2, "samples averaged: 1, 2, 4, 8"),
                                         Field("DO", 2, 3, "continuous output rate code"),
                                         Field("MS", 0, 2, "00 normal, 01 +bias, 10 -bias")],
        doc="Configuration A; bit 7 must be 0 on the HMC5883L"),
    Reg(0x01, "CRB", reset=0x20, fields=[Field("GN", 5, 3, "gain code")],
        doc="Configuration B; bits 4:0 must be 0"),
    Reg(0x02, "MR", reset=0x01, fields=[Field("HS", 7, 1, "high-speed I2C"),
                                        Field("MD", 0, 2, "00 continuous, 01 single, 1x idle")]),
    Reg(0x03, "DXRA", access="r", doc="data X MSB"),
    Reg(0x04, "DXRB", access="r", doc="data X LSB"),
    Reg(0x05, "DZRA", access="r", doc="data Z MSB"),
    Reg(0x06, "DZRB", access="r", doc="data Z LSB"),
    Reg(0x07, "DYRA", access="r", doc="data Y MSB"),
    Reg(0x08, "DYRB", access="r", doc="data Y LSB"),
    Reg(0x09, "SR", access="r", fields=[Field("LOCK", 1), Field("RDY", 0)]),
    Reg(0x0A, "IRA", reset=0x48, access="r", doc="'H'"),
    Reg(0x0B, "IRB", reset=0x34, access="r", doc="'4'"),
    Reg(0x0C, "IRC", reset=0x33, access="r", doc="'3'"),
]

#: CRB.GN -> LSB per gauss (reference sheet 5.4).
GAIN_LSB_PER_GA: Final[tuple[int, ...]] = (1370, 1090, 820, 660, 440, 390, 330, 230)
#: CRA.DO -> continuous output rate in Hz (code 7 is reserved: treated as 75 Hz, logged).
DATA_RATE_HZ: Final[tuple[float, ...]] = (0.75, 1.5, 3.0, 7.5, 15.0, 30.0, 75.0, 75.0)
#: Self-test field in gauss on X, Y, Z (open point 6 of the reference sheet).
SELF_TEST_GA: Final[tuple[float, ...]] = (1.16, 1.16, 1.08)
#: What an overflowed axis reads.
OVERFLOW: Final = -4096

MEASUREMENT_NS: Final = 6_000_000     # single measurement, MA = 1 (~6 ms, max 160 Hz)
RDY_LOW_NS: Final = 250 * NS_PER_US   # RDY clear / DRDY low before and while data land
MAG_NOISE_GA: Final = 0.002           # datasheet noise floor (standard deviation)
_IDLE_AFTER_SINGLE: Final = 0x03      # MD read back after a single measurement (open point 7)
# Addresses the pointer logic uses, named after the table above.
DXRA: Final = 0x03                    # first data byte (X MSB)
DYRB: Final = 0x08                    # last data byte (Y LSB)
IRA: Final = 0x0A                     # first identification byte
IRC: Final = 0x0C                     # last identification byte, the pointer's end
_DATA: Final = range(DXRA, DYRB + 1)
_ALL_DATA_READ: Final = (1 << len(_DATA)) - 1   # one bit per data byte


class Hmc5883(I2cTarget):
    """The HMC5883L; attach with ``bus.attach(0x1E, Hmc5883(...))``."""

    def __init__(self, kernel: Kernel, env: Environment, rng: np.random.Generator,
                 name: str = "hmc5883", drdy_pin: Pin | None = None) -> None:
        self.kernel = kernel
        self.env = env
        self.rng = rng
        self.name = name
        self.drdy_pin = drdy_pin
        self.faults = FaultState()
        self.errors = ImuErrorModel(AxisErrors(noise_density=MAG_NOISE_GA), rng)
        self.regs = RegisterFile(name, REGISTERS, size=256, undefined_value=0x00)
        self.regs.hook("CRA", on_write=self._on_config_write)
        self.regs.hook("CRB", on_write=self._on_crb_write)
        self.regs.hook("MR", on_write=self._on_mode_write, on_read=self._on_mode_read)
        self.pointer = 0
        self.measurements = 0
        self.dropped_locked = 0
        self._gain_code = self.regs.get("CRB.GN")   # gain of the next measurement
        self._events: list[list] = []
        self._read_mask = 0         # data bytes read since the last new result (bits 0..5)
        self._first_byte = False    # next written byte is the register pointer
        self._last_counts = (0, 0, 0)
        self._warned_do7 = False
        self._now = kernel.now_ns   # time of the byte being written (for restart timing)
        if drdy_pin is not None:
            drdy_pin.high()
        self._start_mode(kernel.now_ns)

    # -- I2C hooks -------------------------------------------------------------------------

    def _start(self, t_ns: int, is_read: bool) -> bool:
        if self.faults.absent:
            return False
        self._first_byte = not is_read
        return True

    def _write(self, t_ns: int, data: bytes) -> int:
        regs = self.regs
        for b in data:
            if self._first_byte:
                self.pointer = b
                self._first_byte = False
                continue
            self._now = t_ns
            regs.write(self.pointer, b)
            self._advance()
        return len(data)

    def _read(self, t_ns: int, n: int) -> bytes:
        out = bytearray()
        wrong = self.faults.wrong_id
        for _ in range(n):
            p = self.pointer
            if IRA <= p <= IRC and wrong is not None:
                out.append((wrong >> (8 * (IRC - p))) & 0xFF)
            else:
                out.append(self.regs.read(p))
            if p in _DATA:
                self._data_byte_read(p - DXRA)
            self._advance()
        return bytes(out)

    def _advance(self) -> None:
        p = self.pointer
        # From IRC (or above) back to CRA, from the last data byte back to the first.
        self.pointer = 0x00 if p >= IRC else DXRA if p == DYRB else p + 1

    # -- status bits -----------------------------------------------------------------------

    def _data_byte_read(self, index: int) -> None:
        self._read_mask |= 1 << index
        if self._read_mask == _ALL_DATA_READ:
            self._read_mask = 0
            self.regs.set("SR.LOCK", 0)
            self.regs.set("SR.RDY", 0)
        else:
            self.regs.set("SR.LOCK", 1)

    def _unlock(self) -> None:
        self._read_mask = 0
        self.regs.set("SR.LOCK", 0)

    # -- register hooks --------------------------------------------------------------------

    def _on_config_write(self, value: int, old: int) -> None:
        self._unlock()
        if self.regs.get("CRA.DO") == 7 and not self._warned_do7:
            self._warned_do7 = True
            log.warning("%s: CRA.DO = 111 is reserved; measuring at 75 Hz", self.name)
        self._start_mode(self._write_time())

    def _on_crb_write(self, value: int, old: int) -> None:
        self._start_mode(self._write_time())

    def _on_mode_write(self, value: int, old: int) -> None:
        self._unlock()
        self._start_mode(self._write_time())

    def _on_mode_read(self, value: int) -> int:
        self.regs.set("SR.LOCK", 1)
        return value

    def _write_time(self) -> int:
        return max(self._now, self.kernel.now_ns)

    # -- measurements ----------------------------------------------------------------------

    def _cancel(self) -> None:
        for e in self._events:
            self.kernel.cancel(e)
        self._events = []

    def _start_mode(self, t_ns: int) -> None:
        """(Re)start measuring per MR.MD, as after a write to MR, CRA or CRB."""
        self._cancel()
        md = self.regs.get("MR.MD")
        if md == 0:
            period = int(1e9 / DATA_RATE_HZ[self.regs.get("CRA.DO")])
            self._schedule(t_ns + 2 * period, period)
        elif md == 1:
            self._schedule(t_ns + MEASUREMENT_NS, 0)

    def _schedule(self, t_done: int, period: int) -> None:
        k = self.kernel
        self._events = [k.call_at(max(t_done - RDY_LOW_NS, k.now_ns), self._begin_write,
                                  priority=PRIO_HW),
                        k.call_at(t_done, self._land, t_done, period, priority=PRIO_HW)]

    def _begin_write(self) -> None:
        if not self.regs.get("SR.LOCK"):
            self.regs.set("SR.RDY", 0)
        pin = self.drdy_pin
        if pin is not None and not self.faults.drdy_stuck:
            pin.low()

    def _land(self, t_ns: int, period: int) -> None:
        """A measurement is done: place it (unless locked), set RDY, go on per the mode."""
        counts = self._measure(t_ns)
        self.measurements += 1
        regs = self.regs
        if regs.get("SR.LOCK"):
            self.dropped_locked += 1
        else:
            raw = b"".join((c & 0xFFFF).to_bytes(2, "big") for c in counts)
            regs.values[DXRA:DYRB + 1] = raw
            regs.set("SR.RDY", 1)
        pin = self.drdy_pin
        if pin is not None and not self.faults.drdy_stuck:
            pin.high(t_ns)
        if period:
            self._schedule(t_ns + period, period)
        else:
            self._events = []
            regs.set("MR.MD", _IDLE_AFTER_SINGLE)

    def _measure(self, t_ns: int) -> tuple[int, int, int]:
        """Counts in register order X, Z, Y."""
        f = self.faults
        gain_code, self._gain_code = self._gain_code, self.regs.get("CRB.GN")
        if f.saturate:
            return (OVERFLOW, OVERFLOW, OVERFLOW)
        if f.frozen:
            return self._last_counts
        if f.random_data:
            x, z, y = (int(v) for v in self.rng.integers(-2048, 2048, 3))
            self._last_counts = (x, z, y)
            return self._last_counts
        nz = f.noise
        self.errors.extra_sigma = nz.get("mag", 0.0) if nz else 0.0
        field = self.errors.apply(t_ns, self.env.mag_gauss, odr_hz=2.0)  # sigma = noise floor
        ms = self.regs.get("CRA.MS")
        sign = 1.0 if ms == 1 else -1.0 if ms == 2 else 0.0
        b = f.bias_step
        gain = GAIN_LSB_PER_GA[gain_code]
        out = []
        for axis in (0, 2, 1):
            value = field[axis] + b[axis] + sign * SELF_TEST_GA[axis]
            c = round(value * gain)
            out.append(c if -2048 <= c <= 2047 else OVERFLOW)
        self._last_counts = (out[0], out[1], out[2])
        return self._last_counts

    def power_cycle(self) -> None:
        """Supply off and on: registers to reset values, single measurement pending."""
        self._cancel()
        self.regs.reset()
        self._gain_code = self.regs.get("CRB.GN")
        self._read_mask = 0
        self.pointer = 0
        self._start_mode(self.kernel.context_ns)

    def __repr__(self) -> str:
        return f"<Hmc5883 {self.name}>"
