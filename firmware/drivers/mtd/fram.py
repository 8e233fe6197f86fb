"""FRAM MTD driver: the Ramtron/Cypress FM25Vxx on SPI2 as a flat byte device with partitions.

What NuttX's ``ramtron`` driver plus PX4's ``mtd start`` give the parameter system on FMUv2
(reference sheet 6.6 and 9.2): probe by RDID, reads as ``03 AH AL`` + data in one chip-select
window, writes as WREN (own window) then ``02 AH AL`` + up to ``WRITE_CHUNK`` bytes, repeated,
and two equal partitions: ``params`` (0x0000-0x1FFF on the 16 KiB part) and ``waypoints``
(0x2000-0x3FFF).

Errors are results, not exceptions: ``read`` returns None and ``write`` False, with the reason
in dmesg and the error perf counter, because the caller (parameter save at shutdown, dataman)
must carry on either way. Before each read and write the status register is checked: a missing
chip reads 0xFF (reserved bits set), and a write into a block-protected range is refused up
front instead of being silently dropped by the chip. ``write(..., verify=True)`` reads back.
Misuse (an unknown partition name) raises, since that is a bug in the caller.
"""

from __future__ import annotations

from typing import Final

from board.spi import SpiHandle
from firmware.platform import Platform
from firmware.platform.perf import PC_COUNT, PC_ELAPSED

__all__ = ["DENSITY_BYTES", "FramMtd", "FramPartition"]

OP_WREN: Final = 0x06
OP_RDSR: Final = 0x05
OP_WRSR: Final = 0x01
OP_READ: Final = 0x03
OP_WRITE: Final = 0x02
OP_RDID: Final = 0x9F
SR_WPEN: Final = 0x80
SR_WEL: Final = 0x02
SR_BP_MASK: Final = 0x0C
SR_BP_SHIFT: Final = 2
SR_RESERVED: Final = 0x71
RDID_FILLER: Final = 0xA5           # what NuttX clocks out while reading the ID
MANUFACTURER_CYPRESS: Final = 0xC2
#: RDID family/density byte -> capacity (FM25V01, V02, V05, V10).
DENSITY_BYTES: Final = {0x21: 16 * 1024, 0x22: 32 * 1024, 0x23: 64 * 1024, 0x24: 128 * 1024}
WRITE_CHUNK: Final = 32             # NuttX's emulated block size (RAMTRON_EMULATE_PAGE_SHIFT = 5)
CLOCK_HZ: Final = 40_000_000


class FramPartition:
    """A window of the FRAM (PX4's ``/fs/mtd_params``): offsets are relative to its start."""

    def __init__(self, mtd: FramMtd, name: str, offset: int, size: int) -> None:
        self.mtd = mtd
        self.name = name
        self.offset = offset
        self.size = size

    def _inside(self, off: int, n: int, what: str) -> bool:
        if type(off) is not int or type(n) is not int or off < 0 or n < 0 or off + n > self.size:
            self.mtd._fail(f"{what} of {n!r} bytes at {off!r} outside partition {self.name} "
                           f"(size {self.size})")
            return False
        return True

    def read(self, off: int, n: int) -> bytes | None:
        """``n`` bytes from ``off``, or None (reason in dmesg)."""
        if not self._inside(off, n, "read"):
            return None
        return self.mtd.read(self.offset + off, n)

    def write(self, off: int, data: bytes, verify: bool = False) -> bool:
        """Write ``data`` at ``off``; False on failure (reason in dmesg)."""
        if not self._inside(off, len(data), "write"):
            return False
        return self.mtd.write(self.offset + off, data, verify=verify)

    def __repr__(self) -> str:
        return f"<FramPartition {self.name} 0x{self.offset:04X}+0x{self.size:04X}>"


