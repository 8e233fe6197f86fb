"""SPI throughput: MPU6000-style 14-byte burst reads through the emulated bus per second.

The sensor driver reads ACCEL_XOUT_H..GYRO_ZOUT_L (14 bytes from 0x3B, command byte 0xBB)
8000 times a virtual second, so this figure bounds how fast the whole board can run. The target
is a trivial register file answering a ``0x80 | addr`` burst with auto-increment, so the number
measures the bus, not a sensor model.
"""

from __future__ import annotations

from bench._util import median_rate
from board.kernel import Kernel
from board.spi import SpiBus, SpiTarget

N_TRANSFERS = 50_000


class BurstRegisters(SpiTarget):
    """128 registers; the first byte is ``R/W | addr``, reads auto-increment."""

    max_clock_hz = 20_000_000

    def __init__(self) -> None:
        self.regs = bytearray(range(128))

    def _exchange(self, t_ns: int, tx: bytes) -> bytes:
        addr = tx[0] & 0x7F
        if tx[0] & 0x80:
            data = bytes(self.regs[addr:addr + len(tx) - 1])
            return b"\x00" + data + b"\x00" * (len(tx) - 1 - len(data))
        self.regs[addr:addr + len(tx) - 1] = tx[1:]
        return b"\x00" * len(tx)


def _run() -> int:
    kernel = Kernel("bench")
    bus = SpiBus(kernel, "spi1")
    bus.attach("mpu", BurstRegisters())
    transfer = bus.device("mpu", mode=3, clock_hz=20_000_000).transfer
    tx = bytes((0x80 | 0x3B,)) + bytes(14)  # command + 14 data bytes
    for _ in range(N_TRANSFERS):
        transfer(tx)
    return N_TRANSFERS


def bench_spi_14byte_transfers_per_s() -> float:
    """Median over 5 runs of 14-byte burst reads per wall-clock second."""
    return median_rate(_run)


if __name__ == "__main__":
    print(f"spi_14byte_transfers_per_s: {bench_spi_14byte_transfers_per_s():,.0f}")
