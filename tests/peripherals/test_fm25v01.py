"""FM25V01 FRAM model: every opcode, the write enable latch, protection, sleep, persistence."""

from __future__ import annotations

import os

import pytest

from board.gpio import Gpio
from board.kernel import Kernel
from board.spi import SpiBus
from peripherals.fm25v01 import RDID_FM25V01, Fm25v01

SIZE = 16384


@pytest.fixture
def bus(kernel: Kernel) -> SpiBus:
    return SpiBus(kernel, "spi2")


def attach(bus: SpiBus, chip: Fm25v01):
    bus.attach("PD10", chip)
    return bus.device("PD10", mode=3, clock_hz=20_000_000)


@pytest.fixture
def chip(kernel: Kernel) -> Fm25v01:
    return Fm25v01(kernel)


@pytest.fixture
def dev(bus, chip):
    return attach(bus, chip)


def rdsr(dev) -> int:
    return dev.transfer(b"\x05\x00")[1]


def write(dev, addr: int, data: bytes, wren: bool = True) -> None:
    if wren:
        dev.transfer(b"\x06")
    dev.transfer(bytes((0x02, addr >> 8, addr & 0xFF)) + data)


def read(dev, addr: int, n: int) -> bytes:
    return dev.transfer(bytes((0x03, addr >> 8, addr & 0xFF)) + bytes(n))[3:]


def test_virgin_memory_is_ff_and_status_zero(dev):
    assert read(dev, 0, 16) == b"\xff" * 16
    assert rdsr(dev) == 0x00


def test_rdid(dev):
    assert dev.transfer(b"\x9f" + b"\xa5" * 9)[1:] == RDID_FM25V01
    assert RDID_FM25V01 == bytes.fromhex("7f7f7f7f7f7fc22100")


def test_wren_wrdi_and_wel_cleared_at_cs_rise_after_write(dev):
    dev.transfer(b"\x06")
    assert rdsr(dev) == 0x02
    dev.transfer(b"\x04")
    assert rdsr(dev) == 0x00
    write(dev, 0x100, b"abc")
    assert rdsr(dev) == 0x00              # cleared when CS rose after WRITE
    assert read(dev, 0x100, 3) == b"abc"


def test_write_without_wren_is_ignored(chip, dev):
    write(dev, 0x10, b"xyz", wren=False)
    assert read(dev, 0x10, 3) == b"\xff\xff\xff"
    assert chip.ignored_writes == 3


def test_rdsr_repeats(dev):
    dev.transfer(b"\x06")
    assert dev.transfer(b"\x05\x00\x00\x00")[1:] == b"\x02\x02\x02"


def test_fast_read_has_a_dummy_byte(dev):
    write(dev, 0x200, b"\x11\x22\x33")
    assert dev.transfer(b"\x0b\x02\x00\x00\x00\x00\x00")[4:] == b"\x11\x22\x33"


def test_address_top_bits_ignored_and_wrap(dev):
    write(dev, 0x3FFE, b"\x01\x02\x03\x04")
    assert read(dev, 0x0000, 2) == b"\x03\x04"
    assert read(dev, 0xFFFE, 4) == b"\x01\x02\x03\x04"   # 0xFFFE & 0x3FFF = 0x3FFE


def test_wrsr_needs_wel_and_sets_bp(dev):
    dev.transfer(b"\x01\x0c")
    assert rdsr(dev) == 0x00
    dev.transfer(b"\x06")
    dev.transfer(b"\x01\xfe")             # only WPEN and BP bits are writable
    assert rdsr(dev) == 0x8C


@pytest.mark.parametrize("bp, first_protected", [(0, SIZE), (1, 0x3000), (2, 0x2000), (3, 0)])
def test_block_protection(dev, bp, first_protected):
    dev.transfer(b"\x06")
    dev.transfer(bytes((0x01, bp << 2)))
    for addr in (0x0000, 0x1FFF, 0x2000, 0x2FFF, 0x3000, 0x3FFF):
        write(dev, addr, b"\x5a")
        want = b"\xff" if addr >= first_protected else b"\x5a"
        assert read(dev, addr, 1) == want, hex(addr)


