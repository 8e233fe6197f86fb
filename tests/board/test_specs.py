"""Board specs: the FMUv2/IOv2 facts, and validation that catches impossible boards."""

import dataclasses

import pytest

from board.specs import FMU_V2, IO_V2, I2cBusSpec, I2cDevice, SpecError, SpiBusSpec, SpiDevice


def test_fmu_v2_wiring_facts():
    spi1 = FMU_V2.spi[0]
    assert spi1.name == "SPI1"
    cs = {d.name: (d.cs, d.drdy) for d in spi1.devices}
    assert cs == {"mpu6000": ("PC2", ("PD15",)), "l3gd20": ("PC13", ("PB0",)),
                  "lsm303d": ("PC15", ("PB4", "PB1")), "ms5611": ("PD7", ())}
    assert FMU_V2.device("fram").cs == "PD10"
    assert FMU_V2.device("hmc5883").address == 0x1E
    io_link = next(u for u in FMU_V2.uarts if u.role == "io_link")
    assert (io_link.name, io_link.baud) == ("USART6", 1_500_000)
    gps = next(u for u in FMU_V2.uarts if u.role == "gps")
    assert (gps.name, gps.device) == ("UART4", "/dev/ttyS3")
    batt = next(a for a in FMU_V2.adc if a.signal == "battery_voltage")
    assert (batt.channel, batt.pin) == (2, "PA2")


def test_io_v2_outputs_and_rc_inputs():
    assert [o.pin for o in IO_V2.pwm] == ["PA0", "PA1", "PB8", "PB9", "PA6", "PA7", "PB0", "PB1"]
    assert [o.port for o in IO_V2.pwm] == [f"pwm{i}" for i in range(1, 9)]
    assert {u.role: u.name for u in IO_V2.uarts} == {"dsm": "USART1", "fmu_link": "USART2",
                                                     "sbus": "USART3"}
    assert IO_V2.pins["safety_button"] == "PB5" and IO_V2.pins["ppm_in"] == "PA8"


def test_duplicate_chip_select_rejected():
    bad = SpiBusSpec("SPI1", 1, 84_000_000, (
        SpiDevice("a", "mpu6000", cs="PC2"), SpiDevice("b", "ms5611", cs="PC2")))
    with pytest.raises(SpecError, match="pin PC2 used by both"):
        dataclasses.replace(FMU_V2, spi=(bad,))


def test_unknown_model_and_bad_address_rejected():
    with pytest.raises(SpecError, match="unknown model 'bmi088'"):
        dataclasses.replace(FMU_V2, spi=(SpiBusSpec("SPI1", 1, 1, (
            SpiDevice("x", "bmi088", cs="PC2"),)),))
    with pytest.raises(SpecError, match="reserved or not 7-bit"):
        dataclasses.replace(FMU_V2, i2c=(I2cBusSpec("I2C1", 1, 400_000, True, (
            I2cDevice("m", "hmc5883", 0x7F),)),))
    with pytest.raises(SpecError, match="used twice"):
        dataclasses.replace(FMU_V2, i2c=(I2cBusSpec("I2C1", 1, 400_000, True, (
            I2cDevice("m", "hmc5883", 0x1E), I2cDevice("n", "hmc5883", 0x1E))),))


def test_bad_pin_name_rejected():
    with pytest.raises(SpecError, match="not a pin name"):
        dataclasses.replace(FMU_V2, spi=(SpiBusSpec("SPI1", 1, 1, (
            SpiDevice("x", "mpu6000", cs="C2"),)),))
