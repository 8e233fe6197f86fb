"""I2C bus: ACK/NAK results, repeated start, smbus2/MicroPython wrappers, exact clock timing."""

from __future__ import annotations

import errno

import pytest

from board.i2c import I2cBus, I2cTarget
from board.kernel import Kernel


class RegDevice(I2cTarget):
    """First written byte is the register pointer; reads auto-increment."""

    def __init__(self, nak_after: int | None = None) -> None:
        self.regs = bytearray(range(256))
        self.ptr = 0
        self.nak_after = nak_after
        self.log: list[tuple] = []

    def _start(self, t_ns, is_read):
        self.log.append(("start", t_ns, is_read))
        return True

    def _write(self, t_ns, data):
        self.log.append(("write", t_ns, bytes(data)))
        n = len(data) if self.nak_after is None else min(len(data), self.nak_after)
        self.ptr = data[0]
        for i, b in enumerate(data[1:n]):
            self.regs[(self.ptr + i) & 0xFF] = b
        return n

    def _read(self, t_ns, n):
        self.log.append(("read", t_ns, n))
        out = bytes(self.regs[(self.ptr + i) & 0xFF] for i in range(n))
        self.ptr = (self.ptr + n) & 0xFF
        return out

    def _stop(self, t_ns):
        self.log.append(("stop", t_ns))


@pytest.fixture
def kernel() -> Kernel:
    return Kernel("fmu")


def test_absent_address_naks_with_eio_and_takes_11_clocks(kernel):
    bus = I2cBus(kernel, "i2c1", clock_hz=100_000)
    assert bus.transfer(0x1E, b"\x0a", 3) == (-errno.EIO, b"")
    assert kernel.busy_ns == 110_000  # START + address + STOP
    assert bus.nak_count == 1 and bus.addr_nak_count == 1


def test_smbus_wrappers_raise_oserror_eio_on_nak(kernel):
    bus = I2cBus(kernel, "i2c1")
    with pytest.raises(OSError) as info:
        bus.read_byte_data(0x1E, 0x0A)
    assert info.value.errno == errno.EIO
    assert "0x1e" in str(info.value)
    with pytest.raises(OSError):
        bus.readfrom_mem(0x50, 0, 4)
    with pytest.raises(OSError):
        bus.device(0x1E).write_byte_data(0, 0)
    assert bus.nak_count == 3


def test_write_then_read_uses_repeated_start_at_exact_times_100khz(kernel):
    bus = I2cBus(kernel, "i2c1", clock_hz=100_000)
    dev = RegDevice()
    bus.attach(0x1E, dev)
    kernel.run(1_000)
    assert bus.read_byte_data(0x1E, 0x0A) == 0x0A
    # START 1 + addr 9 + reg 9 + Sr 1 + addr 9 + data 9 + STOP 1 = 39 clocks of 10 us
    assert kernel.busy_ns == 390_000
    assert dev.log == [
        ("start", 1_000, False),
        ("write", 1_000 + 100_000, b"\x0a"),
        ("start", 1_000 + 190_000, True),
        ("read", 1_000 + 290_000, 1),
        ("stop", 1_000 + 380_000),
    ]


def test_exact_durations_400khz(kernel):
    bus = I2cBus(kernel, "i2c1", clock_hz=400_000)
    bus.attach(0x1E, RegDevice())
    assert bus.read_i2c_block_data(0x1E, 3, 6) == [3, 4, 5, 6, 7, 8]
    clocks = 1 + 9 + 9 + 1 + 9 + 6 * 9 + 1  # 84
    assert kernel.busy_ns == clocks * 2_500
    kernel.busy_ns = 0
    bus.write_byte_data(0x1E, 0x00, 0x70)  # START + addr + 2 bytes + STOP = 29 clocks
    assert kernel.busy_ns == 72_500
    kernel.busy_ns = 0
    assert bus.readfrom(0x1E, 2) == b"\x70\x01"  # pointer left at reg 0
    assert kernel.busy_ns == (1 + 9 + 18 + 1) * 2_500


def test_data_nak_ends_transfer_after_that_byte(kernel):
    bus = I2cBus(kernel, "i2c1", clock_hz=100_000)
    dev = RegDevice(nak_after=1)
    bus.attach(0x50, dev)
    status, data = bus.transfer(0x50, b"\x10\x11\x12", 0)
    assert (status, data) == (-errno.EIO, b"")
    assert kernel.busy_ns == (1 + 9 + 9 * 2 + 1) * 10_000  # address, 1 ACKed + 1 NAKed, STOP
    assert bus.data_nak_count == 1
    with pytest.raises(OSError):
        bus.writeto_mem(0x50, 0x10, b"\x01")


def test_micropython_mem_access_and_16bit_memaddr(kernel):
    bus = I2cBus(kernel, "i2c1")
    dev = RegDevice()
    bus.attach(0x1E, dev)
    bus.writeto_mem(0x1E, 0x20, b"\xaa\xbb")
    assert bus.readfrom_mem(0x1E, 0x20, 2) == b"\xaa\xbb"
    buf = bytearray(2)
    bus.readfrom_mem_into(0x1E, 0x20, buf)
    assert buf == b"\xaa\xbb"
    assert bus.writeto(0x1E, b"\x21\xcc") == 2
    assert bus.device(0x1E).readfrom_mem(0x20, 2) == b"\xaa\xcc"
    bus.transfer(0x1E, b"", 0)
    assert dev.log[-2:] == [("start", dev.log[-2][1], False), ("stop", dev.log[-1][1])]
    with pytest.raises(ValueError, match="does not fit 8 bits"):
        bus.readfrom_mem(0x1E, 0x100, 1)


def test_scan_and_quick_write(kernel):
    bus = I2cBus(kernel, "i2c1")
    bus.attach(0x1E, RegDevice())
    bus.attach(0x77, RegDevice())
    assert bus.scan() == [0x1E, 0x77]
    bus.write_quick(0x1E)


def test_target_that_naks_its_address(kernel):
    class Busy(I2cTarget):
        def _start(self, t_ns, is_read):
            return False

    bus = I2cBus(kernel, "i2c1")
    bus.attach(0x40, Busy())
    assert bus.transfer(0x40, b"", 1)[0] == -errno.EIO


def test_attach_rejects_bad_and_reserved_addresses(kernel):
    bus = I2cBus(kernel, "i2c1")
    for addr in (0x00, 0x07, 0x78, 0x7F):
        with pytest.raises(ValueError, match="reserved"):
            bus.attach(addr, RegDevice())
    with pytest.raises(ValueError, match="7-bit"):
        bus.attach(0x80, RegDevice())
    bus.attach(0x1E, RegDevice())
    with pytest.raises(ValueError, match="already taken"):
        bus.attach(0x1E, RegDevice())
    with pytest.raises(ValueError, match="1..32"):
        bus.read_i2c_block_data(0x1E, 0, 33)
    with pytest.raises(ValueError, match="register must be an int 0..255"):
        bus.read_byte_data(0x1E, 256)
