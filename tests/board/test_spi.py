"""SPI bus: what a device model sees, and what a driver gets back, at exact virtual times."""

from __future__ import annotations

import pytest

from board.kernel import Kernel
from board.spi import SpiBus, SpiBusError, SpiTarget


class Recorder(SpiTarget):
    """Logs every hook call; answers a 0x80|addr read with addr, addr+1, ..."""

    def __init__(self, max_clock_hz: int | None = None) -> None:
        self.max_clock_hz = max_clock_hz
        self.calls: list[tuple] = []
        self._addr: int | None = None

    def _select(self, t_ns, mode, clock_hz):
        self.calls.append(("select", t_ns, mode, clock_hz))
        self._addr = None

    def _exchange(self, t_ns, tx):
        self.calls.append(("exchange", t_ns, tx))
        out = bytearray()
        for b in tx:
            if self._addr is None:
                self._addr = b & 0x7F
                out.append(0)
            else:
                out.append(self._addr & 0xFF)
                self._addr += 1
        return bytes(out)

    def _deselect(self, t_ns):
        self.calls.append(("deselect", t_ns))


@pytest.fixture
def kernel() -> Kernel:
    return Kernel("fmu")


@pytest.fixture
def bus(kernel: Kernel) -> SpiBus:
    return SpiBus(kernel, "spi1")


def test_select_exchange_deselect_in_order_with_times(kernel, bus):
    dev_model = Recorder()
    bus.attach("mpu", dev_model)
    dev = bus.device("mpu", mode=3, clock_hz=1_000_000)
    kernel.run(1_000)
    rx = dev.transfer(bytes([0xBB]) + bytes(13))
    assert rx == bytes([0]) + bytes(range(0x3B, 0x3B + 13))
    assert dev_model.calls == [
        ("select", 1_000, 3, 1_000_000),
        ("exchange", 1_000, bytes([0xBB]) + bytes(13)),
        ("deselect", 1_000 + 112_000),
    ]
    assert not dev_model.selected


def test_durations_add_to_busy_and_next_transfer_starts_after(kernel, bus):
    rec = Recorder()
    bus.attach("mpu", rec)
    dev = bus.device("mpu", clock_hz=1_000_000)
    dev.transfer(bytes(14))
    assert kernel.busy_ns == 112_000
    dev.max_speed_hz = 20_000_000
    dev.transfer(bytes(14))
    assert kernel.busy_ns == 112_000 + 5_600
    assert rec.calls[3] == ("select", 112_000, 3, 20_000_000)
    assert kernel.context_ns == 117_600


def test_no_device_reads_ff_and_still_takes_time(kernel, bus):
    dev = bus.device("nothing", clock_hz=1_000_000)
    assert dev.transfer(b"\x80\x00\x00") == b"\xff\xff\xff"
    assert kernel.busy_ns == 24_000
    assert dev.xfer([0x80, 0]) == [0xFF, 0xFF]


def test_clock_above_device_max_is_refused_once_per_selection(bus):
    rec = Recorder(max_clock_hz=1_000_000)
    bus.attach("mpu", rec)
    dev = bus.device("mpu", clock_hz=20_000_000)
    assert dev.transfer(b"\xf5\x00") == b"\xff\xff"
    with dev.transaction() as tr:
        assert tr.exchange(b"\xf5") == b"\xff"
        assert tr.exchange(b"\x00") == b"\xff"
    assert rec.too_fast_count == 2
    assert [c[0] for c in rec.calls] == ["select", "deselect", "select", "deselect"]
    dev.max_speed_hz = 1_000_000
    assert dev.transfer(b"\xf5\x00") == b"\x00\x75"


def test_clock_too_fast_hook_can_be_overridden(bus):
    class Garbage(Recorder):
        def _clock_too_fast(self, t_ns, tx):
            return b"\x5a" * len(tx)

    bus.attach("mpu", Garbage(max_clock_hz=1_000_000))
    assert bus.device("mpu", clock_hz=2_000_000).transfer(b"\x80\x00") == b"\x5a\x5a"


def test_multi_segment_transaction_holds_cs(kernel, bus):
    rec = Recorder()
    bus.attach("baro", rec)
    dev = bus.device("baro", mode=0, clock_hz=2_000_000)
    dev.select()
    assert dev.exchange(b"\x90") == b"\x00"
    assert dev.exchange(bytes(3)) == bytes([0x10, 0x11, 0x12])
    dev.deselect()
    assert rec.calls == [
        ("select", 0, 0, 2_000_000),
        ("exchange", 0, b"\x90"),
        ("exchange", 4_000, bytes(3)),
        ("deselect", 16_000),
    ]
    assert kernel.busy_ns == 16_000


def test_two_chip_selects_at_once_is_an_error(bus):
    bus.attach("a", Recorder())
    bus.attach("b", Recorder())
    a, b = bus.device("a"), bus.device("b")
    a.select()
    with pytest.raises(SpiBusError, match="still asserted"):
        b.transfer(b"\x00")
    a.deselect()
    b.transfer(b"\x00")


def test_micropython_and_spidev_shapes(bus):
    bus.attach("mpu", Recorder())
    dev = bus.device("mpu")
    buf = bytearray(3)
    dev.write_readinto(b"\x80\x00\x00", buf)
    assert buf == bytearray([0, 0, 1])
    with pytest.raises(ValueError, match="differ in length"):
        dev.write_readinto(b"\x80", bytearray(2))
    assert dev.xfer([0x85, 0, 0]) == [0, 5, 6]
    assert dev.read(2, write=0x81) == b"\x00\x01"


def test_stm32_prescaler_rounds_clock_down(kernel):
    bus = SpiBus(kernel, "spi1", pclk_hz=84_000_000)
    dev = bus.device("mpu", clock_hz=20_000_000)
    assert dev.max_speed_hz == 20_000_000
    assert dev.clock_hz == 10_500_000
    dev.max_speed_hz = 1_000_000
    assert dev.clock_hz == 656_250


def test_bad_arguments(kernel, bus):
    with pytest.raises(ValueError, match="mode must be 0..3"):
        bus.device("x", mode=4)
    with pytest.raises(ValueError, match="positive int"):
        bus.device("x", clock_hz=0)
    bus.attach("x", Recorder())
    with pytest.raises(ValueError, match="already has"):
        bus.attach("x", Recorder())
    fixed = SpiBus(kernel, "spi2", cs_names=("fram",))
    with pytest.raises(ValueError, match="unknown chip select 'farm'"):
        fixed.device("farm")


def test_wrong_reply_length_from_model_is_reported(bus):
    class Short(SpiTarget):
        def _exchange(self, t_ns, tx):
            return b"\x00"

    bus.attach("s", Short())
    with pytest.raises(ValueError, match="answered 2 bytes sent with 1 bytes"):
        bus.device("s").transfer(b"\x00\x00")


def test_transfer_from_isr_is_allowed_and_timed(kernel, bus):
    bus.attach("mpu", Recorder())
    dev = bus.device("mpu")
    kernel.in_isr = True
    dev.transfer(b"\x80\x00")
    assert kernel.busy_ns == 16_000
