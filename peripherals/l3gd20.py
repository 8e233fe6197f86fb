"""ST L3GD20 3-axis gyroscope on SPI1 of the FMUv2 (reference sheet section 2).

The original Pixhawk 1 part (WHO_AM_I 0xD4) is modelled; the later L3GD20H (0xD7) differs
mainly in its identity and a few extra registers, of which LOW_ODR (0x39) is kept as plain
storage because PX4 writes and checks it on any part.

Behaviour modelled (sheet 2.4-2.7): ODR 95/190/380/760 Hz by DR, power-down/sleep by PD and the
axis enables, full scale 250/500/2000 dps at 8.75/17.5/70 mdps per digit, BDU, BLE, STATUS_REG
data-ready and overrun, OUT_TEMP = 40 - T (-1 LSB/degC, no calibrated offset), the 32-level
FIFO (Bypass, FIFO, Stream; FIFO_SRC WTM/OVRN/EMPTY/FSS), and the DRDY/INT2 pin: active high,
driven high while any source enabled in CTRL_REG3 bits 3:0 is true (I2_DRDY: ZYXDA, I2_WTM,
I2_ORun, I2_Empty). Reserved addresses 0x00-0x0E are plain storage (PX4 reads and writes 0x05).

Not modelled (declared, stored, logged by the register file where relevant): the high-pass
filter and LPF2 (Out_Sel / HPen select a path whose output equals LPF1 here; the sample noise
follows the ODR), the INT1 threshold interrupt generator (INT1_SRC reads 0), self-test, 3-wire
SPI, turn-on time. Errors (:data:`DEFAULT_ERRORS`): rate noise density 0.03 dps/sqrt(Hz)
(datasheet typical); the zero-rate level is drawn with 0.2 dps spread (the datasheet's +-75 dps
at 2000 dps is a worst-case spread that PX4 calibrates away; use ``errors=`` to model it) and
drifts 0.03 dps/degC away from 25 degC.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import partial
from typing import Final

import numpy as np

from board.gpio import Pin
from board.kernel import Kernel
from peripherals.errors import AxisErrors, ImuErrorModel
from peripherals.physics import Environment
from peripherals.regs import Field, Reg, RegisterFile
from peripherals.st_spi import (
    FIFO_BYPASS,
    FIFO_DEPTH,
    SampleChannel,
    StSpiTarget,
    check_rotation,
    to_int16,
)

__all__ = [
    "DEFAULT_ERRORS",
    "ODR_HZ",
    "REGISTERS",
    "SENSITIVITY_MDPS",
    "WHO_AM_I_L3GD20",
    "L3gd20",
]

WHO_AM_I_L3GD20: Final = 0xD4
_DPS: Final = math.pi / 180.0

#: CTRL_REG1.DR -> output data rate in milli-hertz (sheet 2.6).
ODR_MHZ: Final[tuple[int, ...]] = (95_000, 190_000, 380_000, 760_000)
ODR_HZ: Final = tuple(m / 1000 for m in ODR_MHZ)
#: CTRL_REG4.FS -> sensitivity in mdps per digit (11 is 2000 dps as 10).
SENSITIVITY_MDPS: Final[tuple[float, ...]] = (8.75, 17.5, 70.0, 70.0)

DEFAULT_ERRORS: Final = AxisErrors(
    noise_density=0.03 * _DPS,        # rad/s/sqrt(Hz)
    bias=0.2 * _DPS,                  # rad/s, per-axis spread
    bias_instability=0.002 * _DPS,    # rad/s/sqrt(s)
    scale_error=0.005,
    misalignment_rad=0.002,
    temp_coeff=0.03 * _DPS,           # rad/s/degC
)

_OUT: Final[tuple[str, ...]] = ("OUT_X_L", "OUT_X_H", "OUT_Y_L", "OUT_Y_H", "OUT_Z_L", "OUT_Z_H")

# Registers and field masks the behaviour uses, named ``REG`` and ``REG_FIELD`` after the table
# below (tests/peripherals/test_register_names.py checks them against it).
CTRL_REG1_PD: Final = 0x08
CTRL_REG1_ZEN: Final = 0x04
CTRL_REG1_XEN: Final = 0x02
CTRL_REG1_YEN: Final = 0x01
CTRL_REG1_DR_LSB: Final = 6
CTRL_REG3: Final = 0x22
CTRL_REG3_I2_DRDY: Final = 0x08
CTRL_REG3_I2_WTM: Final = 0x04
CTRL_REG3_I2_ORUN: Final = 0x02
CTRL_REG3_I2_EMPTY: Final = 0x01
#: I2_DRDY | I2_WTM | I2_ORun | I2_Empty: the sources of the DRDY/INT2 pin.
CTRL_REG3_INT2_SOURCES: Final = 0x0F
CTRL_REG4: Final = 0x23
CTRL_REG4_BDU: Final = 0x80
CTRL_REG4_BLE: Final = 0x40
CTRL_REG4_FS: Final = 0x30
CTRL_REG4_FS_LSB: Final = 4
CTRL_REG5_BOOT: Final = 0x80
OUT_TEMP: Final = 0x26
OUT_X_L: Final = 0x28
OUT_Z_H: Final = 0x2D
FIFO_CTRL_REG: Final = 0x2E
FIFO_CTRL_REG_WTM: Final = 0x1F
FIFO_SRC_REG_WTM: Final = 0x80
FIFO_SRC_REG_OVRN: Final = 0x40
FIFO_SRC_REG_EMPTY: Final = 0x20

REGISTERS: Final[list[Reg]] = [
    *(Reg(a, f"RESERVED_{a:02X}", doc="reserved; plain storage (PX4 uses 0x05)")
      for a in range(0x0F)),
    Reg(0x0F, "WHO_AM_I", reset=WHO_AM_I_L3GD20, access="r"),
    Reg(0x20, "CTRL_REG1", reset=0x07, fields=[
        Field("DR", 6, 2), Field("BW", 4, 2), Field("PD", 3), Field("Zen", 2),
        Field("Xen", 1), Field("Yen", 0)]),
    Reg(0x21, "CTRL_REG2", fields=[Field("HPM", 4, 2), Field("HPCF", 0, 4)]),
    Reg(0x22, "CTRL_REG3", fields=[
        Field("I1_Int1", 7), Field("I1_Boot", 6), Field("H_Lactive", 5), Field("PP_OD", 4),
        Field("I2_DRDY", 3), Field("I2_WTM", 2), Field("I2_ORun", 1), Field("I2_Empty", 0)]),
    Reg(0x23, "CTRL_REG4", fields=[Field("BDU", 7), Field("BLE", 6), Field("FS", 4, 2),
                                   Field("SIM", 0)]),
    Reg(0x24, "CTRL_REG5", fields=[Field("BOOT", 7), Field("FIFO_EN", 6), Field("HPen", 4),
                                   Field("INT1_Sel", 2, 2), Field("Out_Sel", 0, 2)]),
    Reg(0x25, "REFERENCE"),
    Reg(0x26, "OUT_TEMP", access="r"),
    Reg(0x27, "STATUS_REG", access="r", fields=[
        Field("ZYXOR", 7), Field("ZOR", 6), Field("YOR", 5), Field("XOR", 4),
        Field("ZYXDA", 3), Field("ZDA", 2), Field("YDA", 1), Field("XDA", 0)]),
    *(Reg(0x28 + i, name, access="r") for i, name in enumerate(_OUT)),
    Reg(0x2E, "FIFO_CTRL_REG", fields=[Field("FM", 5, 3), Field("WTM", 0, 5)]),
    Reg(0x2F, "FIFO_SRC_REG", reset=0x20, access="r", fields=[
        Field("WTM", 7), Field("OVRN", 6), Field("EMPTY", 5), Field("FSS", 0, 5)]),
    Reg(0x30, "INT1_CFG", fields=[
        Field("AND_OR", 7), Field("LIR", 6), Field("ZHIE", 5), Field("ZLIE", 4),
        Field("YHIE", 3), Field("YLIE", 2), Field("XHIE", 1), Field("XLIE", 0)]),
    Reg(0x31, "INT1_SRC", access="r", doc="interrupt generator not modelled: reads 0"),
    *(Reg(0x32 + i, f"INT1_TSH_{n}") for i, n in enumerate(("XH", "XL", "YH", "YL", "ZH",
                                                           "ZL"))),
    Reg(0x38, "INT1_DURATION", fields=[Field("WAIT", 7), Field("D", 0, 7)]),
    Reg(0x39, "LOW_ODR", doc="L3GD20H register; storage on the L3GD20 (PX4 writes 0x08)"),
]



class L3gd20(StSpiTarget):
    """Register-level L3GD20; ``drdy_pin`` is the MCU pin wired to DRDY/INT2 (PB0 on FMUv2).

    ``rotation`` is an optional 3x3 board->sensor matrix applied to ``env.gyro_rad_s``.
    """

    def __init__(self, kernel: Kernel, env: Environment, rng: np.random.Generator,
                 name: str = "l3gd20", drdy_pin: Pin | None = None,
                 rotation: Sequence[Sequence[float]] | None = None,
                 errors: AxisErrors | None = None) -> None:
        super().__init__(kernel, name, rng, frozenset((OUT_TEMP,)) | frozenset(
            range(OUT_X_L, OUT_Z_H + 1)))
        self.env = env
        self.drdy_pin = drdy_pin
        self.rotation = check_rotation(rotation)
        self.errors = ImuErrorModel(errors or DEFAULT_ERRORS, rng)
        self.regs = RegisterFile(name, REGISTERS, size=64)
        self.ch = SampleChannel(self._sample, FIFO_DEPTH)
        self._last_raw: tuple[int, int, int] | None = None
        regs = self.regs
        regs.hook("CTRL_REG1", on_write=self._w_ctrl1)
        regs.hook("CTRL_REG4", on_write=self._w_ctrl4)
        regs.hook("CTRL_REG5", on_write=self._w_ctrl5)
        regs.hook("FIFO_CTRL_REG", on_write=self._w_fifo_ctrl)
        regs.hook("OUT_TEMP", on_read=self._r_temp)
        regs.hook("STATUS_REG", on_read=lambda _v: self.ch.status_byte())
        regs.hook("FIFO_SRC_REG", on_read=lambda _v: self.ch.fifo_src(
            self.regs.get("FIFO_CTRL_REG.WTM")))
        regs.hook("INT1_SRC", on_read=lambda _v: 0)
        for i, reg in enumerate(_OUT):
            regs.hook(reg, on_read=partial(self._r_out, i))
        # The same reads, a whole burst at a time (StSpiTarget._burst_read).
        for a in range(OUT_X_L, OUT_Z_H + 1):
            self._out_blocks[a] = (OUT_X_L, OUT_Z_H, self.ch)
        if drdy_pin is not None:
            drdy_pin.low()  # push-pull output, inactive after power-on

    # -- physics --------------------------------------------------------------------------------

    @property
    def odr_hz(self) -> float:
        """Output data rate now (0 when powered down or asleep)."""
        return self.ch.odr_mhz / 1000

    def _sample(self, t_ns: int) -> tuple[int, int, int]:
        raw = self._faulted(self._last_raw)
        if raw is None:
            env = self.env
            w = self._sense(self.errors, "gyro", env.gyro_rad_s, t_ns, self.ch.odr_mhz / 1000,
                            env.board_temperature_c)
            fs = (self.regs.values[CTRL_REG4] & CTRL_REG4_FS) >> CTRL_REG4_FS_LSB
            lsb = SENSITIVITY_MDPS[fs] * 1e-3 * _DPS
            raw = (to_int16(w[0] / lsb), to_int16(w[1] / lsb), to_int16(w[2] / lsb))
        self._last_raw = raw
        return raw

    def _r_temp(self, _value: int) -> int:
        t = round(40.0 - self.env.board_temperature_c)
        return max(-128, min(127, t)) & 0xFF

    def _r_out(self, i: int, _value: int) -> int:
        return self.ch.read_byte(i, self._big_endian())

    def _big_endian(self) -> bool:
        return bool(self.regs.values[CTRL_REG4] & CTRL_REG4_BLE)

    # -- configuration --------------------------------------------------------------------------

    def _w_ctrl1(self, value: int, old: int) -> None:
        ch = self.ch
        # The channel's axis bits are X, Y, Z from bit 0; the register's order is Zen Xen Yen.
        axes = ((1 if value & CTRL_REG1_XEN else 0) | (2 if value & CTRL_REG1_YEN else 0)
                | (4 if value & CTRL_REG1_ZEN else 0))
        ch.axes = axes
        odr = ODR_MHZ[value >> CTRL_REG1_DR_LSB] if (value & CTRL_REG1_PD and axes) else 0
        if odr != ch.odr_mhz:
            if odr:
                ch.start(self._t, odr)
            else:
                ch.stop()

    def _w_ctrl4(self, value: int, old: int) -> None:
        self.ch.set_bdu(bool(value & CTRL_REG4_BDU))

    def _w_ctrl5(self, value: int, old: int) -> None:
        self._update_fifo()
        if value & CTRL_REG5_BOOT:
            self._start_boot()

    def _w_fifo_ctrl(self, value: int, old: int) -> None:
        self._update_fifo()

    def _update_fifo(self) -> None:
        regs = self.regs
        self._select_fifo_mode(self.ch, regs.get("FIFO_CTRL_REG.FM"),
                               bool(regs.get("CTRL_REG5.FIFO_EN")))

    def _power_on(self) -> None:
        self.ch.clear()
        self._last_raw = None

    # -- StSpiTarget hooks ----------------------------------------------------------------------

    def _service(self, t_ns: int) -> None:
        self.ch.advance(t_ns)

    def _fifo_wrap(self) -> bool:
        return self.ch.fifo_mode != FIFO_BYPASS

    def _refresh_pins(self, t_ns: int) -> None:
        pin = self.drdy_pin
        if pin is None:
            return
        ch = self.ch
        values = self.regs.values
        src = values[CTRL_REG3] & CTRL_REG3_INT2_SOURCES
        faults = self.faults
        if not src or faults.drdy_stuck or faults.absent:
            self._set_pin(pin, 0, t_ns)
            self._arm(None)
            return
        fifo = ch.fifo_src(values[FIFO_CTRL_REG] & FIFO_CTRL_REG_WTM)
        level = int(bool((src & CTRL_REG3_I2_DRDY and ch.da)
                         or (src & CTRL_REG3_I2_WTM and fifo & FIFO_SRC_REG_WTM)
                         or (src & CTRL_REG3_I2_ORUN and fifo & FIFO_SRC_REG_OVRN)
                         or (src & CTRL_REG3_I2_EMPTY and fifo & FIFO_SRC_REG_EMPTY)))
        self._set_pin(pin, level, t_ns)
        # The level can only change by a read (handled on access) or at the next sample.
        self._arm(ch.next_sample_ns() if (level == 0 or src & CTRL_REG3_I2_EMPTY) else None)
