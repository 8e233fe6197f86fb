"""Cypress (Ramtron) FM25V01 128-Kbit SPI FRAM, with its contents kept in a host file.

Protocol (reference sheet 6.3/6.4): one opcode per chip-select window, then address / data
bytes for as long as the clock runs. Each byte is written as it is clocked in (no page buffer,
no busy bit). What the model enforces, because a driver that gets it wrong on the real part
silently loses writes:

* WRITE and WRSR are ignored unless the write enable latch (WEL) is set; WEL is set by WREN,
  cleared by WRDI, at power-up, and when CS rises at the end of a WRITE or WRSR.
* Writes into the range protected by BP1:BP0 are ignored (the bytes are still consumed).
* With /WP low and WPEN = 1, WRSR is ignored.
* Addresses are 2 bytes, the top bits don't care; sequential access wraps at the end.
* SLEEP takes effect when CS rises; the next CS fall wakes the part, which ignores the bus for
  the recovery time (400 us, datasheet tREC) and answers 0xFF meanwhile.
* Unknown opcodes are ignored until CS rises. Above 40 MHz the part cannot follow the clock.

Persistence: the array lives in ``path`` (a raw image, byte n = FRAM address n), read at
construction and written through with ``os.pwrite`` for every byte run a WRITE changes, so a
crash of the host process loses nothing that was written. A missing file starts as virgin
memory (all 0xFF: PX4 reads that as "no parameters", reference 9.3); a short file is padded
with 0xFF without touching what it holds; a longer one is used as is. The non-volatile status
bits (WPEN, BP1:BP0) live in a one-byte sidecar ``<path>.sr``. Without a path the memory is
volatile (tests).
"""

from __future__ import annotations

import logging
import os
import random
import weakref

from board.gpio import Pin
from board.kernel import NS_PER_US, Kernel
from board.spi import SpiTarget
from peripherals.faults import FaultState

__all__ = [
    "OP_FSTRD",
    "OP_RDID",
    "OP_RDSR",
    "OP_READ",
    "OP_SLEEP",
    "OP_WRDI",
    "OP_WREN",
    "OP_WRITE",
    "OP_WRSR",
    "RDID_FM25V01",
    "SR_BP_SHIFT",
    "SR_WEL",
    "SR_WPEN",
    "Fm25v01",
]

log = logging.getLogger(__name__)

OP_WREN, OP_WRDI, OP_RDSR, OP_WRSR = 0x06, 0x04, 0x05, 0x01
OP_READ, OP_FSTRD, OP_WRITE = 0x03, 0x0B, 0x02
OP_SLEEP, OP_RDID = 0xB9, 0x9F

SR_WPEN = 0x80
SR_BP_SHIFT = 2
SR_BP_MASK = 0x0C
SR_WEL = 0x02
_SR_NONVOLATILE = SR_WPEN | SR_BP_MASK

#: RDID answer: six JEDEC continuation codes, Cypress/Ramtron, family/density 0x21, sub-type.
RDID_FM25V01 = bytes((0x7F,) * 6 + (0xC2, 0x21, 0x00))
WAKE_NS = 400 * NS_PER_US


def _close_fd(fd: int) -> None:
    try:
        os.close(fd)
    except OSError:
        pass


