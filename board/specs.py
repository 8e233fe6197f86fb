"""Board specs as validated data: what sits on which bus, pin and timer of the FMUv2 and IOv2.

A spec names everything a board builder needs and nothing about behaviour. Device models are
named (``model="mpu6000"``) and found in :data:`MODELS`, imported only when a board is built,
so a spec can be read (by docs, a shell ``ver`` command, tests) without importing any model.

Validation happens when a spec is built: duplicate chip selects or pins, an I2C address used
twice on one bus, a device on a bus the board does not have, an unknown model, a data-ready
line on a pin that something else drives, all raise :class:`SpecError` naming the problem.
"""

from __future__ import annotations

import importlib
import re
from dataclasses import dataclass, field
from typing import Any

__all__ = ["SpecError", "SpiDevice", "SpiBusSpec", "I2cDevice", "I2cBusSpec", "UartSpec",
           "AdcChannel", "PwmOutput", "CanSpec", "BoardSpecData", "FMU_V2", "IO_V2", "MODELS",
           "model_class"]

_PIN = re.compile(r"^P[A-K]\d{1,2}$")


class SpecError(ValueError):
    """A board spec that cannot describe a real board."""


#: Device model name -> "module:Class", imported lazily.
MODELS: dict[str, str] = {
    "mpu6000": "peripherals.mpu6000:Mpu6000",
    "l3gd20": "peripherals.l3gd20:L3gd20",
    "lsm303d": "peripherals.lsm303d:Lsm303d",
    "ms5611": "peripherals.ms5611:Ms5611",
    "fm25v01": "peripherals.fm25v01:Fm25v01",
    "hmc5883": "peripherals.hmc5883:Hmc5883",
    "ublox_m8": "peripherals.ublox:UbloxM8",
}


def model_class(name: str) -> Any:
    try:
        target = MODELS[name]
    except KeyError:
        raise SpecError(f"unknown device model {name!r}; known: {', '.join(sorted(MODELS))}"
                        ) from None
    module, _, cls = target.partition(":")
    return getattr(importlib.import_module(module), cls)


def _pin(p: str | None, what: str) -> None:
    if p is not None and not _PIN.match(p):
        raise SpecError(f"{what}: {p!r} is not a pin name like 'PD15'")


@dataclass(frozen=True)
class SpiDevice:
    name: str           # instance name (also the driver's name)
    model: str          # key of MODELS
    cs: str             # chip-select pin (active low)
    drdy: tuple[str, ...] = ()  # data-ready / interrupt pins, in the model's order
    max_clock_hz: int | None = None
    about: str = ""


@dataclass(frozen=True)
class SpiBusSpec:
    name: str           # "SPI1"
    number: int         # PX4 bus number (1-based)
    pclk_hz: int
    devices: tuple[SpiDevice, ...] = ()


@dataclass(frozen=True)
class I2cDevice:
    name: str
    model: str
    address: int
    external: bool = False
    about: str = ""


@dataclass(frozen=True)
class I2cBusSpec:
    name: str           # "I2C1"
    number: int
    clock_hz: int
    external: bool
    devices: tuple[I2cDevice, ...] = ()


@dataclass(frozen=True)
class UartSpec:
    name: str           # "USART6"
    device: str         # NuttX device, "/dev/ttyS4"
    role: str           # "io_link", "telem1", "gps", "console", ...
    baud: int = 57_600  # NuttX default until a driver changes it
    port: str | None = None   # lockstep port name when the UART leaves the board
    external_model: str | None = None  # a device plugged into the connector (the GPS)
    about: str = ""


@dataclass(frozen=True)
class AdcChannel:
    channel: int
    pin: str
    signal: str
    scale: float        # signal units per pin volt
    unit: str


@dataclass(frozen=True)
class PwmOutput:
    name: str           # "MAIN1", "AUX1"
    pin: str
    timer: str          # "TIM2"
    channel: int
    group: int          # rate group
    port: str | None = None


@dataclass(frozen=True)
class CanSpec:
    name: str
    rx: str
    tx: str


