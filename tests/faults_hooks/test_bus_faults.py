"""Bus faults at the register level: SPI MISO stuck, I2C NAK storms and a stuck SDA, UART line
noise; the drivers notice as PX4's do."""

from __future__ import annotations

import pytest

from fmu.board import BOOT_TO_SENSORS_NS, FmuV2Board
from board.i2c import I2cBus, I2cFault, I2cTarget
from board.kernel import Kernel
from board.spi import SpiBus, SpiTarget
from board.uart import Uart, UartConfig, connect
from board.uart_fault import LineNoise
from board.uart_line import FE, PE
from hil.turntable import Turntable

S = 1_000_000_000
MS = 1_000_000


class _Echo(SpiTarget):
    """Answers each byte with its complement and remembers what it received."""

    def __init__(self) -> None:
        self.got = bytearray()

    def _exchange(self, t_ns, tx):
        self.got += tx
        return bytes(b ^ 0xFF for b in tx)


@pytest.mark.parametrize("level,byte", [(1, 0xFF), (0, 0x00)])
def test_miso_stuck_every_device_reads_the_stuck_level_and_still_hears_mosi(level, byte):
    k = Kernel()
    bus = SpiBus(k, "SPI1")
    a, b = _Echo(), _Echo()
    bus.attach("A", a)
    bus.attach("B", b)
    ha, hb, hc = bus.device("A"), bus.device("B"), bus.device("C")
    assert ha.transfer(b"\x0f\xf0") == b"\xf0\x0f"
    bus.set_miso_stuck(level)
    for h in (ha, hb, hc):
        assert h.transfer(b"\x12\x34\x56") == bytes([byte]) * 3
        with h.transaction() as tr:
            assert tr.exchange(b"\x01") == bytes([byte])
    assert a.got.endswith(b"\x12\x34\x56\x01") and b.got == b"\x12\x34\x56\x01"
    bus.set_miso_stuck(None)
    assert hb.transfer(b"\x0f") == b"\xf0"
    with pytest.raises(ValueError, match="0, 1 or None"):
        bus.set_miso_stuck(2)


def _sensors_board(seed: int = 3) -> FmuV2Board:
    board = FmuV2Board(seed=seed, firmware="sensors")
    Turntable(board.kernel, board.env, alt_m=488.0)
    board.kernel.run(BOOT_TO_SENSORS_NS + 2 * S)
    return board


def _count(board, topic, instance=0):
    return board.platform.orb.node(topic, instance).publish_count


def _hmc(board):
    """Publications of the HMC5883's own sensor_mag instance."""
    return board.drivers["hmc5883"]._pub.node.publish_count


