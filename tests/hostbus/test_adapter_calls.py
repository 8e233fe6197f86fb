"""The adapters make the calls smbus2 and spidev document, and nothing else: one ``i2c_rdwr``
with smbus2's ``i2c_msg.write``/``i2c_msg.read`` per combined transaction (``write_quick`` for an
address-only probe), ``xfer2`` with CS held for a whole SPI transfer, and ``mode`` /
``max_speed_hz`` set as spidev has them."""

from __future__ import annotations

import inspect

import pytest
import smbus2
from smbus2 import i2c_msg

from board.i2c import I2cBus
from board.kernel import Kernel
from firmware.drivers.device import I2cAddress
from firmware.drivers.magnetometer.hmc5883 import Hmc5883Driver
from firmware.platform import Platform
from hil.hostbus import SMBusHandle, SpiDevHandle
from hil.smbus_emulated import EmulatedSMBus
from peripherals.errors import rng_for
from peripherals.hmc5883 import Hmc5883
from tests.hostbus.rigs import RecordingSMBus, RecordingSpiDev, describe, environment, run_baro


@pytest.mark.parametrize("write, read_len, expected", [
    (b"\x03", 6, [("i2c_rdwr", ("w", 0x1E, b"\x03"), ("r", 0x1E, 6))]),
    (b"\x02\x01", 0, [("i2c_rdwr", ("w", 0x1E, b"\x02\x01"))]),
    (b"", 2, [("i2c_rdwr", ("r", 0x1E, 2))]),
    (b"", 0, [("write_quick", 0x1E)]),
])
def test_one_transaction_is_one_documented_call(write, read_len, expected) -> None:
    rec = RecordingSMBus()
    status, data = SMBusHandle(rec, 1).transfer(0x1E, write, read_len)
    assert status == 0 and data == bytes(read_len)   # the read buffer smbus2 allocated
    assert [describe(c) for c in rec.calls] == expected
    for name, args in rec.calls:
        # A method of smbus2's SMBus, called in a way its signature accepts, with its i2c_msg.
        inspect.signature(getattr(smbus2.SMBus, name)).bind(object(), *args)
        assert all(isinstance(a, smbus2.i2c_msg) for a in args if not isinstance(a, int))


def test_the_driver_start_sequence_on_a_recording_smbus() -> None:
    """PX4's probe and configure of the HMC5883, as smbus2 calls."""
    k = Kernel("t")
    p = Platform(k)
    bus = I2cBus(k, "I2C1")
    bus.attach(0x1E, Hmc5883(k, environment(), rng_for(1, "hmc5883")))
    rec = RecordingSMBus(EmulatedSMBus(bus))
    handle = SMBusHandle(rec, 1)
    drv = Hmc5883Driver(p, handle.device(0x1E), bus=1)
    assert drv.start()
    k.run(20_000_000)
    a = 0x1E
    assert [describe(c) for c in rec.calls[:10]] == [
        ("i2c_rdwr", ("w", a, b"\x0a"), ("r", a, 1)),       # ID A, B, C one at a time
        ("i2c_rdwr", ("w", a, b"\x0b"), ("r", a, 1)),
        ("i2c_rdwr", ("w", a, b"\x0c"), ("r", a, 1)),
        ("i2c_rdwr", ("w", a, b"\x00\x10")),                # CRA: 15 Hz, normal
        ("i2c_rdwr", ("w", a, b"\x01\x40")),                # CRB: +-1.9 Ga
        ("i2c_rdwr", ("w", a, b"\x00"), ("r", a, 2)),       # read both back
        ("i2c_rdwr", ("w", a, b"\x02\x01")),                # MR: single measurement
        ("i2c_rdwr", ("w", a, b"\x03"), ("r", a, 6)),       # the data, 6666 us later
        ("i2c_rdwr", ("w", a, b"\x02\x01")),
        ("i2c_rdwr", ("w", a, b"\x03"), ("r", a, 6)),
    ]
    assert {name for name, _ in rec.calls} == {"i2c_rdwr"}
    assert handle.transactions == len(rec.calls) and handle.errors == 0


def test_bus_handle_binds_addresses_and_refuses_bad_ones() -> None:
    handle = SMBusHandle(RecordingSMBus(), 7)
    dev = handle.device(0x77)
    assert isinstance(dev, I2cAddress) and dev.addr == 0x77 and dev.bus is handle
    with pytest.raises(ValueError, match="7-bit"):
        handle.device(0x80)
    with pytest.raises(ValueError, match="7-bit"):
        handle.transfer(-1, b"\x00")
    with pytest.raises(ValueError, match="read_len"):
        handle.transfer(0x10, b"", -2)
    with pytest.raises(ValueError, match="bus number"):
        SMBusHandle(RecordingSMBus(), -1)


def test_spidev_calls_of_the_ms5611_driver() -> None:
    recs: list[RecordingSpiDev] = []

    def adapt(dev):
        recs.append(RecordingSpiDev(dev))
        return SpiDevHandle(recs[0])

    published, drv = run_baro(adapt)
    log = recs[0].log
    # mode 3 and the fast clock set as spidev attributes, then RESET and the eight PROM words,
    # each one xfer2 (CS held over command and answer).
    assert log[:4] == [("set", "mode", 3), ("set", "max_speed_hz", 20_000_000),
                       ("xfer2", [0x1E]), ("xfer2", [0xA0, 0, 0])]
    assert [e[1] for e in log[3:11]] == [[0xA0 + 2 * i, 0, 0] for i in range(8)]
    assert ("xfer2", [0, 0, 0, 0]) in log                  # ADC reads
    assert {e[0] for e in log} == {"set", "xfer2"}
    assert published and drv.error_count == 0
