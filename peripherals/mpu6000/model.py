"""InvenSense MPU-6000 on SPI: register file, lazy sampling, FIFO, data-ready pin, faults.

Facts are from shared/reference/sensors.md section 1. Decisions the datasheet leaves open:

* Lazy sampling. Samples are not kernel events. The chip's sample clock is a phase (``_t0``)
  and a period; whenever the bus touches the chip (the command byte of a transfer) or a pin
  event needs it, every sample due since the last look is produced in one numpy batch
  (:mod:`.sampling`). The physical input is read once per batch, so all samples of a batch see
  the environment as it is at the moment of the look (at most one driver cycle, 1 ms with PX4's
  driver, late; the world itself steps at 1 kHz). Samples nobody can see (FIFO off: all but the
  last; FIFO on: those pushed out by overflow) are skipped but still advance the filters, which
  is exact because the input is constant within a batch.
* Kernel events exist only for the INT pin: one per sample while INT_ENABLE.DATA_RDY_EN is set
  and a pin is wired, one at the predicted overflow time while FIFO_OFLOW_EN is set. With
  nothing enabled, an idle chip costs nothing. The 50 us pulse end is not an event: the pin
  returns lazily when nothing observes that edge (:meth:`board.gpio.Pin.pulse`), and the chip's
  own view of INT (``_int_on``) compares the clock with the pulse end. The leading edge's EXTI
  handler runs inside the chip's sample event (``sync``): PX4's driver sees the same edge time
  in interrupt context, one kernel event per sample instead of three.
* SPI clock. The datasheet allows 1 MHz (+10 %) for all registers and 20 MHz (+10 %) for reading
  INT_STATUS and the sensor data. The FIFO count and data port are served at 20 MHz too (PX4
  reads them on its fast clock and real parts deliver). Above 22 MHz nothing is decoded (MISO
  0xFF, base class). Between 1.1 and 22 MHz a read of any other register returns 0xFF (the
  output stage cannot follow: the bits read at the rail) and writes are ignored; such a
  selection is counted in ``too_fast_count`` and logged once.
* DEVICE_RESET (and power-up) make the chip deaf for 100 ms: reads return 0x00, writes are
  ignored. An unpowered or absent chip leaves MISO to its pull-up (0xFF).
* Not modelled: the aux I2C master and its FIFO slots, the DMP, FSYNC, motion detection, low-power
  CYCLE mode (treated as normal sampling), the 30 ms gyro start-up, user offset registers.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from typing import TYPE_CHECKING, Final

import numpy as np

from board.kernel import NS_PER_MS, PRIO_HW, Event, Kernel
from board.spi import SpiTarget
from peripherals.errors import AxisErrors, ImuErrorModel
from peripherals.faults import FaultState
from peripherals.mpu6000.registers import (
    ACCEL_CONFIG,
    ACCEL_CONFIG_AFS_SEL,
    ACCEL_CONFIG_AFS_SEL_LSB,
    CLKSEL_STOP,
    CONFIG,
    CONFIG_DLPF_CFG,
    DATA_FIRST,
    FAST_READ,
    FIFO_EN,
    FIFO_R_W,
    FIFO_SIZE,
    GYRO_CONFIG,
    GYRO_CONFIG_FS_SEL,
    GYRO_CONFIG_FS_SEL_LSB,
    INT_ENABLE,
    INT_ENABLE_DATA_RDY_EN,
    INT_ENABLE_FIFO_OFLOW_EN,
    INT_PIN_CFG,
    INT_PIN_CFG_INT_LEVEL,
    INT_PIN_CFG_INT_OPEN,
    INT_PIN_CFG_INT_RD_CLEAR,
    INT_PIN_CFG_LATCH_INT_EN,
    INT_STATUS,
    INT_STATUS_DATA_RDY_INT,
    INT_STATUS_FIFO_OFLOW_INT,
    PWR_MGMT_1,
    PWR_MGMT_1_CLKSEL,
    PWR_MGMT_1_DEVICE_RESET,
    PWR_MGMT_1_SLEEP,
    PWR_MGMT_1_TEMP_DIS,
    PWR_MGMT_2,
    REV_C_IDS,
    SELF_TEST_BITS,
    SELF_TEST_TRIM,
    SIGNAL_PATH_RESET,
    SIGNAL_PATH_RESET_ACCEL_RESET,
    SIGNAL_PATH_RESET_GYRO_RESET,
    SMPLRT_DIV,
    USER_CTRL,
    USER_CTRL_FIFO_EN,
    USER_CTRL_FIFO_RESET,
    USER_CTRL_SIG_COND_RESET,
    USER_CTRL_STROBES,
    mpu6000_registers,
    self_test_response,
)
from peripherals.mpu6000.rotation import board_to_sensor
from peripherals.mpu6000.sampling import SampleEngine
from peripherals.physics import Environment
from peripherals.regs import RegisterFile
from common.units import G0_M_S2

if TYPE_CHECKING:
    from board.gpio import Pin

__all__ = ["Mpu6000", "default_accel_errors", "default_gyro_errors"]

log = logging.getLogger(__name__)

DEG: Final = 0.017453292519943295
RESET_TIME_NS: Final = 100 * NS_PER_MS
INT_PULSE_NS: Final = 50_000
REG_CLOCK_LIMIT_HZ: Final = 1_100_000
#: SPI framing (sheet 1.3): the command byte is R/W (bit 7, 1 = read) and the address (6:0).
SPI_READ: Final = 0x80
SPI_ADDR_MASK: Final = 0x7F
DATA_CLOCK_LIMIT_HZ: Final = 22_000_000



def default_gyro_errors() -> AxisErrors:
    """Datasheet noise (0.005 deg/s/rtHz) on a part whose large initial zero-rate offset
    (+-20 deg/s) has been trimmed, as a calibrated board looks: 0.1 deg/s bias spread."""
    return AxisErrors(noise_density=0.005 * DEG, bias=0.1 * DEG, bias_instability=1e-5,
                      scale_error=0.002, misalignment_rad=0.001)


def default_accel_errors() -> AxisErrors:
    """Datasheet noise (400 ug/rtHz) with a calibrated 2 mg bias spread."""
    return AxisErrors(noise_density=400e-6 * G0_M_S2, bias=0.002 * G0_M_S2, scale_error=0.002,
                      misalignment_rad=0.001)


class Mpu6000(SpiTarget):
    """The chip as the SPI bus and the INT pin see it.

    ``rotation`` is how the die sits on the board: a PX4 rotation enum (int or name) or a
    board->sensor 3x3 matrix (see :mod:`.rotation`). ``gyro_errors``/``accel_errors`` replace the
    calibrated-part defaults; ``power_up_ms`` is the time from construction (power on) until
    the chip answers. ``bias_step_sensor`` says where ``faults.bias_step`` (SI units) goes:
    ``"gyro"`` (rad/s), ``"accel"`` (m/s^2) or ``"both"``.
    """

    max_clock_hz: int | None = DATA_CLOCK_LIMIT_HZ

    def __init__(self, kernel: Kernel, env: Environment, rng: np.random.Generator,
                 name: str = "mpu6000", drdy_pin: Pin | None = None, product_id: int = 0x58,
                 rotation: int | str | Sequence[Sequence[float]] | None = None,
                 gyro_errors: AxisErrors | None = None, accel_errors: AxisErrors | None = None,
                 power_up_ms: float = 100.0, self_test_trim: tuple[int, int, int, int] =
                 SELF_TEST_TRIM, bias_step_sensor: str = "gyro") -> None:
        if not 0 <= product_id <= 0xFF:
            raise ValueError(f"{name}: product_id 0x{product_id:X} is not a byte")
        if bias_step_sensor not in ("gyro", "accel", "both"):
            raise ValueError(f"{name}: bias_step_sensor must be gyro, accel or both")
        self.kernel = kernel
        self.env = env
        self.rng = rng
        self.name = name
        self.drdy_pin = drdy_pin
        self.product_id = product_id
        self.faults = FaultState()
        self.bias_step_sensor = bias_step_sensor
        self.regs = RegisterFile(name, mpu6000_registers(product_id, self_test_trim))
        self._bind_hooks()
        self.engine = SampleEngine(
            rng, board_to_sensor(rotation),
            ImuErrorModel(gyro_errors or default_gyro_errors(), rng),
            ImuErrorModel(accel_errors or default_accel_errors(), rng),
            self_test_response(self_test_trim), rev_c=product_id in REV_C_IDS)
        self.fifo = bytearray()
        self._fifo_last = 0
        self._id_after_reset: int | None = None
        self._count_latch = 0
        #: Samples produced since power-on (lazily, see module docstring).
        self.samples_produced = 0
        self.powered = True
        self._ready_ns = kernel.now_ns + int(power_up_ms * NS_PER_MS)
        # Sampling clock.
        self._awake = False
        self._t0 = 0
        self._k = 0
        self._period = 125_000
        # Transaction state.
        self._t = 0
        self._cmd = -1
        self._addr = 0
        self._reading = False
        self._slow_only = False
        self._refused = False
        self._did_read = False
        # INT pin.
        self._int_active = False
        #: End of the running INT pulse (-1: none, or a held latched level).
        self._pulse_end_ns = -1
        self._drdy_entry: Event | None = None
        self._ovf_entry: Event | None = None
        #: Pin drives for INT asserted and idle (0, 1, or None: released, open drain).
        self._on_drive: int | None = 0
        self._off_drive: int | None = 1
        self._retime()
        self._int_idle()

    # -- register behaviour ---------------------------------------------------------------------

    def _bind_hooks(self) -> None:
        r = self.regs
        for name in ("SMPLRT_DIV", "CONFIG", "GYRO_CONFIG", "ACCEL_CONFIG", "PWR_MGMT_2"):
            r.hook(name, on_write=self._on_config)
        r.hook("PWR_MGMT_1", on_write=self._on_pwr_mgmt_1)
        r.hook("USER_CTRL", on_write=self._on_user_ctrl)
        r.hook("SIGNAL_PATH_RESET", on_write=self._on_signal_path_reset)
        r.hook("FIFO_EN", on_write=self._on_int_config)
        r.hook("INT_ENABLE", on_write=self._on_int_config)
        r.hook("INT_PIN_CFG", on_write=self._on_int_pin_cfg)
        r.hook("INT_STATUS", on_read=self._read_int_status)
        r.hook("FIFO_COUNTH", on_read=self._read_count_h)
        r.hook("FIFO_COUNTL", on_read=self._read_count_l)
        r.hook("FIFO_R_W", on_read=self._read_fifo_byte, on_write=self._write_fifo_byte)
        r.hook("WHO_AM_I", on_read=self._read_who_am_i)

    def _on_config(self, value: int, old: int) -> None:
        self._retime()

    def _on_pwr_mgmt_1(self, value: int, old: int) -> None:
        if value & PWR_MGMT_1_DEVICE_RESET:
            self._device_reset(self._t)
            return
        self._retime()

    def _on_user_ctrl(self, value: int, old: int) -> None:
        if value & USER_CTRL_FIFO_RESET:
            self.fifo.clear()
        if value & USER_CTRL_SIG_COND_RESET:  # signal paths and sensor registers
            self.engine.reset_filters()
            self.regs.values[DATA_FIRST:DATA_FIRST + 14] = bytes(14)
        # The strobes clear themselves (DMP_RESET too).
        self.regs.values[USER_CTRL] = value & ~USER_CTRL_STROBES & 0xFF
        self._schedule_int()

    def _on_signal_path_reset(self, value: int, old: int) -> None:
        self.engine.reset_filters(gyro=bool(value & SIGNAL_PATH_RESET_GYRO_RESET),
                                  accel=bool(value & SIGNAL_PATH_RESET_ACCEL_RESET))
        self.regs.values[SIGNAL_PATH_RESET] = 0

    def _on_int_config(self, value: int, old: int) -> None:
        self._schedule_int()

    def _on_int_pin_cfg(self, value: int, old: int) -> None:
        if self._int_on() and not value & INT_PIN_CFG_LATCH_INT_EN:
            self._int_active = False  # leaving latched mode ends a held level
        self._int_level()
        self._schedule_int()

    def _read_int_status(self, value: int) -> int:
        self.regs.values[INT_STATUS] = 0
        if self._int_on() and self.regs.values[INT_PIN_CFG] & INT_PIN_CFG_LATCH_INT_EN:
            self._int_active = False
            self._int_level()
        return value

    def _read_count_h(self, value: int) -> int:
        self._count_latch = len(self.fifo)
        return self._count_latch >> 8

    def _read_count_l(self, value: int) -> int:
        return self._count_latch & 0xFF

    def _read_fifo_byte(self, value: int) -> int:
        return self._fifo_pop(1)[0]

    def _write_fifo_byte(self, value: int, old: int) -> None:
        self._fifo_push(bytes((value,)))

    def _read_who_am_i(self, value: int) -> int:
        wrong = self.faults.wrong_id
        if wrong is None:
            wrong = self._id_after_reset
        return value if wrong is None else wrong & 0xFF

    # -- power and reset ------------------------------------------------------------------------

    def _device_reset(self, t_ns: int) -> None:
        """DEVICE_RESET: every register to its reset value, FIFO empty, asleep, deaf 100 ms."""
        self.regs.reset()
        self.fifo.clear()
        self._fifo_last = 0
        # A part whose identity comes back wrong from a reset (FaultState.wrong_id_after_reset)
        self._id_after_reset = self.faults.wrong_id_after_reset
        self.engine.reset_filters()
        self._ready_ns = t_ns + RESET_TIME_NS
        self._retime()
        self._int_idle()

    def set_power(self, on: bool) -> None:
        """The sensor rail (PE3 on FMUv2): off makes the chip vanish, on is a power-on reset."""
        self._t = t = self.kernel.context_ns
        if on and not self.powered:
            self.powered = True
            self._device_reset(t)
        elif not on and self.powered:
            self._catch_up(t)
            self.powered = False
            self._awake = False
            self._schedule_int()

    # -- sampling clock -------------------------------------------------------------------------

    def _sample_period_ns(self) -> int:
        v = self.regs.values
        fast = (v[CONFIG] & CONFIG_DLPF_CFG) in (0, 7)
        return (125_000 if fast else 1_000_000) * (1 + v[SMPLRT_DIV])

    def _retime(self) -> None:
        """A register that shapes sampling changed (the caller caught up to ``_t`` first)."""
        v = self.regs.values
        t = self._t
        pwr = v[PWR_MGMT_1]
        awake = (self.powered and not pwr & PWR_MGMT_1_SLEEP
                 and (pwr & PWR_MGMT_1_CLKSEL) != CLKSEL_STOP)
        period = self._sample_period_ns()
        if self._awake and awake:
            self._t0 += self._k * self._period  # keep the phase: next sample one period on
            self._k = 0
        elif awake:
            self._t0 = t
            self._k = 0
            self.engine.wake(t)
        self._period = period
        self._awake = awake
        gyro, accel = v[GYRO_CONFIG], v[ACCEL_CONFIG]
        self.engine.configure(v[CONFIG] & CONFIG_DLPF_CFG, v[SMPLRT_DIV],
                              (gyro & GYRO_CONFIG_FS_SEL) >> GYRO_CONFIG_FS_SEL_LSB,
                              (accel & ACCEL_CONFIG_AFS_SEL) >> ACCEL_CONFIG_AFS_SEL_LSB,
                              gyro & SELF_TEST_BITS, accel & SELF_TEST_BITS, v[PWR_MGMT_2])
        self._schedule_int()

    def _catch_up(self, t_ns: int) -> None:
        """Produce every sample due at or before ``t_ns``."""
        if not self._awake:
            return
        k_max = (t_ns - self._t0) // self._period
        n = k_max - self._k
        if n <= 0:
            return
        v = self.regs.values
        fifo_en = v[FIFO_EN] if v[USER_CTRL] & USER_CTRL_FIFO_EN else 0
        rows, record = self.engine.produce(
            self.env, self._t0, self._period, self._k + 1, n, fifo_en, FIFO_SIZE,
            self.faults, self.bias_step_sensor,
            temp_enabled=not v[PWR_MGMT_1] & PWR_MGMT_1_TEMP_DIS)
        self._k = k_max
        self.samples_produced += n
        v[DATA_FIRST:DATA_FIRST + 14] = rows
        if record:
            self._fifo_push(record)  # sets FIFO_OFLOW_INT when the oldest bytes are lost
            if self.faults.fifo_overflow:
                # The FIFO fills faster than the sample clock: by the next look it is full
                # and has overflowed (the oldest bytes lost, records misaligned).
                self._fifo_push(record * (FIFO_SIZE // len(record) + 1))
        v[INT_STATUS] |= INT_STATUS_DATA_RDY_INT

    # -- FIFO -----------------------------------------------------------------------------------

    def _fifo_push(self, data: bytes) -> None:
        fifo = self.fifo
        fifo += data
        excess = len(fifo) - FIFO_SIZE
        if excess > 0:
            del fifo[:excess]  # the oldest bytes are lost; record alignment goes with them
            self.regs.values[INT_STATUS] |= INT_STATUS_FIFO_OFLOW_INT

    def _fifo_pop(self, n: int) -> bytes:
        fifo = self.fifo
        have = len(fifo)
        if n <= have:
            out = bytes(fifo[:n])
            del fifo[:n]
        else:  # an empty FIFO repeats the last byte read
            last = fifo[-1] if have else self._fifo_last
            out = bytes(fifo) + bytes((last,)) * (n - have)
            fifo.clear()
        if out:
            self._fifo_last = out[-1]
        return out

    # -- SPI ------------------------------------------------------------------------------------

    def _select(self, t_ns: int, mode: int, clock_hz: int) -> None:
        self._cmd = -1
        self._slow_only = clock_hz > REG_CLOCK_LIMIT_HZ
        self._refused = False
        self._did_read = False

    def _exchange(self, t_ns: int, tx: bytes) -> bytes:
        n = len(tx)
        if not self.powered or self.faults.absent:
            return b"\xff" * n
        if t_ns < self._ready_ns:
            self._cmd = 0x100  # deaf: nothing decoded in this selection
            return bytes(n)
        start = 0
        if self._cmd < 0:
            c = self._cmd = tx[0]
            self._reading = bool(c & SPI_READ)
            self._addr = c & SPI_ADDR_MASK
            self._t = t_ns
            self._catch_up(t_ns)
            start = 1
        elif self._cmd > 0xFF:
            return bytes(n)
        if start >= n:
            return bytes(n)
        if self._reading:
            self._did_read = True
            if self._addr == FIFO_R_W:
                return (b"\x00" if start else b"") + self._fifo_pop(n - start)
            return (b"\x00" if start else b"") + self._read_bytes(n - start)
        self._write_bytes(tx[start:])
        return bytes(n)

    def _read_bytes(self, n: int) -> bytes:
        out = bytearray(n)
        addr = self._addr
        read = self.regs.read
        slow_only = self._slow_only
        for i in range(n):
            if slow_only and addr not in FAST_READ:
                out[i] = 0xFF
                self._refused = True
            else:
                out[i] = read(addr)
            if addr != FIFO_R_W:
                addr = (addr + 1) & SPI_ADDR_MASK
        self._addr = addr
        return bytes(out)

    def _write_bytes(self, data: bytes) -> None:
        if self._slow_only:
            self._refused = True
            return
        addr = self._addr
        for b in data:
            if self._t < self._ready_ns:  # a DEVICE_RESET earlier in this burst
                break
            self.regs.write(addr, b)
            if addr != FIFO_R_W:
                addr = (addr + 1) & SPI_ADDR_MASK
        self._addr = addr

    def _deselect(self, t_ns: int) -> None:
        if self._refused:
            self.too_fast_count += 1
            if self.too_fast_count == 1:
                log.warning("%s: register access at %d Hz above the 1.1 MHz limit: reads 0xFF, "
                            "writes ignored", self.name, self.clock_hz)
        if self._did_read and self.regs.values[INT_PIN_CFG] & INT_PIN_CFG_INT_RD_CLEAR:
            self._read_int_status(0)
        if self._ovf_entry is not None or self.regs.values[INT_ENABLE] & INT_ENABLE_FIFO_OFLOW_EN:
            self._schedule_int()

    # -- INT pin --------------------------------------------------------------------------------

    def _int_on(self) -> bool:
        """INT asserted now? A pulse ends by the clock, not by an event (module docstring)."""
        if self._int_active and 0 <= self._pulse_end_ns <= self.kernel.now_ns:
            self._int_active = False
            self._pulse_end_ns = -1
        return self._int_active

    def _drive_pin(self, drive: int | None) -> None:
        pin = self.drdy_pin
        if pin is None:
            return
        if drive is None:
            pin.release()
        elif drive:
            pin.high()
        else:
            pin.low()

    def _int_level(self) -> None:
        """Drive the pin to match the INT state and INT_PIN_CFG (level, open drain); a pulse
        still running keeps its end, a latched configuration holds it."""
        pin = self.drdy_pin
        if pin is None or not self.powered:
            return
        cfg = self.regs.values[INT_PIN_CFG]
        active_low = bool(cfg & INT_PIN_CFG_INT_LEVEL)
        self._on_drive = 0 if active_low else 1
        self._off_drive = None if cfg & INT_PIN_CFG_INT_OPEN else (1 if active_low else 0)
        if self._int_on():
            if cfg & INT_PIN_CFG_LATCH_INT_EN:
                self._pulse_end_ns = -1  # latched: held until INT_STATUS is cleared
            if self._pulse_end_ns >= 0:
                pin.pulse(self._on_drive, self._off_drive, self._pulse_end_ns)
            else:
                self._drive_pin(self._on_drive)
        else:
            self._drive_pin(self._off_drive)

    def _int_idle(self) -> None:
        self._int_active = False
        self._pulse_end_ns = -1
        self._int_level()

    def _assert_int(self, sync: bool = False) -> None:
        """Assert INT from a chip event (now): held when latched, else a 50 us pulse (a pulse
        still running is extended). ``sync``: the pin's listeners (the driver's EXTI handler)
        run inside this event, as the data-ready interrupt does."""
        faults = self.faults
        if faults.drdy_stuck or faults.absent:
            return
        if self.regs.values[INT_PIN_CFG] & INT_PIN_CFG_LATCH_INT_EN:  # held until INT_STATUS read
            if not self._int_on():
                self._int_active = True
                self._pulse_end_ns = -1
                self._drive_pin(self._on_drive)
            return
        self._int_active = True
        end = self._pulse_end_ns = self.kernel.now_ns + INT_PULSE_NS
        pin = self.drdy_pin
        if pin is not None:
            pin.pulse(self._on_drive, self._off_drive, end, sync)

    def _schedule_int(self) -> None:
        """(Re)arm the kernel events that move the INT pin; none when nothing can be seen."""
        k = self.kernel
        if self._drdy_entry is not None:
            Kernel.cancel(self._drdy_entry)
            self._drdy_entry = None
        if self._ovf_entry is not None:
            Kernel.cancel(self._ovf_entry)
            self._ovf_entry = None
        if self.drdy_pin is None or not self._awake:
            return
        v = self.regs.values
        t = max(self._t, k.now_ns)
        k_next = (t - self._t0) // self._period + 1
        if v[INT_ENABLE] & INT_ENABLE_DATA_RDY_EN:
            self._drdy_entry = k.post(self._t0 + k_next * self._period, PRIO_HW,
                                      self._on_drdy, ())
        if v[INT_ENABLE] & INT_ENABLE_FIFO_OFLOW_EN and v[USER_CTRL] & USER_CTRL_FIFO_EN:
            rec = self.engine.record_bytes(v[FIFO_EN])
            if rec:
                k_ovf = self._k + (FIFO_SIZE - len(self.fifo)) // rec + 1
                self._ovf_entry = k.post(self._t0 + max(k_ovf, k_next) * self._period,
                                         PRIO_HW, self._on_overflow, ())

    def _on_drdy(self) -> None:
        """A sample is due: re-arm for the next one and pulse INT. The driver's EXTI handler
        runs inside this event (``sync``), at this time, in interrupt context; the overflow
        event asserts INT unsynchronised, as it still re-arms after (a queued EXTI is fine)."""
        k = self.kernel
        self._drdy_entry = k.post(k.now_ns + self._period, PRIO_HW, self._on_drdy, ())
        self._assert_int(sync=True)

    def _on_overflow(self) -> None:
        self._ovf_entry = None
        self._t = t = self.kernel.now_ns
        self._catch_up(t)
        if self.regs.values[INT_STATUS] & INT_STATUS_FIFO_OFLOW_INT:
            self._assert_int()
        self._schedule_int()

    def __repr__(self) -> str:
        return (f"<Mpu6000 {self.name} {'awake' if self._awake else 'asleep'} "
                f"fifo={len(self.fifo)}>")
