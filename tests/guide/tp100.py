"""TP100: the example chip of docs/driver_guide.md, a small I2C barometer with a datasheet.

The TP100 is made up (so that nothing here is a copy of a real driver), but shaped like the
common parts (BMP280, LPS22, MS5611): it sits at I2C address 0x76, has an identity register, a
control register with a soft reset and a one-shot conversion whose length depends on the
oversampling, a status register with a data-ready bit, and pressure and temperature data
registers. Its "datasheet":

| addr | name      | access | reset | bits |
|------|-----------|--------|-------|------|
| 0x00 | WHO_AM_I  | r      | 0xB1  | identity |
| 0x01 | CTRL      | rw     | 0x00  | 7 SOFT_RST (self-clearing), 2:1 OSR, 0 START (one-shot) |
| 0x02 | STATUS    | r      | 0x00  | 1 BUSY (converting), 0 DRDY (cleared by reading PRESS_MSB) |
| 0x03 | PRESS_MSB | r      | 0x00  | pressure, 1/64 Pa, unsigned 24 bits, big endian |
| 0x04 | PRESS_CSB | r      | 0x00  | |
| 0x05 | PRESS_LSB | r      | 0x00  | |
| 0x06 | TEMP_MSB  | r      | 0x00  | temperature, 0.01 degC, signed 16 bits, big endian |
| 0x07 | TEMP_LSB  | r      | 0x00  | |

A conversion (CTRL.START written 1) takes ``CONVERSION_NS[OSR]``; at its end the data
registers hold the new sample, STATUS.DRDY is set and the optional DRDY pin goes high, until
the controller reads PRESS_MSB. A soft reset restores every register and makes the chip deaf
(it NAKs its address) for ``RESET_NS``. The register pointer auto-increments on reads.
"""

from __future__ import annotations

from typing import Final

import numpy as np

from board.gpio import Pin
from board.i2c import I2cTarget
from board.kernel import PRIO_HW, Event, Kernel
from peripherals.faults import FaultState
from peripherals.physics import Environment
from peripherals.regs import Field, Reg, RegisterFile

# <guide:model-registers>
I2C_ADDRESS: Final = 0x76
WHO_AM_I_VALUE: Final = 0xB1
#: conversion time by CTRL.OSR (oversampling 1x, 2x, 4x, 8x)
CONVERSION_NS: Final = (2_000_000, 4_000_000, 8_000_000, 16_000_000)
RESET_NS: Final = 1_000_000           # deaf after a soft reset
PRESS_LSB_PER_PA: Final = 64
TEMP_LSB_PER_C: Final = 100
PRESSURE_NOISE_PA: Final = 1.5        # rms at OSR 1x, halved by each OSR step

REGISTERS: Final = [
    Reg(0x00, "WHO_AM_I", reset=WHO_AM_I_VALUE, access="r"),
    Reg(0x01, "CTRL", fields=[Field("SOFT_RST", 7), Field("OSR", 1, 2), Field("START", 0)],
        doc="bits 6:3 reserved"),
    Reg(0x02, "STATUS", access="r", fields=[Field("BUSY", 1), Field("DRDY", 0)]),
    Reg(0x03, "PRESS_MSB", access="r", doc="pressure, 1/64 Pa, bits 23:16"),
    Reg(0x04, "PRESS_CSB", access="r"),
    Reg(0x05, "PRESS_LSB", access="r"),
    Reg(0x06, "TEMP_MSB", access="r", doc="temperature, 0.01 degC, signed, bits 15:8"),
    Reg(0x07, "TEMP_LSB", access="r"),
]
# </guide:model-registers>