@dataclass(frozen=True)
class BoardSpecData:
    name: str
    mcu: str
    sysclk_hz: int
    spi: tuple[SpiBusSpec, ...] = ()
    i2c: tuple[I2cBusSpec, ...] = ()
    uarts: tuple[UartSpec, ...] = ()
    adc: tuple[AdcChannel, ...] = ()
    pwm: tuple[PwmOutput, ...] = ()
    can: tuple[CanSpec, ...] = ()
    timers_hz: dict[str, int] = field(default_factory=dict)
    pins: dict[str, str] = field(default_factory=dict)   # named GPIO roles -> pin

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        where = f"board {self.name}"
        claimed: dict[str, str] = {}

        def claim(pin: str, who: str) -> None:
            _pin(pin, f"{where}: {who}")
            if pin in claimed:
                raise SpecError(f"{where}: pin {pin} used by both {claimed[pin]} and {who}")
            claimed[pin] = who

        names: set[str] = set()
        for bus in self.spi:
            for dev in bus.devices:
                if dev.model not in MODELS:
                    raise SpecError(f"{where}: {bus.name} device {dev.name} has unknown model "
                                    f"{dev.model!r}")
                if dev.name in names:
                    raise SpecError(f"{where}: device name {dev.name} used twice")
                names.add(dev.name)
                claim(dev.cs, f"{dev.name} chip select")
                for p in dev.drdy:
                    claim(p, f"{dev.name} data-ready")
        for bus in self.i2c:
            addrs: set[int] = set()
            for dev in bus.devices:
                if dev.model not in MODELS:
                    raise SpecError(f"{where}: {bus.name} device {dev.name} has unknown model "
                                    f"{dev.model!r}")
                if not 0x08 <= dev.address <= 0x77:
                    raise SpecError(f"{where}: {dev.name} address 0x{dev.address:02X} is "
                                    f"reserved or not 7-bit")
                if dev.address in addrs:
                    raise SpecError(f"{where}: {bus.name} address 0x{dev.address:02X} used twice")
                addrs.add(dev.address)
                if dev.name in names:
                    raise SpecError(f"{where}: device name {dev.name} used twice")
                names.add(dev.name)
        seen_uarts: set[str] = set()
        for u in self.uarts:
            if u.name in seen_uarts:
                raise SpecError(f"{where}: UART {u.name} listed twice")
            seen_uarts.add(u.name)
            if u.external_model is not None and u.external_model not in MODELS:
                raise SpecError(f"{where}: {u.name} external model {u.external_model!r} unknown")
        for out in self.pwm:
            claim(out.pin, f"PWM {out.name}")
            if out.timer not in self.timers_hz:
                raise SpecError(f"{where}: PWM {out.name} on {out.timer}, which has no clock")
        for a in self.adc:
            _pin(a.pin, f"{where}: ADC channel {a.channel}")
        for role, p in self.pins.items():
            if p in claimed and claimed[p] != role:
                # A few pins legitimately double (the FMUv2 PB4 strap is the LSM303D INT1).
                continue
            _pin(p, f"{where}: {role}")

    def device(self, name: str) -> SpiDevice | I2cDevice:
        for bus in self.spi:
            for dev in bus.devices:
                if dev.name == name:
                    return dev
        for ibus in self.i2c:
            for idev in ibus.devices:
                if idev.name == name:
                    return idev
        raise KeyError(f"{self.name} has no device {name!r}")


