"""ST LSM303D accelerometer + magnetometer on SPI1 of the FMUv2 (reference sheet section 3).

Behaviour modelled (sheet 3.3-3.6): accel ODR 3.125-1600 Hz (AODR, 0000 = power-down), range
+-2/4/6/8/16 g at 0.061/0.122/0.183/0.244/0.732 mg/LSB, anti-alias bandwidth 773/194/362/50 Hz
(shapes the noise), axis enables, BDU; magnetometer ODR 3.125-100 Hz (M_ODR; MLP forces
3.125 Hz), range +-2/4/8/12 gauss at 0.080/0.160/0.320/0.479 mgauss/LSB, resolution (low
resolution doubles the noise), continuous / single conversion / power-down (MD), hard-iron
OFFSET registers (in output LSB, subtracted by the chip); temperature (TEMP_EN) at the
magnetometer rate, 8 LSB/degC, zero at 25 degC, 12-bit right-justified and sign-extended into
TEMP_OUT_H bits 7:4; STATUS_A / STATUS_M data-ready and overrun; the 32-level accel FIFO with
the 0x2D -> 0x28 burst wrap; INT1/INT2 data-ready routing per CTRL3/CTRL4 (DRDY_A, DRDY_M,
EMPTY on INT1; DRDY_A, DRDY_M, Overrun, FTH on INT2) with the polarity of INT_CTRL_M.IEA.

Reset values follow the sheet including its [?] items: CTRL1 0x07 (PX4 modern depends on it),
CTRL5 0x18, CTRL6 0x20, CTRL7 0x02 (magnetometer powered down), INT_CTRL_M 0xE8, FIFO_SRC 0x20.
Choices where the sheet is silent: M_ODR 100 Hz with the accel at 3.125..50 Hz runs at 50 Hz;
the reserved M_ODR codes 110/111 (including the reset value) produce no conversions; a single
conversion leaves MD = 10; reserved AFS codes use the +-16 g sensitivity.

Not modelled: inertial interrupt generators, click, magnetic threshold interrupt (their SRC
registers read 0, their routing bits are stored), accel high-pass filter (AFDS) and REFERENCE,
self-test, FTH_EN depth limitation, 3-wire SPI, turn-on time.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from functools import partial
from typing import Final

import numpy as np

from board.gpio import Pin
from board.kernel import Kernel
from peripherals.errors import AxisErrors, ImuErrorModel
from peripherals.physics import Environment
from common.units import G0_M_S2
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
    "ACCEL_ERRORS",
    "ACCEL_MG_LSB",
    "ACCEL_ODR_MHZ",
    "MAG_ERRORS",
    "MAG_MGAUSS_LSB",
    "MAG_ODR_MHZ",
    "REGISTERS",
    "WHO_AM_I_LSM303D",
    "Lsm303d",
]

log = logging.getLogger(__name__)

WHO_AM_I_LSM303D: Final = 0x49

#: CTRL1.AODR -> accel ODR in milli-hertz (0: power-down; 11..15 not in the table: power-down).
ACCEL_ODR_MHZ: Final[tuple[int, ...]] = (0, 3_125, 6_250, 12_500, 25_000, 50_000, 100_000, 200_000, 400_000,
                 800_000, 1_600_000)
#: CTRL5.M_ODR -> mag ODR in milli-hertz (6, 7 reserved: no conversions).
MAG_ODR_MHZ: Final[tuple[int, ...]] = (3_125, 6_250, 12_500, 25_000, 50_000, 100_000)
#: CTRL2.AFS -> mg per LSB.
ACCEL_MG_LSB: Final[tuple[float, ...]] = (0.061, 0.122, 0.183, 0.244, 0.732)
#: CTRL6.MFS -> mgauss per LSB.
MAG_MGAUSS_LSB: Final[tuple[float, ...]] = (0.080, 0.160, 0.320, 0.479)
#: CTRL2.ABW -> anti-alias filter bandwidth in Hz.
ACCEL_ABW_HZ: Final[tuple[float, ...]] = (773.0, 194.0, 362.0, 50.0)

ACCEL_ERRORS: Final = AxisErrors(
    noise_density=150e-6 * G0_M_S2,   # 150 ug/sqrt(Hz) (datasheet typical), in m/s^2/sqrt(Hz)
    bias=0.010 * G0_M_S2,             # residual zero-g offset spread
    bias_instability=0.0002 * G0_M_S2,
    scale_error=0.01,
    misalignment_rad=0.002,
    temp_coeff=0.0005 * G0_M_S2,      # +-0.5 mg/degC
)
MAG_ERRORS: Final = AxisErrors(
    noise_density=1.0e-3,        # gauss/sqrt(Hz): 5 mgauss RMS at 50 Hz, high resolution
    bias=0.005,
    scale_error=0.01,
    misalignment_rad=0.002,
)

_OUT_M: Final[tuple[str, ...]] = ("OUT_X_L_M", "OUT_X_H_M", "OUT_Y_L_M", "OUT_Y_H_M", "OUT_Z_L_M", "OUT_Z_H_M")
_OUT_A: Final[tuple[str, ...]] = ("OUT_X_L_A", "OUT_X_H_A", "OUT_Y_L_A", "OUT_Y_H_A", "OUT_Z_L_A", "OUT_Z_H_A")
# Registers and field masks the behaviour uses, named ``REG`` and ``REG_FIELD`` after the table
# below (tests/peripherals/test_register_names.py checks them against it).
TEMP_OUT_L: Final = 0x05
TEMP_OUT_H: Final = 0x06
OUT_X_L_M: Final = 0x08
OUT_Z_H_M: Final = 0x0D
INT_CTRL_M: Final = 0x12
INT_CTRL_M_IEA: Final = 0x08                    # interrupt polarity: 1 active high
OFFSET_X_L_M: Final = 0x16                      # X, Y, Z hard-iron offsets, L then H
CTRL0_BOOT: Final = 0x80
CTRL1_AODR_LSB: Final = 4
CTRL1_BDU: Final = 0x08
CTRL1_AXES: Final = 0x07                        # AZEN | AYEN | AXEN, X at bit 0
CTRL2: Final = 0x21
CTRL2_ABW_LSB: Final = 6
CTRL2_AFS: Final = 0x38
CTRL2_AFS_LSB: Final = 3
CTRL3: Final = 0x22
CTRL3_INT1_DRDY_A: Final = 0x04
CTRL3_INT1_DRDY_M: Final = 0x02
CTRL3_INT1_EMPTY: Final = 0x01
CTRL4: Final = 0x23
CTRL4_INT2_DRDY_A: Final = 0x08
CTRL4_INT2_DRDY_M: Final = 0x04
CTRL4_INT2_OVERRUN: Final = 0x02
CTRL4_INT2_FTH: Final = 0x01
OUT_X_L_A: Final = 0x28
OUT_Z_H_A: Final = 0x2D
FIFO_CTRL: Final = 0x2E
FIFO_CTRL_FTH: Final = 0x1F
FIFO_SRC_FTH: Final = 0x80
FIFO_SRC_OVRN: Final = 0x40
FIFO_SRC_EMPTY: Final = 0x20

_STATUS_FIELDS: Final[tuple[str, ...]] = ("ZYX{0}OR", "Z{0}OR", "Y{0}OR", "X{0}OR", "ZYX{0}DA", "Z{0}DA", "Y{0}DA",
                  "X{0}DA")


def _status(suffix: str) -> list[Field]:
    return [Field(f.format(suffix), 7 - i) for i, f in enumerate(_STATUS_FIELDS)]


def _ig(addr: int, n: int) -> list[Reg]:
    return [Reg(addr, f"IG_CFG{n}", fields=[
                Field("AOI", 7), Field("6D", 6), Field("ZHIE", 5), Field("ZLIE", 4),
                Field("YHIE", 3), Field("YLIE", 2), Field("XHIE", 1), Field("XLIE", 0)]),
            Reg(addr + 1, f"IG_SRC{n}", access="r", doc="generator not modelled: reads 0"),
            Reg(addr + 2, f"IG_THS{n}"), Reg(addr + 3, f"IG_DUR{n}")]


REGISTERS: Final[list[Reg]] = [
    *(Reg(a, f"RESERVED_{a:02X}", doc="reserved; storage (PX4 reads 0x00, legacy uses 0x02)")
      for a in range(0x05)),
    Reg(0x05, "TEMP_OUT_L", access="r"),
    Reg(0x06, "TEMP_OUT_H", access="r"),
    Reg(0x07, "STATUS_M", access="r", fields=_status("M")),
    *(Reg(0x08 + i, name, access="r") for i, name in enumerate(_OUT_M)),
    Reg(0x0F, "WHO_AM_I", reset=WHO_AM_I_LSM303D, access="r"),
    Reg(0x12, "INT_CTRL_M", reset=0xE8, fields=[
        Field("XMIEN", 7), Field("YMIEN", 6), Field("ZMIEN", 5), Field("PP_OD", 4),
        Field("IEA", 3), Field("IEL", 2), Field("4D", 1), Field("MIEN", 0)]),
    Reg(0x13, "INT_SRC_M", access="r", doc="threshold interrupt not modelled: reads 0"),
    Reg(0x14, "INT_THS_L_M"),
    Reg(0x15, "INT_THS_H_M"),
    *(Reg(0x16 + i, f"OFFSET_{ax}_{hl}_M") for i, (ax, hl) in enumerate(
        (a, h) for a in "XYZ" for h in "LH")),
    Reg(0x1C, "REFERENCE_X"), Reg(0x1D, "REFERENCE_Y"), Reg(0x1E, "REFERENCE_Z"),
    Reg(0x1F, "CTRL0", fields=[Field("BOOT", 7), Field("FIFO_EN", 6), Field("FTH_EN", 5),
                               Field("HP_Click", 2), Field("HPIS1", 1), Field("HPIS2", 0)]),
    Reg(0x20, "CTRL1", reset=0x07, fields=[Field("AODR", 4, 4), Field("BDU", 3),
                                           Field("AZEN", 2), Field("AYEN", 1), Field("AXEN", 0)]),
    Reg(0x21, "CTRL2", fields=[Field("ABW", 6, 2), Field("AFS", 3, 3), Field("AST", 1),
                               Field("SIM", 0)]),
    Reg(0x22, "CTRL3", fields=[
        Field("INT1_BOOT", 7), Field("INT1_Click", 6), Field("INT1_IG1", 5),
        Field("INT1_IG2", 4), Field("INT1_IGM", 3), Field("INT1_DRDY_A", 2),
        Field("INT1_DRDY_M", 1), Field("INT1_EMPTY", 0)]),
    Reg(0x23, "CTRL4", fields=[
        Field("INT2_Click", 7), Field("INT2_IG1", 6), Field("INT2_IG2", 5),
        Field("INT2_IGM", 4), Field("INT2_DRDY_A", 3), Field("INT2_DRDY_M", 2),
        Field("INT2_Overrun", 1), Field("INT2_FTH", 0)]),
    Reg(0x24, "CTRL5", reset=0x18, fields=[Field("TEMP_EN", 7), Field("M_RES", 5, 2),
                                           Field("M_ODR", 2, 3), Field("LIR2", 1),
                                           Field("LIR1", 0)]),
    Reg(0x25, "CTRL6", reset=0x20, fields=[Field("MFS", 5, 2)]),
    Reg(0x26, "CTRL7", reset=0x02, fields=[Field("AHPM", 6, 2), Field("AFDS", 5),
                                           Field("T_ONLY", 4), Field("MLP", 2),
                                           Field("MD", 0, 2)]),
    Reg(0x27, "STATUS_A", access="r", fields=_status("A")),
    *(Reg(0x28 + i, name, access="r") for i, name in enumerate(_OUT_A)),
    Reg(0x2E, "FIFO_CTRL", fields=[Field("FM", 5, 3), Field("FTH", 0, 5)]),
    Reg(0x2F, "FIFO_SRC", reset=0x20, access="r", fields=[
        Field("FTH", 7), Field("OVRN", 6), Field("EMPTY", 5), Field("FSS", 0, 5)]),
    *_ig(0x30, 1), *_ig(0x34, 2),
    Reg(0x38, "CLICK_CFG"), Reg(0x39, "CLICK_SRC", access="r"), Reg(0x3A, "CLICK_THS"),
    Reg(0x3B, "TIME_LIMIT"), Reg(0x3C, "TIME_LATENCY"), Reg(0x3D, "TIME_WINDOW"),
    Reg(0x3E, "Act_THS"), Reg(0x3F, "Act_DUR"),
]

_ZERO_SRC: Final[tuple[str, ...]] = ("INT_SRC_M", "IG_SRC1", "IG_SRC2", "CLICK_SRC")


def _s16(lo: int, hi: int) -> int:
    v = lo | (hi << 8)
    return v - 0x10000 if v & 0x8000 else v


class Lsm303d(StSpiTarget):
    """Register-level LSM303D; ``int1_pin``/``int2_pin`` are the MCU pins wired to INT1/INT2
    (PB4 accel DRDY and PB1 mag DRDY on FMUv2). ``rotation``: optional 3x3 board->sensor matrix.
    """

    def __init__(self, kernel: Kernel, env: Environment, rng: np.random.Generator,
                 name: str = "lsm303d", int1_pin: Pin | None = None,
                 int2_pin: Pin | None = None,
                 rotation: Sequence[Sequence[float]] | None = None,
                 accel_errors: AxisErrors | None = None,
                 mag_errors: AxisErrors | None = None) -> None:
        data = frozenset((TEMP_OUT_L, TEMP_OUT_H)) | frozenset(
            range(OUT_X_L_M, OUT_Z_H_M + 1)) | frozenset(range(OUT_X_L_A, OUT_Z_H_A + 1))
        super().__init__(kernel, name, rng, data)
        self.env = env
        self.int1_pin = int1_pin
        self.int2_pin = int2_pin
        self.rotation = check_rotation(rotation)
        self.accel_errors = ImuErrorModel(accel_errors or ACCEL_ERRORS, rng)
        self.mag_errors = ImuErrorModel(mag_errors or MAG_ERRORS, rng)
        self.regs = RegisterFile(name, REGISTERS, size=64)
        self.accel = SampleChannel(self._sample_accel, FIFO_DEPTH)
        self.mag = SampleChannel(self._sample_mag)
        self._last_accel: tuple[int, int, int] | None = None
        self._last_mag: tuple[int, int, int] | None = None
        self._temp_raw = 0
        regs = self.regs
        regs.hook("CTRL0", on_write=self._w_ctrl0)
        regs.hook("CTRL1", on_write=self._w_ctrl1)
        regs.hook("CTRL2", on_write=self._w_ctrl2)
        regs.hook("CTRL5", on_write=self._w_mag_cfg)
        regs.hook("CTRL7", on_write=self._w_mag_cfg)
        regs.hook("FIFO_CTRL", on_write=lambda v, o: self._update_fifo())
        regs.hook("STATUS_A", on_read=lambda _v: self.accel.status_byte())
        regs.hook("STATUS_M", on_read=lambda _v: self.mag.status_byte())
        regs.hook("FIFO_SRC", on_read=lambda _v: self.accel.fifo_src(self.regs.get("FIFO_CTRL.FTH")))
        regs.hook("TEMP_OUT_L", on_read=lambda _v: self._temp_raw & 0xFF)
        regs.hook("TEMP_OUT_H", on_read=lambda _v: (self._temp_raw >> 8) & 0xFF)
        for name_ in _ZERO_SRC:
            regs.hook(name_, on_read=lambda _v: 0)
        for i, reg in enumerate(_OUT_A):
            regs.hook(reg, on_read=partial(self._r_out, self.accel, i))
        for i, reg in enumerate(_OUT_M):
            regs.hook(reg, on_read=partial(self._r_out, self.mag, i))
        # The same reads, a whole burst at a time (StSpiTarget._burst_read).
        for a in range(OUT_X_L_A, OUT_Z_H_A + 1):
            self._out_blocks[a] = (OUT_X_L_A, OUT_Z_H_A, self.accel)
        for a in range(OUT_X_L_M, OUT_Z_H_M + 1):
            self._out_blocks[a] = (OUT_X_L_M, OUT_Z_H_M, self.mag)
        for pin in (int1_pin, int2_pin):
            if pin is not None:
                pin.low()

    # -- physics --------------------------------------------------------------------------------

    @property
    def accel_odr_hz(self) -> float:
        return self.accel.odr_mhz / 1000

    @property
    def mag_odr_hz(self) -> float:
        return self.mag.odr_mhz / 1000

    def _sample_accel(self, t_ns: int) -> tuple[int, int, int]:
        raw = self._faulted(self._last_accel)
        if raw is None:
            env = self.env
            ctrl2 = self.regs.values[CTRL2]
            bw = min(self.accel.odr_mhz / 2000, ACCEL_ABW_HZ[ctrl2 >> CTRL2_ABW_LSB])
            a = self._sense(self.accel_errors, "accel", env.accel_m_s2, t_ns, 2.0 * bw,
                            env.board_temperature_c)
            afs = (ctrl2 & CTRL2_AFS) >> CTRL2_AFS_LSB
            lsb = ACCEL_MG_LSB[afs if afs < 5 else 4] * 1e-3 * G0_M_S2
            raw = (to_int16(a[0] / lsb), to_int16(a[1] / lsb), to_int16(a[2] / lsb))
        self._last_accel = raw
        return raw

    def _sample_mag(self, t_ns: int) -> tuple[int, int, int]:
        regs, faults = self.regs, self.faults
        if regs.get("CTRL5.TEMP_EN") and not faults.frozen:
            t = round((self.env.board_temperature_c - 25.0) * 8.0)
            self._temp_raw = max(-2048, min(2047, t)) & 0xFFFF
        powered = regs.get("CTRL7.MD") in (0, 1) and not regs.get("CTRL7.T_ONLY")
        raw = self._faulted(self._last_mag, hold=not powered)
        if raw is None:
            env = self.env
            self.mag_errors.noise_scale = 1.0 if regs.get("CTRL5.M_RES") == 3 else 2.0
            b = self._sense(self.mag_errors, "mag", env.mag_gauss, t_ns, self.mag.odr_mhz / 1000,
                            env.board_temperature_c)
            lsb = MAG_MGAUSS_LSB[regs.get("CTRL6.MFS")] * 1e-3
            v = regs.values
            off = [_s16(v[OFFSET_X_L_M + 2 * j], v[OFFSET_X_L_M + 1 + 2 * j]) for j in range(3)]
            raw = (to_int16(b[0] / lsb - off[0]), to_int16(b[1] / lsb - off[1]),
                   to_int16(b[2] / lsb - off[2]))
        self._last_mag = raw
        return raw

    def _r_out(self, ch: SampleChannel, i: int, _value: int) -> int:
        return ch.read_byte(i)

    # -- configuration --------------------------------------------------------------------------

    def _w_ctrl0(self, value: int, old: int) -> None:
        self._update_fifo()
        if value & CTRL0_BOOT:
            self._start_boot()

    def _w_ctrl2(self, value: int, old: int) -> None:
        afs = (value & CTRL2_AFS) >> CTRL2_AFS_LSB
        if afs > 4:
            self._warn_once("afs", f"reserved AFS={afs:03b}: +-16 g sensitivity")

    def _w_ctrl1(self, value: int, old: int) -> None:
        acc = self.accel
        acc.axes = value & CTRL1_AXES
        bdu = bool(value & CTRL1_BDU)
        acc.set_bdu(bdu)
        self.mag.set_bdu(bdu)
        aodr = value >> CTRL1_AODR_LSB
        if aodr >= len(ACCEL_ODR_MHZ):
            self._warn_once("aodr", f"AODR={aodr:04b} not in the datasheet table: power-down")
        odr = ACCEL_ODR_MHZ[aodr] if aodr < len(ACCEL_ODR_MHZ) else 0
        if odr != acc.odr_mhz:
            if odr:
                acc.start(self._t, odr)
            else:
                acc.stop()
        self._w_mag_cfg(0, 0)  # 100 Hz mag depends on the accel rate

    def _mag_odr_mhz(self) -> int:
        regs = self.regs
        md = regs.get("CTRL7.MD")
        t_only = regs.get("CTRL7.T_ONLY") and regs.get("CTRL5.TEMP_EN")
        if md not in (0, 1) and not t_only:
            return 0
        if regs.get("CTRL7.MLP"):
            return MAG_ODR_MHZ[0]
        m_odr = regs.get("CTRL5.M_ODR")
        if m_odr >= len(MAG_ODR_MHZ):
            self._warn_once("m_odr", f"reserved M_ODR={m_odr:03b} with the magnetometer on: "
                            f"no conversions")
            return 0
        aodr = regs.get("CTRL1.AODR")
        if m_odr == 5 and 1 <= aodr <= 5:
            return MAG_ODR_MHZ[4]
        return MAG_ODR_MHZ[m_odr]

    def _w_mag_cfg(self, value: int, old: int) -> None:
        mag = self.mag
        odr = self._mag_odr_mhz()
        single = self.regs.get("CTRL7.MD") == 1
        if not odr:
            mag.stop()
        elif single and mag.limit is None:
            mag.start(self._t, odr, limit=1)
        elif odr != mag.odr_mhz or (not single and mag.limit is not None):
            mag.start(self._t, odr)

    def _update_fifo(self) -> None:
        regs = self.regs
        self._select_fifo_mode(self.accel, regs.get("FIFO_CTRL.FM"),
                               bool(regs.get("CTRL0.FIFO_EN")))

    def _power_on(self) -> None:
        self.accel.clear()
        self.mag.clear()
        self._last_accel = self._last_mag = None
        self._temp_raw = 0

    # -- StSpiTarget hooks ----------------------------------------------------------------------

    def _service(self, t_ns: int) -> None:
        self.accel.advance(t_ns)
        mag = self.mag
        single = mag.limit is not None
        mag.advance(t_ns)
        if single and not mag.running:
            # Single conversion done: the part returns to power-down (MD = 10).
            self.regs.set("CTRL7.MD", 0b10)

    def _fifo_wrap(self) -> bool:
        return self.accel.fifo_mode != FIFO_BYPASS

    def _refresh_pins(self, t_ns: int) -> None:
        """Drive INT1/INT2 from the routed sources and arm the next time a level can change.

        Routing (CTRL3 on INT1: DRDY_A, DRDY_M, EMPTY; CTRL4 on INT2: DRDY_A, DRDY_M, Overrun,
        FTH) is evaluated with plain bit tests because this runs on every SPI access. A pin that
        is off can turn on at its sources' next sample; the EMPTY source (on when the FIFO is
        empty) can change at the accel's next sample whatever the level.
        """
        int1, int2 = self.int1_pin, self.int2_pin
        if int1 is None and int2 is None:
            return
        v = self.regs.values
        acc, mag, faults = self.accel, self.mag, self.faults
        dead = faults.drdy_stuck or faults.absent
        active = v[INT_CTRL_M] & INT_CTRL_M_IEA
        fifo = acc.fifo_src(v[FIFO_CTRL] & FIFO_CTRL_FTH)
        c3, c4 = v[CTRL3], v[CTRL4]
        acc_next = mag_next = False
        if int1 is not None:
            on = 0 if dead else int(bool((c3 & CTRL3_INT1_DRDY_A and acc.da)
                                         or (c3 & CTRL3_INT1_DRDY_M and mag.da)
                                         or (c3 & CTRL3_INT1_EMPTY and fifo & FIFO_SRC_EMPTY)))
            self._set_pin(int1, on if active else 1 - on, t_ns)
            if not dead:
                if not on:
                    acc_next = bool(c3 & (CTRL3_INT1_DRDY_A | CTRL3_INT1_EMPTY))
                    mag_next = bool(c3 & CTRL3_INT1_DRDY_M)
                elif c3 & CTRL3_INT1_EMPTY:
                    acc_next = True
        if int2 is not None:
            on = 0 if dead else int(bool((c4 & CTRL4_INT2_DRDY_A and acc.da)
                                         or (c4 & CTRL4_INT2_DRDY_M and mag.da)
                                         or (c4 & CTRL4_INT2_OVERRUN and fifo & FIFO_SRC_OVRN)
                                         or (c4 & CTRL4_INT2_FTH and fifo & FIFO_SRC_FTH)))
            self._set_pin(int2, on if active else 1 - on, t_ns)
            if not dead and not on:
                acc_next = acc_next or bool(
                    c4 & (CTRL4_INT2_DRDY_A | CTRL4_INT2_OVERRUN | CTRL4_INT2_FTH))
                mag_next = mag_next or bool(c4 & CTRL4_INT2_DRDY_M)
        t_acc = acc.next_sample_ns() if acc_next else None
        t_mag = mag.next_sample_ns() if mag_next else None
        if t_acc is None:
            self._arm(t_mag)
        elif t_mag is None:
            self._arm(t_acc)
        else:
            self._arm(min(t_acc, t_mag))
