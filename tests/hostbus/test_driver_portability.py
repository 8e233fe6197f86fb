"""The FMU's own drivers run unchanged on a Linux bus API: the HMC5883 driver through
hil/hostbus.py's SMBusHandle on an smbus2-API object backed by the emulated chip (and on smbus2's
real SMBus class, only its ioctl answered by the emulated bus) publishes exactly what it
publishes on the emulated board; the MS5611 driver likewise through SpiDevHandle (xfer2)."""

from __future__ import annotations

from fmu.board import BOOT_TO_SENSORS_NS, FmuV2Board
from firmware.drivers.magnetometer.hmc5883 import Hmc5883Driver
from hil.hostbus import SMBusHandle, SpiDevHandle
from hil.smbus_emulated import EmulatedSMBus
from tests.hostbus.rigs import (MS, RecordingSpiDev, real_smbus_on, record_publications,
                                run_baro, run_mag)

NOT_MAG = ("mpu6000", "l3gd20", "lsm303d", "ms5611", "fram", "gps", "ublox_m8")


def test_hmc5883_publishes_the_same_samples_through_the_smbus_adapter(monkeypatch) -> None:
    direct, drv_a, _ = run_mag(lambda bus: bus.device(0x1E))
    emulated, drv_b, _ = run_mag(lambda bus: SMBusHandle(EmulatedSMBus(bus), 1).device(0x1E))
    real_api, drv_c, _ = run_mag(lambda bus: SMBusHandle(real_smbus_on(bus, monkeypatch), 1)
                                 .device(0x1E))
    assert len(direct) > 50                       # 150 Hz for 0.4 s, less the configure cycle
    # Byte for byte, at the same virtual times: values, device id, error counts.
    assert emulated == direct
    assert real_api == direct
    assert drv_a.device_id == drv_b.device_id == drv_c.device_id
    assert drv_a.error_count == drv_b.error_count == drv_c.error_count == 0


def test_hmc5883_through_the_adapter_matches_the_emulated_board() -> None:
    """The FMU board with only its magnetometer: once with the board's own driver start, once
    with the driver started at the same time on the board's I2C1 behind the smbus2 API."""
    on_board = FmuV2Board(seed=3, firmware="sensors", exclude=NOT_MAG)
    expected, undo = record_publications(on_board.kernel, "sensor_mag")
    try:
        on_board.kernel.run(BOOT_TO_SENSORS_NS + 300 * MS)
    finally:
        undo()
    hosted = FmuV2Board(seed=3, firmware="none", exclude=NOT_MAG)
    handle = SMBusHandle(EmulatedSMBus(hosted.i2c["I2C1"]), 1)
    drivers: list[Hmc5883Driver] = []

    def start() -> None:
        drivers.append(Hmc5883Driver(hosted.platform, handle.device(0x1E), bus=1))
        assert drivers[0].start()

    hosted.kernel.call_at(BOOT_TO_SENSORS_NS, start)
    got, undo = record_publications(hosted.kernel, "sensor_mag")
    try:
        hosted.kernel.run(BOOT_TO_SENSORS_NS + 300 * MS)
    finally:
        undo()
    assert len(expected) > 30
    assert got == expected
    assert handle.transactions > len(expected) and handle.errors == 0


def test_ms5611_publishes_the_same_samples_through_the_spidev_adapter() -> None:
    direct, _ = run_baro(lambda dev: dev)
    adapted, drv = run_baro(lambda dev: SpiDevHandle(RecordingSpiDev(dev)))
    assert len(direct) > 15                       # 75 Hz for 0.3 s, less reset and PROM
    assert adapted == direct
    assert drv.error_count == 0