# <guide:model-class>
class Tp100(I2cTarget):
    """The TP100 on an I2C bus: ``bus.attach(0x76, Tp100(kernel, env, rng))``."""

    def __init__(self, kernel: Kernel, env: Environment, rng: np.random.Generator,
                 name: str = "tp100", drdy_pin: Pin | None = None) -> None:
        self.kernel = kernel
        self.env = env            # the world at the board: pressure_pa, temperature_c
        self.rng = rng            # this device's own random stream (seeded per board)
        self.name = name
        self.drdy_pin = drdy_pin
        self.faults = FaultState()  # set by the catalogue's kinds, read here only
        self.regs = RegisterFile(name, REGISTERS, size=8)
        self.regs.hook("CTRL", on_write=self._on_ctrl)
        self.regs.hook("PRESS_MSB", on_read=self._on_press_read)
        self.pointer = 0
        self.conversions = 0
        self._conversion: Event | None = None
        self._deaf_until_ns = 0
        self._pointer_next = False

    # -- the I2C face: START, bytes written, bytes read --------------------------------------

    def _start(self, t_ns: int, is_read: bool) -> bool:
        if self.faults.absent or t_ns < self._deaf_until_ns:
            return False                           # NAK: the driver sees -EIO
        self._pointer_next = not is_read           # a write starts with the register pointer
        return True

    def _write(self, t_ns: int, data: bytes) -> int:
        for b in data:
            if self._pointer_next:
                self.pointer, self._pointer_next = b & 0x07, False
            else:
                self.regs.write(self.pointer, b)
                self.pointer = (self.pointer + 1) & 0x07
        return len(data)

    def _read(self, t_ns: int, n: int) -> bytes:
        regs = self.regs
        if self.faults.wrong_id is not None:
            regs["WHO_AM_I"] = self.faults.wrong_id
        out = regs.read_block(self.pointer, n)
        self.pointer = (self.pointer + n) & 0x07
        return out
    # </guide:model-class>

    # <guide:model-behaviour>
    # -- register behaviour: hooks, not if/elif on addresses ---------------------------------

    def _on_ctrl(self, value: int, old: int) -> None:
        regs = self.regs
        if regs.get("CTRL.SOFT_RST"):
            self._cancel_conversion()
            regs.reset()                            # SOFT_RST clears itself with the rest
            self._set_drdy(False)
            self._deaf_until_ns = self.kernel.now_ns + self.kernel.busy_ns + RESET_NS
        elif regs.get("CTRL.START") and self._conversion is None and not self.faults.stale:
            regs.set("STATUS.BUSY", 1)
            self._conversion = self.kernel.call_later(
                CONVERSION_NS[regs.get("CTRL.OSR")] + self.kernel.busy_ns, self._land,
                priority=PRIO_HW)

    def _land(self) -> None:
        """End of a conversion: new data (unless frozen), DRDY up, START and BUSY down."""
        self._conversion = None
        regs = self.regs
        if not (self.faults.frozen and self.conversions):
            osr = regs.get("CTRL.OSR")
            noise_pa = PRESSURE_NOISE_PA / 2 ** osr * float(self.rng.standard_normal())
            counts = round((self.env.pressure_pa + noise_pa) * PRESS_LSB_PER_PA)
            counts = min(max(counts, 0), 0xFFFFFF)
            temp = round(self.env.temperature_c * TEMP_LSB_PER_C) & 0xFFFF
            for i, name in enumerate(("PRESS_MSB", "PRESS_CSB", "PRESS_LSB")):
                regs[name] = counts >> (16 - 8 * i)
            regs["TEMP_MSB"], regs["TEMP_LSB"] = temp >> 8, temp
        self.conversions += 1
        regs.set("CTRL.START", 0)
        regs.set("STATUS.BUSY", 0)
        regs.set("STATUS.DRDY", 1)
        self._set_drdy(True)

    def _on_press_read(self, value: int) -> int:
        self.regs.set("STATUS.DRDY", 0)             # reading the data acknowledges it
        self._set_drdy(False)
        return value

    def _set_drdy(self, level: bool) -> None:
        pin = self.drdy_pin
        if pin is not None and not self.faults.drdy_stuck:
            pin.set(int(level))

    def _cancel_conversion(self) -> None:
        if self._conversion is not None:
            self.kernel.cancel(self._conversion)
            self._conversion = None
    # </guide:model-behaviour>

    def __repr__(self) -> str:
        return f"<Tp100 {self.name}>"