def test_wp_pin_freezes_status_when_wpen(kernel, bus):
    gpio = Gpio(kernel)
    wp = gpio.pin("PD11")
    chip = Fm25v01(kernel, wp_pin=wp)
    dev = attach(bus, chip)
    dev.transfer(b"\x06")
    dev.transfer(b"\x01\x84")             # WPEN + BP = 01
    wp.low()
    dev.transfer(b"\x06")
    dev.transfer(b"\x01\x00")
    assert rdsr(dev) & 0x8C == 0x84       # frozen
    write(dev, 0x0000, b"\x42")           # /WP does not protect the array by itself
    assert read(dev, 0, 1) == b"\x42"
    wp.high()
    dev.transfer(b"\x06")
    dev.transfer(b"\x01\x00")
    assert rdsr(dev) == 0x00


def test_sleep_takes_effect_at_cs_rise_and_wakes_after_trec(kernel, chip, dev):
    write(dev, 0, b"\x77")
    dev.transfer(b"\xb9")
    assert chip.asleep
    assert read(dev, 0, 1) == b"\xff"     # this window only wakes it
    kernel.run(kernel.now_ns + 500_000)
    assert not chip.asleep
    assert read(dev, 0, 1) == b"\x77"


def test_unknown_opcode_ignored_until_cs_rises(dev):
    assert dev.transfer(b"\x55\x06\x02\x00\x00\x12") == b"\xff" * 6
    assert rdsr(dev) == 0x00


def test_too_fast_clock_is_refused(bus, chip):
    dev = attach(bus, chip)
    dev.max_speed_hz = 50_000_000
    dev.transfer(b"\x06")
    dev.max_speed_hz = 40_000_000
    assert rdsr(dev) == 0x00
    assert chip.too_fast_count == 1


def test_persistence_across_restart(kernel, tmp_path):
    path = tmp_path / "fram.bin"
    bus = SpiBus(kernel, "spi2")
    chip = Fm25v01(kernel, path=path)
    dev = attach(bus, chip)
    assert path.stat().st_size == SIZE
    write(dev, 0x1234, b"param data")
    write(dev, 0x3FFF, b"\x01\x02")       # wraps to 0x0000
    dev.transfer(b"\x06")
    dev.transfer(b"\x01\x04")             # BP = 01 is non-volatile too
    bus.detach("PD10")                    # no close(): a crash must not lose the data
    again = Fm25v01(kernel, path=path)
    dev2 = attach(bus, again)
    assert read(dev2, 0x1234, 10) == b"param data"
    assert read(dev2, 0x3FFF, 2) == b"\x01\x02"
    assert rdsr(dev2) == 0x04             # WEL volatile, BP kept
    raw = path.read_bytes()
    assert raw[0x1234:0x123E] == b"param data" and raw[0] == 0x02 and len(raw) == SIZE
    chip.close()
    again.close()


def test_partial_host_file_padded_without_loss(kernel, tmp_path):
    path = tmp_path / "short.bin"
    path.write_bytes(b"\x2b\x00\x00\x00saved")
    chip = Fm25v01(kernel, path=path)
    dev = attach(SpiBus(kernel, "spi2"), chip)
    assert read(dev, 0, 10) == b"\x2b\x00\x00\x00saved\xff"
    assert os.path.getsize(path) == SIZE
    assert path.read_bytes()[:9] == b"\x2b\x00\x00\x00saved"
    chip.close()


def test_a_closed_chip_collected_later_leaves_a_newer_file_open(kernel, tmp_path):
    # close() released the descriptor and the collector released the same number again: if a
    # newer FRAM file had reused it (a reboot in the same process), its writes failed (EBADF).
    import gc

    old = Fm25v01(kernel, path=tmp_path / "old.bin")
    old.close()
    new = Fm25v01(kernel, path=tmp_path / "new.bin")
    dev = attach(SpiBus(kernel, "spi2"), new)
    del old
    gc.collect()
    write(dev, 0x10, b"kept")
    new.close()
    assert (tmp_path / "new.bin").read_bytes()[0x10:0x14] == b"kept"


def test_faults(chip, dev):
    chip.faults.absent = True
    assert dev.transfer(b"\x9f" + bytes(9)) == b"\xff" * 10
    chip.faults.clear()
    chip.faults.wrong_id = 0x00
    assert dev.transfer(b"\x9f" + bytes(9))[7] == 0x00
    chip.faults.clear()
    chip.faults.frozen = True
    write(dev, 0, b"\x01")
    assert read(dev, 0, 1) == b"\xff"


def test_bad_size_raises(kernel):
    with pytest.raises(ValueError, match="power of two"):
        Fm25v01(kernel, size=1000)