def test_spi1_miso_stuck_high_the_spi1_drivers_see_errors_and_recover_after():
    board = _sensors_board()
    spi1 = ("mpu6000", "l3gd20", "lsm303d", "ms5611")
    e0 = {d: board.drivers[d].error_count for d in spi1}
    n_log = len(board.platform.dmesg)
    board.call("spi_miso_stuck", "SPI1", 1)
    board.kernel.run_for(S)
    for d in spi1:
        assert board.drivers[d].error_count > e0[d], d
    assert board.drivers["hmc5883"].error_count == 0
    errors = {mod: t for _, sev, mod, t in board.platform.dmesg[n_log:] if sev <= 3}
    # as PX4's drivers do: an all-ones FIFO count / WHO_AM_I means no device; reset and retry
    assert "resetting" in errors["mpu6000"] and "0xFF" in errors["mpu6000"]
    assert "0xFF" in errors["l3gd20"] and "0xFF" in errors["lsm303d"]
    # the FRAM on SPI2 and the magnetometer on I2C are not affected
    n_mag = _hmc(board)
    board.kernel.run_for(S // 2)
    assert _hmc(board) > n_mag
    board.call("spi_miso_stuck", "SPI1", None)
    n = _count(board, "sensor_gyro", 0)
    board.kernel.run_for(2 * S)
    assert _count(board, "sensor_gyro", 0) > n + 500     # reset, configured, streaming again
    with pytest.raises(ValueError, match="no SPI bus"):
        board.call("spi_miso_stuck", "SPI9", 1)


class _Ack(I2cTarget):
    def _read(self, t_ns, n):
        return b"\x42" * n


def test_i2c_nak_storm_at_the_stated_rate_and_stuck_sda_fails_everything():
    k = Kernel()
    bus = I2cBus(k, "I2C1", clock_hz=400_000)
    bus.attach(0x1E, _Ack())
    bus.set_fault(I2cFault(nak_rate=0.3, seed=1, name="I2C1"))
    n = 4000
    naks = sum(bus.transfer(0x1E, b"\x03", 1)[0] != 0 for _ in range(n))
    # binomial(4000, 0.3): sigma 29
    assert abs(naks - 0.3 * n) < 5 * 29
    assert bus.addr_nak_count == naks
    bus.set_fault(I2cFault(sda_stuck=True))
    k.busy_ns = 0
    status, data = bus.transfer(0x1E, b"\x03", 1)
    assert status < 0 and data == b""
    assert k.busy_ns == 1_000_000          # the controller waited for the bus
    with pytest.raises(OSError) as exc:
        bus.read_byte_data(0x1E, 3)
    assert exc.value.errno == 110          # ETIMEDOUT
    bus.set_fault(None)
    assert bus.transfer(0x1E, b"\x03", 1) == (0, b"\x42")
    with pytest.raises(ValueError):
        I2cFault(nak_rate=1.5)


def test_hmc5883_driver_counts_the_naks_and_keeps_publishing_through_a_partial_storm():
    board = _sensors_board()
    drv = board.drivers["hmc5883"]
    e0 = drv.error_count
    board.call("i2c_fault", "I2C1", 0.2, False)
    n = _hmc(board)
    board.kernel.run_for(2 * S)
    assert drv.error_count > e0 + 5
    assert _hmc(board) > n + 50                              # most reads still get through
    board.call("i2c_fault", "I2C1", 0.0, True)               # SDA stuck: nothing gets through
    board.kernel.run_for(S // 5)
    n = _hmc(board)
    e1 = drv.error_count
    board.kernel.run_for(S)
    assert _hmc(board) == n
    assert drv.error_count > e1
    assert board.call("bus_stats", "i2c", "I2C1")["timeouts"] > 0
    board.call("i2c_fault", "I2C1", 0.0, False)
    board.kernel.run_for(2 * S)
    assert _hmc(board) > n + 50


def _uart_pair(ber=0.0, drop=0.0, cfg=UartConfig(115_200, 8, "E", 1)):
    k = Kernel()
    tx, rx = Uart(k, "TX", cfg), Uart(k, "RX", cfg, rx_buffer_size=1 << 20)
    connect(tx, rx)
    noise = LineNoise(rx, ber, drop, seed=9).install() if (ber or drop) else None
    return k, tx, rx, noise


def test_uart_bit_errors_at_the_stated_rate_with_parity_and_framing_flags():
    k, tx, rx, noise = _uart_pair(ber=1e-3)
    data = bytes(range(256)) * 200          # 51200 frames of 11 bits
    tx.write(data)
    k.run_for(S * 6)
    got = rx.read()
    bits = len(data) * 11
    flips = bits * 1e-3                      # ~563, sigma ~24
    st = noise.stats()
    damaged = st["corrupted"] + st["dropped"] + st["framing_errors"]
    # each damaged frame holds one flip (rarely two): within 5 sigma of the expectation
    assert abs(damaged - flips) < 5 * 24 + 0.02 * flips
    assert len(got) == len(data) - st["dropped"]
    assert st["parity_errors"] > 0 and st["framing_errors"] > 0
    assert rx.parity_errors == st["parity_errors"] and rx.framing_errors == st["framing_errors"]
    assert sum(a != b for a, b in zip(got, data)) > 0
    # a start-bit flip loses the frame: 1 bit in 11
    assert abs(st["dropped"] - flips / 11) < 5 * (flips / 11) ** 0.5 + 3


def test_uart_byte_drops_are_seeded_and_removing_the_fault_restores_the_clean_line():
    def run():
        k, tx, rx, noise = _uart_pair(drop=0.05)
        tx.write(bytes(20_000))
        k.run_for(3 * S)
        return rx.read(), noise
    a, na = run()
    b, _ = run()
    assert a == b
    assert abs((20_000 - len(a)) - 1000) < 5 * 31
    k, tx, rx, noise = _uart_pair(drop=0.5)
    LineNoise.remove(rx)
    assert "receive" not in rx.__dict__          # the class method again: no cost
    tx.write(b"hello")
    k.run_for(MS)
    assert rx.read() == b"hello"


def test_uart_noise_with_a_per_byte_interrupt_delivers_flags_at_the_byte_times():
    k, tx, rx, noise = _uart_pair(ber=0.02)
    seen = []
    rx.on_rx(lambda t, b, f: seen.append((t, b, f)))
    tx.write(bytes(2000))
    k.run_for(S)
    times = [t for t, _, _ in seen]
    assert times == sorted(times)
    assert any(f & (PE | FE) for _, _, f in seen)
    assert len(seen) == 2000 - noise.stats()["dropped"]