#: Pixhawk 1 FMU (PX4 fmu-v2): facts from ../shared/reference/sensors.md section 7.
FMU_V2 = BoardSpecData(
    name="px4_fmu-v2",
    mcu="STM32F427VI",
    sysclk_hz=168_000_000,
    spi=(
        SpiBusSpec("SPI1", 1, 84_000_000, (
            SpiDevice("mpu6000", "mpu6000", cs="PC2", drdy=("PD15",),
                      about="6-axis IMU, INT on PD15"),
            SpiDevice("l3gd20", "l3gd20", cs="PC13", drdy=("PB0",), about="gyro, DRDY/INT2"),
            SpiDevice("lsm303d", "lsm303d", cs="PC15", drdy=("PB4", "PB1"),
                      about="accel (INT1 PB4) + mag (INT2 PB1)"),
            SpiDevice("ms5611", "ms5611", cs="PD7", about="barometer"),
        )),
        SpiBusSpec("SPI2", 2, 42_000_000, (
            SpiDevice("fram", "fm25v01", cs="PD10", about="16 KiB FRAM: parameters, dataman"),
        )),
    ),
    i2c=(
        I2cBusSpec("I2C1", 1, 400_000, external=True, devices=(
            I2cDevice("hmc5883", "hmc5883", 0x1E, external=True,
                      about="compass in the GPS module"),
        )),
        I2cBusSpec("I2C2", 2, 400_000, external=False),
    ),
    uarts=(
        UartSpec("USART1", "/dev/ttyS0", "io_console", 115_200,
                 about="console output of the IO coprocessor (RX only)"),
        UartSpec("USART2", "/dev/ttyS1", "telem1", 57_600, port="telem1",
                 about="TELEM1, MAVLink, hardware flow control"),
        UartSpec("USART3", "/dev/ttyS2", "telem2", 57_600, port="telem2",
                 about="TELEM2, MAVLink or companion"),
        UartSpec("UART4", "/dev/ttyS3", "gps", 9_600, external_model="ublox_m8",
                 about="GPS port: u-blox M8 module"),
        UartSpec("USART6", "/dev/ttyS4", "io_link", 1_500_000, port="io_link",
                 about="PX4IO link, 1.5 Mbit/s, DMA both ways"),
        UartSpec("UART7", "/dev/ttyS5", "console", 57_600, port="console",
                 about="NuttX system console (nsh)"),
        UartSpec("UART8", "/dev/ttyS6", "serial4", 57_600, about="SERIAL 4"),
    ),
    adc=(
        AdcChannel(2, "PA2", "battery_voltage", 10.177939394, "V"),
        AdcChannel(3, "PA3", "battery_current", 15.391030303, "A"),
        AdcChannel(4, "PA4", "vdd_5v", 2.0, "V"),
        AdcChannel(13, "PC3", "aux_adc_3v3", 1.0, "V"),
        AdcChannel(14, "PC4", "aux_adc2_3v3", 1.0, "V"),
        AdcChannel(15, "PC5", "airspeed_6v6", 2.0, "V"),
    ),
    pwm=(
        PwmOutput("AUX1", "PE14", "TIM1", 4, 0, port="aux1"),
        PwmOutput("AUX2", "PE13", "TIM1", 3, 0, port="aux2"),
        PwmOutput("AUX3", "PE11", "TIM1", 2, 0, port="aux3"),
        PwmOutput("AUX4", "PE9", "TIM1", 1, 0, port="aux4"),
        PwmOutput("AUX5", "PD13", "TIM4", 2, 1, port="aux5"),
        PwmOutput("AUX6", "PD14", "TIM4", 3, 1, port="aux6"),
    ),
    can=(CanSpec("CAN1", "PD0", "PD1"), CanSpec("CAN2", "PB12", "PB6")),
    timers_hz={"TIM1": 168_000_000, "TIM4": 84_000_000, "TIM8": 168_000_000,
               "TIM2": 84_000_000},
    pins={"led_amber": "PE12", "sensors_3v3_en": "PE3", "periph_5v_en": "PA8",
          "brick_valid": "PB5", "servo_valid": "PB7", "usb_valid": "PC0",
          "hw_strap_pb12": "PB12", "hw_strap_pb4": "PB4", "buzzer": "PA15"},
)


#: Pixhawk 1 IO coprocessor (PX4 io-v2): facts from ../shared/reference/io-and-rc.md 3.1, 8.1.
IO_V2 = BoardSpecData(
    name="px4_io-v2",
    mcu="STM32F100C8",
    sysclk_hz=24_000_000,
    uarts=(
        UartSpec("USART1", "/dev/ttyS0", "dsm", 115_200, port="dsm_in",
                 about="TX: console to the FMU; RX: Spektrum satellite"),
        UartSpec("USART2", "/dev/ttyS1", "fmu_link", 1_500_000, port="fmu_link",
                 about="FMU link, 1.5 Mbit/s, DMA + IDLE framing"),
        UartSpec("USART3", "/dev/ttyS2", "sbus", 100_000, port="sbus_in",
                 about="S.BUS in (RX PB11, inverted 8E2) / out (TX PB10)"),
    ),
    adc=(
        AdcChannel(4, "PA4", "servo_rail_mv", 9900.0 / 3.3, "mV"),
        AdcChannel(5, "PA5", "rssi_mv", 1000.0, "mV"),
    ),
    pwm=tuple(
        PwmOutput(f"MAIN{i + 1}", pin, tim, ch, grp, port=f"pwm{i + 1}")
        for i, (pin, tim, ch, grp) in enumerate([
            ("PA0", "TIM2", 1, 0), ("PA1", "TIM2", 2, 0), ("PB8", "TIM4", 3, 2),
            ("PB9", "TIM4", 4, 2), ("PA6", "TIM3", 1, 1), ("PA7", "TIM3", 2, 1),
            ("PB0", "TIM3", 3, 1), ("PB1", "TIM3", 4, 1)])
    ),
    timers_hz={"TIM1": 24_000_000, "TIM2": 24_000_000, "TIM3": 24_000_000,
               "TIM4": 24_000_000},
    pins={"safety_button": "PB5", "led_blue": "PB14", "led_amber": "PB15",
          "led_safety": "PB13", "led_ring": "PA11", "ppm_in": "PA8",
          "spektrum_power": "PC13", "sbus_out_enable": "PB4", "servo_power_fault": "PA15"},
)