class FramMtd:
    """The FRAM behind ``spi`` (SPI mode 3, 40 MHz requested)."""

    def __init__(self, platform: Platform, spi: SpiHandle, name: str = "fram") -> None:
        self.platform = platform
        self.spi = spi
        self.name = name
        self.size = 0
        self.device_id = b""
        self.running = False
        self.partitions: dict[str, FramPartition] = {}
        perf = platform.perf
        self.perf_read = perf.alloc(PC_ELAPSED, f"{name}: read")
        self.perf_write = perf.alloc(PC_ELAPSED, f"{name}: write")
        self.perf_errors = perf.alloc(PC_COUNT, f"{name}: errors")
        #: the counters above, for the shell module that owns them (freed at ``mtd stop``)
        self.own_perf = [self.perf_read, self.perf_write, self.perf_errors]
        self.bytes_read = 0
        self.bytes_written = 0

    # -- life cycle -----------------------------------------------------------------------

    def probe(self) -> str | None:
        """Read the ID; None if it is a supported FM25Vxx, else the reason."""
        self.spi.mode = 3
        self.spi.max_speed_hz = CLOCK_HZ
        ident = self.spi.transfer(bytes((OP_RDID,)) + bytes((RDID_FILLER,)) * 9)[1:]
        if ident == b"\xff" * 9:
            return "RDID reads all 0xFF (no device answering)"
        if ident[:6] != b"\x7f" * 6 or ident[6] != MANUFACTURER_CYPRESS:
            return (f"RDID {ident.hex(' ')}: not a Cypress/Ramtron FRAM (expected six 7F "
                    f"continuation codes then C2)")
        size = DENSITY_BYTES.get(ident[7])
        if size is None:
            return f"RDID {ident.hex(' ')}: unknown density code 0x{ident[7]:02X}"
        self.device_id = bytes(ident)
        self.size = size
        return None

    def start(self) -> bool:
        """Probe and set up the partitions; False (reason in dmesg) if the chip is wrong."""
        if self.running:
            return True
        why = self.probe()
        if why is not None:
            self._fail(f"not starting: {why}")
            return False
        half = self.size // 2
        self.partitions = {"params": FramPartition(self, "params", 0, half),
                           "waypoints": FramPartition(self, "waypoints", half, half)}
        self.running = True
        self.platform.info(self.name, f"FM25V {self.size // 1024} KiB (ID "
                                      f"{self.device_id.hex(' ')}), partitions params "
                                      f"0x0000-0x{half - 1:04X}, waypoints "
                                      f"0x{half:04X}-0x{self.size - 1:04X}")
        return True

    def partition(self, name: str) -> FramPartition:
        """The partition ``params`` or ``waypoints`` (after :meth:`start`)."""
        try:
            return self.partitions[name]
        except KeyError:
            raise KeyError(f"{self.name}: no partition {name!r} (have: "
                           f"{', '.join(self.partitions) or 'none, not started'})") from None

    # -- status register ------------------------------------------------------------------

    def _fail(self, text: str) -> None:
        self.perf_errors.count()
        self.platform.error(self.name, text)

    def read_status(self) -> int | None:
        """The status register, or None if it cannot be real (reserved bits set: no chip)."""
        sr = self.spi.transfer(bytes((OP_RDSR, 0)))[1]
        if sr & SR_RESERVED:
            self._fail(f"status register reads 0x{sr:02X} (reserved bits set: device absent?)")
            return None
        return sr

    def protected_range(self, sr: int) -> range:
        """Addresses protected by the BP bits of status value ``sr``."""
        bp = (sr & SR_BP_MASK) >> 2
        return range((self.size, self.size - self.size // 4, self.size // 2, 0)[bp], self.size)

    def set_block_protect(self, bp: int, wpen: bool = False) -> bool:
        """Write BP1:BP0 (0 none, 1 upper quarter, 2 upper half, 3 all) and WPEN; verified."""
        if not 0 <= bp <= 3:
            raise ValueError(f"{self.name}: block protect must be 0..3, got {bp!r}")
        if not self._ready("set_block_protect"):
            return False
        value = (bp << SR_BP_SHIFT) | (SR_WPEN if wpen else 0)
        self.spi.transfer(bytes((OP_WREN,)))
        self.spi.transfer(bytes((OP_WRSR, value)))
        sr = self.read_status()
        if sr is None or sr & (SR_WPEN | SR_BP_MASK) != value:
            self._fail(f"status write 0x{value:02X} did not stick (reads "
                       f"{'?' if sr is None else f'0x{sr:02X}'}; /WP low with WPEN set?)")
            return False
        return True

    # -- data -----------------------------------------------------------------------------

    def _ready(self, what: str) -> bool:
        if not self.running:
            self._fail(f"{what}: driver not started")
            return False
        return True

    def _bounds(self, addr: int, n: int, what: str) -> bool:
        if type(addr) is not int or type(n) is not int or addr < 0 or n < 0 \
                or addr + n > self.size:
            self._fail(f"{what} of {n!r} bytes at {addr!r} outside the device (0..{self.size})")
            return False
        return True

    def read(self, addr: int, n: int) -> bytes | None:
        """``n`` bytes from ``addr`` in one chip-select window; None on failure."""
        if not (self._ready("read") and self._bounds(addr, n, "read")):
            return None
        if n == 0:
            return b""
        self.perf_read.begin()
        if self.read_status() is None:
            self.perf_read.cancel()
            return None
        rx = self.spi.transfer(bytes((OP_READ, addr >> 8, addr & 0xFF)) + bytes(n))
        self.perf_read.end()
        self.bytes_read += n
        return rx[3:]

    def write(self, addr: int, data: bytes, verify: bool = False) -> bool:
        """Write ``data`` at ``addr``: WREN + WRITE per chunk of ``WRITE_CHUNK`` bytes."""
        data = bytes(data)
        if not (self._ready("write") and self._bounds(addr, len(data), "write")):
            return False
        if not data:
            return True
        self.perf_write.begin()
        sr = self.read_status()
        if sr is None:
            self.perf_write.cancel()
            return False
        prot = self.protected_range(sr)
        if prot and addr < prot.stop and addr + len(data) > prot.start:
            self.perf_write.cancel()
            self._fail(f"write 0x{addr:04X}+{len(data)} hits block-protected range "
                       f"0x{prot.start:04X}-0x{prot.stop - 1:04X} (BP = {(sr >> 2) & 3})")
            return False
        for off in range(0, len(data), WRITE_CHUNK):
            a = addr + off
            self.spi.transfer(bytes((OP_WREN,)))
            if off == 0:
                sr = self.read_status()
                if sr is None or not sr & SR_WEL:
                    self.perf_write.cancel()
                    if sr is not None:
                        self._fail("write enable latch did not set after WREN")
                    return False
            self.spi.transfer(bytes((OP_WRITE, a >> 8, a & 0xFF)) + data[off:off + WRITE_CHUNK])
        self.perf_write.end()
        self.bytes_written += len(data)
        if verify:
            back = self.read(addr, len(data))
            if back != data:
                if back is not None:
                    bad = next(i for i in range(len(data)) if back[i] != data[i])
                    self._fail(f"verify failed at 0x{addr + bad:04X}: wrote 0x{data[bad]:02X}, "
                               f"read 0x{back[bad]:02X}")
                return False
        return True

    def status(self) -> str:
        lines = [(f"{self.name}: {'running' if self.running else 'stopped'}, {self.size} bytes, "
                 f"{self.bytes_read} read, {self.bytes_written} written")]
        lines += ["  " + pc.summary() for pc in (self.perf_read, self.perf_write,
                                                 self.perf_errors)]
        lines += [f"  {p!r}" for p in self.partitions.values()]
        return "\n".join(lines)