class Fm25v01(SpiTarget):
    """The FRAM on an SPI chip select (SPI2 / PD10 on FMUv2).

    ``wp_pin`` (optional) is the /WP input; unconnected it reads high (not protected).
    Faults: ``absent`` (MISO high, nothing decoded), ``wrong_id`` (RDID byte 7 = this value),
    ``frozen`` (writes do not stick: a worn-out or failing array), ``random_data`` (reads
    return noise).
    """

    def __init__(self, kernel: Kernel, name: str = "fram", path: str | os.PathLike | None = None,
                 size: int = 16384, wp_pin: Pin | None = None) -> None:
        if type(size) is not int or size < 256 or size & (size - 1):
            raise ValueError(f"{name}: size must be a power of two >= 256 bytes, got {size!r}")
        # Set on the instance: the compiled SpiTarget reads its own declared default (None, no
        # limit) and would not see a class attribute of this ordinary module.
        self.max_clock_hz = 40_000_000
        self.kernel = kernel
        self.name = name
        self.size = size
        self.wp_pin = wp_pin
        self.path = None if path is None else os.fspath(path)
        self.faults = FaultState()
        self.mem = bytearray(b"\xff" * size)
        self.status = 0x00
        self.asleep = False
        self.bytes_written = 0
        self.ignored_writes = 0
        self._fd: int | None = None
        self._release: weakref.finalize | None = None
        self._awake_at_ns = 0
        self._noise = random.Random(f"{name}:noise")
        self._op: int | None = None
        self._n = 0               # bytes of this window after the opcode
        self._addr = 0
        self._wrote_data = False
        self._sleep_pending = False
        self._warned: set[int] = set()
        if self.path is not None:
            self._open()

    # -- host file ------------------------------------------------------------------------

    def _open(self) -> None:
        assert self.path is not None
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        self._fd = fd
        # One release of the descriptor, by close() or by the collector, never both: a second
        # os.close of the same number would close whatever file has reused it since.
        self._release = weakref.finalize(self, _close_fd, fd)
        have = os.pread(fd, self.size, 0)
        self.mem[:len(have)] = have
        if len(have) < self.size:
            # Pad the image so it is complete on disk; what was saved stays where it was.
            os.pwrite(fd, b"\xff" * (self.size - len(have)), len(have))
        try:
            with open(self.path + ".sr", "rb") as f:
                sr = f.read(1)
            if sr:
                self.status = sr[0] & _SR_NONVOLATILE
        except FileNotFoundError:
            pass

    def _persist(self, addr: int, data: bytes) -> None:
        if self._fd is not None and data:
            os.pwrite(self._fd, data, addr)

    def _persist_status(self) -> None:
        if self.path is not None:
            with open(self.path + ".sr", "wb") as f:
                f.write(bytes((self.status & _SR_NONVOLATILE,)))

    def close(self) -> None:
        """Flush the image to disk and release the file (the model stays readable)."""
        if self._fd is not None:
            os.fsync(self._fd)
            self._fd = None
        if self._release is not None:
            self._release()       # closes the descriptor once; later calls do nothing
            self._release = None

    # -- helpers --------------------------------------------------------------------------

    @property
    def wel(self) -> bool:
        return bool(self.status & SR_WEL)

    def protected_range(self) -> range:
        """Addresses BP1:BP0 protect: none, upper quarter, upper half, all."""
        bp = (self.status & SR_BP_MASK) >> SR_BP_SHIFT
        start = (self.size, self.size - self.size // 4, self.size // 2, 0)[bp]
        return range(start, self.size)

    def power_cycle(self) -> None:
        """Supply off and on: WEL and sleep cleared; the array and BP/WPEN are non-volatile."""
        self.status &= _SR_NONVOLATILE
        self.asleep = False
        self._sleep_pending = False

    # -- SPI hooks ------------------------------------------------------------------------

    def _select(self, t_ns: int, mode: int, clock_hz: int) -> None:
        self._op = None
        self._n = 0
        self._wrote_data = False
        if self.asleep:
            self.asleep = False
            self._awake_at_ns = t_ns + WAKE_NS

    def _deselect(self, t_ns: int) -> None:
        if self._op in (OP_WRITE, OP_WRSR) and not self.faults.absent:
            self.status &= ~SR_WEL
        if self._sleep_pending:
            self._sleep_pending = False
            self.asleep = True

    def _exchange(self, t_ns: int, tx: bytes) -> bytes:
        if self.faults.absent:
            return b"\xff" * len(tx)
        byte_ns = 8_000_000_000 // max(self.clock_hz, 1)
        rx = bytearray(b"\xff" * len(tx))
        write_start = -1
        write_buf = bytearray()
        for i, b in enumerate(tx):
            if self._op is None:
                if t_ns + i * byte_ns < self._awake_at_ns:
                    continue  # still waking: the byte is not decoded
                self._op = b
                self._opcode(b)
                continue
            op = self._op
            n = self._n
            self._n = n + 1
            if op in (OP_READ, OP_FSTRD, OP_WRITE):
                data_from = 2 if op != OP_FSTRD else 3
                if n < 2:
                    self._addr = ((self._addr << 8) | b) & (self.size - 1)
                    continue
                if n < data_from:
                    continue  # FSTRD dummy byte
                if op != OP_WRITE and not self.faults.random_data:
                    # Bulk read of the rest of this segment (wrapping at the end).
                    count = len(tx) - i
                    self._n = n + count
                    a = self._addr
                    mem = self.mem
                    chunk = bytearray()
                    while len(chunk) < count:
                        take = min(count - len(chunk), self.size - a)
                        chunk += mem[a:a + take]
                        a = (a + take) & (self.size - 1)
                    self._addr = a
                    rx[i:] = chunk
                    break
                a = self._addr
                self._addr = (a + 1) & (self.size - 1)
                if op == OP_WRITE:
                    if self._write_byte(a, b):
                        if write_start >= 0 and write_start + len(write_buf) != a:
                            self._persist(write_start, bytes(write_buf))
                            write_buf.clear()
                        if not write_buf:
                            write_start = a
                        write_buf.append(b)
                else:
                    rx[i] = self._read_byte(a)
            elif op == OP_RDSR:
                rx[i] = self.status
            elif op == OP_RDID:
                ident = bytearray(RDID_FM25V01)
                if self.faults.wrong_id is not None:
                    ident[6] = self.faults.wrong_id & 0xFF
                if n < len(ident):
                    rx[i] = ident[n]
            elif op == OP_WRSR and n == 0:
                self._write_status(b)
        if write_buf:
            self._persist(write_start, bytes(write_buf))
        return bytes(rx)

    def _opcode(self, op: int) -> None:
        if op == OP_WREN:
            if not self.faults.write_fail:  # a failed write-enable circuit: WEL never sets
                self.status |= SR_WEL
        elif op == OP_WRDI:
            self.status &= ~SR_WEL
        elif op == OP_SLEEP:
            self._sleep_pending = True
        elif op in (OP_RDSR, OP_WRSR, OP_READ, OP_FSTRD, OP_WRITE, OP_RDID):
            self._addr = 0
        elif op not in self._warned:
            self._warned.add(op)
            log.warning("%s: unknown opcode 0x%02X ignored until CS rises", self.name, op)

    def _write_status(self, value: int) -> None:
        if not self.wel:
            self.ignored_writes += 1
            return
        wp_low = self.wp_pin is not None and self.wp_pin.level == 0
        if wp_low and self.status & SR_WPEN:
            self.ignored_writes += 1
            return
        self.status = (self.status & SR_WEL) | (value & _SR_NONVOLATILE)
        self._persist_status()

    def _write_byte(self, addr: int, value: int) -> bool:
        """One data byte of a WRITE; True if the array changed (to be written through)."""
        if not self.wel or addr in self.protected_range():
            self.ignored_writes += 1
            return False
        if self.faults.frozen:
            return False
        self.bytes_written += 1
        self.mem[addr] = value
        return True

    def _read_byte(self, addr: int) -> int:
        if self.faults.random_data:
            return self._noise.randrange(256)
        return self.mem[addr]

    def __repr__(self) -> str:
        return f"<Fm25v01 {self.name} {self.size} bytes {self.path or '(volatile)'}>"
