"""What the ST MEMS parts on SPI1 (L3GD20 gyro, LSM303D accel/mag) have in common.

Both chips speak the same SPI protocol (reference sheet 2.3, 3.2): the first byte of a selection
is a command, bit 7 = read, bit 6 = MS (auto-increment the address for each further byte),
bits 5:0 the register address; data follows from the second byte; without MS every further byte
hits the same register. Both latch 3-axis samples at an output data rate into little-endian
(or big-endian, L3GD20 BLE) 16-bit output registers with the same data-ready, overrun, block
data update (BDU) and 32-level FIFO behaviour. That shared machinery lives here so the two
models only declare their register maps and physics.

Cheap sampling. The FMU runs faster than real time, so nothing ticks at the output data rate.
A :class:`SampleChannel` knows its sample grid (sample k is latched at
``t0 + ceil(k * 1e12 / odr_mHz)`` ns: exact mean rate, no drift) and, when the bus or a pin
event looks at it, computes only the samples that are still observable (the newest one for the
output registers, at most 32 for the FIFO). Kernel events are scheduled only for data-ready pin
edges that are enabled in the chip and wired to a pin, and only when the level can change.

Choices where the reference sheet is unsure (section 10), documented once here:

* FIFO_SRC reset/empty value 0x20 (EMPTY). FSS is 5 bits: a full FIFO (32 samples) reads FSS =
  31 with OVRN set [?]. WTM/FTH is set when the level is >= the threshold and not empty.
* In FIFO mode collection stops when 32 samples are stored (OVRN set) and does not resume until
  the FIFO is reset through Bypass mode; in Stream mode the oldest sample is overwritten, OVRN
  is set and cleared again when a sample is read.
* With the FIFO enabled an auto-increment burst that passes OUT_Z_H (0x2D) wraps to OUT_X_L
  (0x28) and reading 0x2D pops one sample (the behaviour PX4's LSM303D driver relies on) [?].
* Stream-to-FIFO and Bypass-to-Stream switch on interrupt-generator events, which are not
  modelled: they behave as Stream and Bypass respectively.
* BOOT (reboot memory content) takes 5 ms, then every register returns to its reset value.
* The command byte's own MISO slot reads 0xFF (MISO is not driven before the address is known).
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable, Sequence
from typing import Final

import numpy as np

from board.gpio import Pin
from board.kernel import PRIO_HW, Event, Kernel
from board.spi import SpiTarget
from common.rotation import board_to_sensor
from peripherals.errors import ImuErrorModel
from peripherals.faults import FaultState
from peripherals.regs import RegisterFile
from common.quaternion import Vec3

__all__ = [
    "BOOT_NS",
    "FIFO_BYPASS",
    "FIFO_DEPTH",
    "FIFO_FIFO",
    "FIFO_STREAM",
    "MS_BIT",
    "READ_BIT",
    "Matrix3",
    "SampleChannel",
    "StSpiTarget",
    "check_rotation",
    "period_ns",
    "to_int16",
]

log = logging.getLogger(__name__)

READ_BIT: Final = 0x80
MS_BIT: Final = 0x40
ADDR_MASK: Final = 0x3F
#: Reboot time after BOOT is set (reference 3.6: "clear BOOT after <= 5 ms").
BOOT_NS: Final = 5_000_000
#: FIFO depth in samples (X, Y, Z each) of both parts.
FIFO_DEPTH: Final = 32
FIFO_BYPASS: Final = 0
FIFO_FIFO: Final = 1
FIFO_STREAM: Final = 2
#: FIFO_CTRL(_REG).FM -> channel FIFO mode, both parts. Stream-to-FIFO runs as Stream and
#: Bypass-to-Stream as Bypass: their switch events come from the unmodelled interrupt generators.
FM_MODES: Final = {0: FIFO_BYPASS, 1: FIFO_FIFO, 2: FIFO_STREAM, 3: FIFO_STREAM, 4: FIFO_BYPASS}
#: STATUS (L3GD20 STATUS_REG, LSM303D STATUS_A/STATUS_M) and FIFO_SRC bits, the same on both
#: parts (FIFO_SRC bit 7 is WTM on the L3GD20, FTH on the LSM303D).
STATUS_ZYXOR: Final = 0x80
STATUS_ZYXDA: Final = 0x08
FIFO_SRC_THRESHOLD: Final = 0x80
FIFO_SRC_OVRN: Final = 0x40
FIFO_SRC_EMPTY: Final = 0x20
FIFO_SRC_FSS: Final = 0x1F
#: First and last output-register address of the 3-axis block (both parts, accel on LSM303D).
OUT_FIRST: Final = 0x28
OUT_LAST: Final = 0x2D

Matrix3 = tuple[tuple[float, float, float], tuple[float, float, float],
                tuple[float, float, float]]
Raw3 = tuple[int, int, int]
#: What a saturated axis reads: the positive rail.
RAILS: Final[Raw3] = (32767, 32767, 32767)


def check_rotation(rotation: int | str | Sequence[Sequence[float]] | None) -> Matrix3 | None:
    """The board->sensor matrix of a mounting (a PX4 rotation enum or name, or a 3x3
    board->sensor matrix); identity becomes None (the fast path)."""
    return board_to_sensor(rotation)


def rotate(m: Matrix3 | None, v: Sequence[float]) -> Vec3:
    """``m @ v`` (identity when ``m`` is None)."""
    if m is None:
        return (v[0], v[1], v[2])
    x, y, z = v
    return (m[0][0] * x + m[0][1] * y + m[0][2] * z,
            m[1][0] * x + m[1][1] * y + m[1][2] * z,
            m[2][0] * x + m[2][1] * y + m[2][2] * z)


def to_int16(value: float) -> int:
    """Quantise to the 16-bit two's complement output, saturating as the ADC does."""
    r = round(value)
    return 32767 if r > 32767 else (max(r, -32768))


def period_ns(odr_mhz: int, k: int = 1) -> int:
    """Time of sample ``k`` after the start of a grid at ``odr_mhz`` milli-hertz."""
    return -(-k * 10**12 // odr_mhz)


class SampleChannel:
    """One 3-axis output of a chip: sample grid, output latch with BDU, status bits, FIFO.

    ``sample_fn(t_ns)`` returns the raw counts (x, y, z) the chip converts for a sample latched
    at ``t_ns``; it is called only for samples someone can still observe.
    """

    def __init__(self, sample_fn: Callable[[int], tuple[int, int, int]],
                 fifo_depth: int = 0) -> None:
        self.sample_fn = sample_fn
        self.fifo_depth = fifo_depth
        self.clear()

    def clear(self) -> None:
        """Power-on state: stopped, outputs zero, no status, FIFO empty and bypassed."""
        self.odr_mhz = 0
        self.t0_ns = 0
        self.k = 0
        #: Conversions left in single-conversion mode (None: continuous).
        self.limit: int | None = None
        self.axes = 0b111
        self.bdu = False
        self.latest = [0, 0, 0]
        self.out = [0, 0, 0]
        self.da = 0
        self.ovr = 0
        self._halves = [0, 0, 0]
        self.fifo: deque[tuple[int, int, int]] = deque()
        self.fifo_mode = FIFO_BYPASS
        self.fifo_ovrn = False
        self.fifo_stopped = False
        self._head = (0, 0, 0)
        #: Samples latched since power-on (tests and status).
        self.samples = 0

    # -- grid ---------------------------------------------------------------------------------

    @property
    def running(self) -> bool:
        return self.odr_mhz > 0

    def start(self, t_ns: int, odr_mhz: int, limit: int | None = None) -> None:
        """(Re)start conversions at ``odr_mhz``: first sample one period after ``t_ns``."""
        self.odr_mhz = odr_mhz
        self.t0_ns = t_ns
        self.k = 0
        self.limit = limit

    def stop(self) -> None:
        self.odr_mhz = 0
        self.limit = None

    def sample_time(self, k: int) -> int:
        return self.t0_ns + period_ns(self.odr_mhz, k)

    def next_sample_ns(self) -> int | None:
        return self.sample_time(self.k + 1) if self.odr_mhz else None

    def advance(self, t_ns: int) -> int:
        """Latch every sample due at or before ``t_ns``; returns how many were due.

        ``sample_fn`` is called once per observable sample in increasing ``k`` (the samples
        pushed into the FIFO, then the newest if it was not among them): the error models draw
        their noise in that order, so the order is part of the behaviour.
        """
        odr = self.odr_mhz
        t0 = self.t0_ns
        if not odr or t_ns <= t0:
            return 0
        n = (t_ns - t0) * odr // 10**12 - self.k
        if n <= 0:
            return 0
        limit = self.limit
        if limit is not None:
            n = min(n, limit)
            self.limit = limit - n
        first, last = self.k + 1, self.k + n
        self.k = last
        mode = self.fifo_mode
        fifo = self.fifo
        depth = self.fifo_depth
        # Pushed samples: k in [p0, p1), contiguous and all <= last.
        if mode == FIFO_FIFO and not self.fifo_stopped:
            p0, p1 = first, first + min(n, depth - len(fifo))
        elif mode == FIFO_STREAM:
            p0, p1 = last - min(n, depth) + 1, last + 1
        else:
            p0 = p1 = 0
        sample_fn = self.sample_fn
        if p1 > p0:
            # sample_time(k), inlined: t0 + ceil(k * 1e12 / odr).
            pushed = [sample_fn(t0 - (-k * 10**12 // odr)) for k in range(p0, p1)]
            v = pushed[-1] if p1 - 1 == last else sample_fn(t0 - (-last * 10**12 // odr))
            fifo.extend(pushed)
            while len(fifo) > depth:
                fifo.popleft()
            if len(fifo) >= depth:
                self.fifo_ovrn = True
                if mode == FIFO_FIFO:
                    self.fifo_stopped = True
        else:
            v = sample_fn(t0 - (-last * 10**12 // odr))
        self.latest = list(v)
        en = self.axes
        self.ovr |= (self.da | (0b111 if n > 1 else 0)) & en
        self.da |= en
        out, halves, bdu = self.out, self._halves, self.bdu
        if en == 0b111 and not (bdu and (halves[0] or halves[1] or halves[2])):
            out[0], out[1], out[2] = v  # the common case of the loop below
        else:
            for j in range(3):
                if en >> j & 1 and not (bdu and halves[j]):
                    out[j] = v[j]
        self.samples += n
        if self.limit == 0:
            self.stop()
        return n

    # -- registers ------------------------------------------------------------------------------

    def set_bdu(self, bdu: bool) -> None:
        self.bdu = bdu
        if not bdu:
            self._halves = [0, 0, 0]

    def set_fifo_mode(self, mode: int) -> None:
        """Select Bypass/FIFO/Stream; Bypass empties the FIFO and clears its flags."""
        if mode == FIFO_BYPASS:
            self.fifo.clear()
            self.fifo_ovrn = False
            self.fifo_stopped = False
        self.fifo_mode = mode

    def read_byte(self, i: int, big_endian: bool = False) -> int:
        """Read output byte ``i`` (0 = lowest address of the X/Y/Z block)."""
        j = i >> 1
        if self.fifo_mode != FIFO_BYPASS:
            v = self.fifo[0][j] if self.fifo else self._head[j]
        else:
            v = self.out[j]
            if self.bdu:
                h = self._halves[j] | (1 << (i & 1))
                self._halves[j] = 0 if h == 3 else h
        high = (i & 1) ^ int(big_endian)
        if high:
            mask = ~(1 << j)
            self.da &= mask
            self.ovr &= mask
        if i == 5 and self.fifo_mode != FIFO_BYPASS and self.fifo:
            self._head = self.fifo.popleft()
            if self.fifo_mode == FIFO_STREAM:
                self.fifo_ovrn = False
        return (v >> 8) & 0xFF if high else v & 0xFF

    def read_bytes(self, i0: int, count: int, big_endian: bool = False) -> bytes:
        """``count`` consecutive :meth:`read_byte` reads from byte ``i0`` (an auto-increment
        burst inside the X/Y/Z block), with exactly the same side effects.

        The whole-block read (the drivers' case) is done at once: every high byte is read, so
        all three DA/OR bits clear; the last byte pops the FIFO; with BDU each axis' half
        tracking goes through the same two steps as two single reads.
        """
        if i0 != 0 or count != 6:
            return bytes([self.read_byte(i, big_endian) for i in range(i0, i0 + count)])
        mode = self.fifo_mode
        if mode != FIFO_BYPASS:
            fifo = self.fifo
            if fifo:
                x, y, z = fifo[0]
                self._head = fifo.popleft()
                if mode == FIFO_STREAM:
                    self.fifo_ovrn = False
            else:
                x, y, z = self._head
        else:
            x, y, z = self.out
            if self.bdu:
                halves = self._halves
                for j in (0, 1, 2):
                    h = halves[j] | 1  # byte 2j (whichever half it is, the bit is 1 << 0)
                    h = 0 if h == 3 else h
                    h |= 2             # byte 2j + 1
                    halves[j] = 0 if h == 3 else h
        self.da &= ~0b111
        self.ovr &= ~0b111
        if big_endian:
            return bytes(((x >> 8) & 0xFF, x & 0xFF, (y >> 8) & 0xFF, y & 0xFF,
                          (z >> 8) & 0xFF, z & 0xFF))
        return bytes((x & 0xFF, (x >> 8) & 0xFF, y & 0xFF, (y >> 8) & 0xFF,
                      z & 0xFF, (z >> 8) & 0xFF))

    def status_byte(self) -> int:
        """STATUS layout of both parts: xyzOR in 7..4, xyzDA in 3..0 (bit 0 = X)."""
        da, ovr = self.da, self.ovr
        return (STATUS_ZYXOR if ovr else 0) | (ovr << 4) | (STATUS_ZYXDA if da else 0) | da

    def fifo_src(self, threshold: int) -> int:
        """FIFO_SRC: threshold flag, OVRN, EMPTY, FSS (see the module notes)."""
        n = len(self.fifo)
        return ((FIFO_SRC_THRESHOLD if n and n >= threshold else 0)
                | (FIFO_SRC_OVRN if self.fifo_ovrn else 0) | (FIFO_SRC_EMPTY if n == 0 else 0)
                | min(n, FIFO_SRC_FSS))


class StSpiTarget(SpiTarget):
    """ST SPI framing, faults on the wire, BOOT, and the single pending pin event.

    Subclasses provide ``regs`` (a :class:`RegisterFile` of 64 addresses), ``_service(t)``
    (bring the sample channels up to ``t``), ``_refresh_pins(t)`` (drive the interrupt pins and
    arm the next pin event), ``_fifo_wrap()`` (True while the FIFO burst wrap is active) and
    ``_power_on()`` (reset the behaviour behind the registers).
    """

    max_clock_hz: int | None = 10_000_000
    WHO_AM_I = 0x0F

    def __init__(self, kernel: Kernel, name: str, rng: np.random.Generator,
                 data_addrs: frozenset[int]) -> None:
        self.kernel = kernel
        self.name = name
        self.rng = rng
        self.faults = FaultState()
        #: the supply (FMUv2: the sensor rail switched by PE3); off, nothing drives MISO
        self.powered = True
        self._data_addrs = data_addrs
        self._cmd: int | None = None
        self._addr = 0
        #: Time of the access being served (hooks use it to restart sample grids).
        self._t = 0
        self._pin_event: Event | None = None
        #: While :meth:`_on_pin_event` drives the pins: the EXTI calls it makes at its end.
        self._hw_edges: list | None = None
        self._boot_event: Event | None = None
        self._warned: set[str] = set()
        self.regs: RegisterFile
        #: How the die sits on the board (board->sensor matrix; None: aligned).
        self.rotation: Matrix3 | None = None
        #: Output blocks a burst read serves in one call: address -> (first address of the
        #: block, last address, channel). Subclasses fill it for the registers whose read hook
        #: is their channel's ``read_byte`` (see :meth:`_burst_read`).
        self._out_blocks: dict[int, tuple[int, int, SampleChannel]] = {}

    # -- SPI hooks ------------------------------------------------------------------------------

    def _select(self, t_ns: int, mode: int, clock_hz: int) -> None:
        self._cmd = None

    def _exchange(self, t_ns: int, tx: bytes) -> bytes:
        faults = self.faults
        if faults.absent or not self.powered:
            return b"\xff" * len(tx)
        self._t = t_ns
        self._service(t_ns)
        start = 0
        if self._cmd is None and tx:
            self._cmd = tx[0]
            self._addr = tx[0] & ADDR_MASK
            start = 1
        cmd = self._cmd
        if cmd is None:
            return bytes(len(tx))
        if cmd & READ_BIT and not faults.random_data and faults.wrong_id is None:
            # Reads without data faults: the same register reads, served a block at a time.
            body = self._burst_read(len(tx) - start, cmd & MS_BIT)
            self._refresh_pins(t_ns)
            return b"\xff" + body if start else body
        out = bytearray(len(tx))
        if start:
            out[0] = 0xFF
        read, inc = cmd & READ_BIT, cmd & MS_BIT
        addr = self._addr
        for i in range(start, len(tx)):
            if read:
                out[i] = self._read(addr)
            else:
                self.regs.write(addr, tx[i])
            if inc:
                addr = OUT_FIRST if (addr == OUT_LAST and self._fifo_wrap()) else \
                    (addr + 1) & ADDR_MASK
        self._addr = addr
        self._refresh_pins(t_ns)
        return bytes(out)

    def _burst_read(self, count: int, inc: int) -> bytes:
        """``count`` data bytes of a read from ``self._addr`` (auto-incrementing if ``inc``),
        byte for byte what ``_read`` per address gives when no data fault is set.

        Runs inside an output block go to the channel's :meth:`SampleChannel.read_bytes`; the
        FIFO wrap (OUT_Z_H back to OUT_X_L) is decided once, as reads cannot change the FIFO
        mode.
        """
        addr = self._addr
        read = self.regs.read
        if not inc:
            out = bytes([read(addr) for _ in range(count)])
            return out
        blocks = self._out_blocks
        wrap = None
        big_endian = None
        parts: list[bytes] = []
        single = bytearray()
        while count > 0:
            blk = blocks.get(addr)
            if blk is None:
                single.append(read(addr))
                count -= 1
                if addr == OUT_LAST:
                    if wrap is None:
                        wrap = self._fifo_wrap()
                    addr = OUT_FIRST if wrap else (addr + 1) & ADDR_MASK
                else:
                    addr = (addr + 1) & ADDR_MASK
                continue
            if single:
                parts.append(bytes(single))
                single.clear()
            first, last, ch = blk
            k = last - addr + 1
            if k > count:
                k = count
            if big_endian is None:
                big_endian = self._big_endian()
            parts.append(ch.read_bytes(addr - first, k, big_endian))
            count -= k
            addr += k
            if addr > last:
                if last == OUT_LAST:
                    if wrap is None:
                        wrap = self._fifo_wrap()
                    addr = OUT_FIRST if wrap else addr & ADDR_MASK
                else:
                    addr &= ADDR_MASK
        self._addr = addr
        if single:
            parts.append(bytes(single))
        return b"".join(parts)

    def _big_endian(self) -> bool:
        """Byte order of the output blocks (L3GD20 CTRL_REG4.BLE); little-endian by default."""
        return False

    def _read(self, addr: int) -> int:
        faults = self.faults
        if addr == self.WHO_AM_I and faults.wrong_id is not None:
            return faults.wrong_id & 0xFF
        value = self.regs.read(addr)
        if faults.random_data and addr in self._data_addrs:
            return int(self.rng.integers(0, 256))
        return value

    # -- physics --------------------------------------------------------------------------------

    def _faulted(self, last: Raw3 | None, hold: bool = False) -> Raw3 | None:
        """The sample the faults make, if they make it: the last one while frozen (or while
        ``hold``: a sensing element that is off), the rails while saturated; None: measure."""
        faults = self.faults
        if (faults.frozen or hold) and last is not None:
            return last
        if faults.saturate:
            return RAILS
        return None

    def _sense(self, err: ImuErrorModel, kind: str, truth: Vec3, t_ns: int, rate_hz: float,
               temperature_c: float) -> Vec3:
        """What one sensing element reads before quantisation, in SI units: ``truth`` (board
        axes) in the die's axes, through its error model with the faults' bias step and the
        extra noise they set for ``kind`` (``"gyro"``, ``"accel"``, ``"mag"``)."""
        faults = self.faults
        err.extra_bias = faults.bias_step
        nz = faults.noise
        err.extra_sigma = nz.get(kind, 0.0) if nz else 0.0
        rot = self.rotation
        return err.apply(t_ns, truth if rot is None else rotate(rot, truth), rate_hz,
                         temperature_c)

    # -- timing helpers -------------------------------------------------------------------------

    def _arm(self, t_ns: int | None) -> None:
        """Keep exactly one pending pin event, at ``t_ns`` (None: none needed)."""
        ev = self._pin_event
        if ev is not None:
            if t_ns == Kernel.due_ns(ev) and Kernel.pending(ev):
                return
            Kernel.cancel(ev)
            self._pin_event = None
        if t_ns is not None:
            self._pin_event = self.kernel.call_at(t_ns, self._on_pin_event, priority=PRIO_HW)

    def _on_pin_event(self) -> None:
        """A sample that can move a pin is due. Its edges are made here, in a hardware event
        at its own time, so their EXTI handlers run in this event once the pins are settled
        (``Pin._apply(defer=...)``: same edge time and interrupt context, one kernel event
        fewer per data-ready edge)."""
        self._pin_event = None
        t = self.kernel.now_ns
        self._t = t
        self._service(t)
        fire = self._hw_edges = []
        try:
            self._refresh_pins(t)
        finally:
            self._hw_edges = None
        for line, pin, t_edge in fire:  # after the chip's state is complete: ISRs may read it
            pin._gpio._fire(line, pin, t_edge)

    def _warn_once(self, key: str, text: str) -> None:
        """Log a setting the datasheet calls reserved, once per kind (the chip just obeys)."""
        if key not in self._warned:
            self._warned.add(key)
            log.warning("%s: %s", self.name, text)

    def _select_fifo_mode(self, ch: SampleChannel, fm: int, enabled: bool) -> None:
        """The FM field and the FIFO enable bit select ``ch``'s FIFO mode (:data:`FM_MODES`); a
        reserved FM leaves the FIFO bypassed, logged once."""
        if fm not in FM_MODES:
            self._warn_once("fm", f"reserved FIFO mode FM={fm:03b}: FIFO stays bypassed")
        ch.set_fifo_mode(FM_MODES.get(fm, FIFO_BYPASS) if enabled else FIFO_BYPASS)

    def _set_pin(self, pin: Pin, level: int, t_ns: int) -> None:
        if pin.level != level or not pin.driven:
            now = self.kernel.now_ns
            edges = self._hw_edges
            if edges is not None and t_ns <= now:
                pin._apply(level, now, edges)  # our own event: the handler runs at its end
                return
            # high()/low() rather than set(): the level is known to be 0 or 1.
            (pin.high if level else pin.low)(t_ns if t_ns > now else now)

    def _start_boot(self) -> None:
        if self._boot_event is None:
            self._boot_event = self.kernel.call_at(self._t + BOOT_NS, self._boot_done,
                                                   priority=PRIO_HW)

    def _boot_done(self) -> None:
        self._boot_event = None
        self.reset()

    def set_power(self, on: bool) -> None:
        """The supply rail: off, the chip stops (no samples, no pin events, MISO left to its
        pull-up); on is a power-on reset (registers to their reset values, BOOT done)."""
        if on and not self.powered:
            self.powered = True
            self.reset()
        elif not on and self.powered:
            self.powered = False
            self._arm(None)
            Kernel.cancel(self._boot_event)
            self._boot_event = None

    def reset(self) -> None:
        """Power-on reset (sensor rail cycled, or the end of a BOOT sequence)."""
        t = self.kernel.now_ns
        self._t = t
        Kernel.cancel(self._boot_event)
        self._boot_event = None
        self.regs.reset()
        self._power_on()
        self._refresh_pins(t)

    # -- subclass hooks -------------------------------------------------------------------------

    def _service(self, t_ns: int) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _refresh_pins(self, t_ns: int) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _fifo_wrap(self) -> bool:  # pragma: no cover - abstract
        raise NotImplementedError

    def _power_on(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError
