"""Board specs as validated data: what sits on which bus, pin and timer of the FMUv2 and IOv2.

A spec names everything a board builder needs and nothing about behaviour. Device models are
named (``model="mpu6000"``) and found in :data:`MODELS`, imported only when a board is built,
so a spec can be read (by docs, a shell ``ver`` command, tests) without importing any model.

A device is put on a board by one entry here, and only here: its bus, chip select or address,
data-ready pins, rotation, and its driver (shell name, options; the shell module from
:data:`DRIVERS` or ``driver_class``). The board derives from the spec which drivers it starts
(:meth:`BoardSpecData.drivers`) and which it registers with the shell; a driver finds its device
through :meth:`BoardSpecData.place`. Board variants are new specs:
:meth:`BoardSpecData.with_device` and :meth:`BoardSpecData.without_device`.

Validation happens when a spec is built: duplicate chip selects or pins, an I2C address used
twice on one bus, a device on a bus the board does not have, an unknown model, a data-ready
line on a pin that something else drives, all raise :class:`SpecError` naming the problem.
"""

from __future__ import annotations

import importlib
import re
from dataclasses import dataclass, field, replace
from typing import Any, Union

__all__ = ["SpecError", "SpiDevice", "SpiBusSpec", "I2cDevice", "I2cBusSpec", "UartSpec",
           "AdcChannel", "PwmOutput", "CanSpec", "BoardSpecData", "DevicePlace", "DriverStart",
           "FMU_V2", "FMU_V2_OPTIONAL", "IO_V2", "MS4525DO_AIRSPEED", "MODELS", "DRIVERS",
           "STAGES", "SENSOR_STAGES", "model_class", "with_optional_devices"]

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
    "ms4525do": "peripherals.ms4525do:Ms4525do",
}


#: Driver shell name -> its shell module, "package.module:Class" (firmware/drivers/modules.py),
#: imported only when started. A device entry names its driver here, or gives ``driver_class``.
DRIVERS: dict[str, str] = {
    "mpu6000": "firmware.drivers.modules:Mpu6000Module",
    "l3gd20": "firmware.drivers.modules:L3gd20Module",
    "lsm303d": "firmware.drivers.modules:Lsm303dModule",
    "ms5611": "firmware.drivers.modules:Ms5611Module",
    "hmc5883": "firmware.drivers.modules:Hmc5883Module",
    "gps": "firmware.drivers.modules:GpsModule",
    "mtd": "firmware.drivers.modules:MtdModule",
    "ms4525_airspeed": "firmware.drivers.modules:Ms4525AirspeedModule",
}

#: When a board starts a device's driver: ``"storage"`` first at boot, before the parameters
#: load from it; ``"baro"`` and ``"sensors"`` with the sensor drivers (``firmware="sensors"``
#: starts both in spec order; rc.sensors starts the barometers first, then the other sensors,
#: as the FMUv2's script always has).
STAGES = ("storage", "baro", "sensors")
#: The stages of the sensor drivers.
SENSOR_STAGES = ("baro", "sensors")


def _is_target(name: str) -> bool:
    """A ``"package.module:Class"`` string (a model or driver not in the tables)."""
    module, sep, cls = name.partition(":")
    return bool(sep and module and cls.isidentifier())


def model_class(name: str) -> Any:
    """The model class of a spec's ``model``: a key of :data:`MODELS` or ``"pkg.mod:Class"``."""
    if _is_target(name):
        target = name
    else:
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
    model: str          # key of MODELS, or "package.module:Class"
    cs: str             # chip-select pin (active low)
    drdy: tuple[str, ...] = ()  # data-ready / interrupt pins, in the model's order
    max_clock_hz: int | None = None
    about: str = ""
    driver: str = ""    # shell name of its driver ("" : none started from the spec)
    driver_class: str = ""  # "package.module:Class" of that shell module (default DRIVERS)
    driver_args: tuple[str, ...] = ()  # start options, as in ``hmc5883 -X start``
    rotation: int | None = None  # PX4 mounting rotation handed to the driver (None: its own)
    stage: str = "sensors"  # when the board starts the driver: see STAGES


@dataclass(frozen=True)
class SpiBusSpec:
    name: str           # "SPI1"
    number: int         # PX4 bus number (1-based)
    pclk_hz: int
    devices: tuple[SpiDevice, ...] = ()


@dataclass(frozen=True)
class I2cDevice:
    name: str
    model: str          # key of MODELS, or "package.module:Class"
    address: int
    external: bool = False
    about: str = ""
    driver: str = ""
    driver_class: str = ""
    driver_args: tuple[str, ...] = ()
    rotation: int | None = None
    stage: str = "sensors"
    drdy: tuple[str, ...] = ()  # data-ready / interrupt pins, in the model's order


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
    driver: str = ""    # the connector device's driver, as for SpiDevice
    driver_class: str = ""
    driver_args: tuple[str, ...] = ()
    stage: str = "sensors"


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


Device = Union[SpiDevice, I2cDevice]


@dataclass(frozen=True)
class DevicePlace:
    """Where one device sits, as its driver needs it: the bus (``"SPI1"``, ``"I2C1"`` or a UART
    name), PX4's bus number, the I2C address (0 on SPI and UART), the chip-select pin (SPI),
    the data-ready pins and the mounting rotation. The driver takes these from here, not from
    constants of its own, so the board's spec is the one place they are written."""

    name: str
    kind: str           # "spi", "i2c" or "uart"
    bus: str
    bus_number: int
    address: int = 0
    cs: str = ""
    external: bool = False
    drdy: tuple[str, ...] = ()
    rotation: int | None = None
    device: str = ""    # the NuttX device of a UART ("/dev/ttyS3")


@dataclass(frozen=True)
class DriverStart:
    """One driver a board starts, derived from its spec: ``command start args`` in the shell."""

    device: str         # the device's name in the spec
    command: str        # shell name
    target: str         # "package.module:Class" of the shell module
    args: tuple[str, ...]
    stage: str

    @property
    def line(self) -> str:
        """The nsh line that starts it (rc.sensors is made of these)."""
        return " ".join((self.command, "start") + self.args)


def _driver_target(where: str, name: str, driver: str, driver_class: str, stage: str) -> str:
    if stage not in STAGES:
        raise SpecError(f"{where}: {name} stage {stage!r} is not one of {', '.join(STAGES)}")
    if not driver:
        if driver_class:
            raise SpecError(f"{where}: {name} has a driver_class but no driver (shell name)")
        return ""
    if not re.match(r"^[a-z][a-z0-9_]*$", driver):
        raise SpecError(f"{where}: {name} driver {driver!r} is not a shell command name")
    if driver_class:
        if not _is_target(driver_class):
            raise SpecError(f"{where}: {name} driver_class {driver_class!r} is not "
                            f"'package.module:Class'")
        return driver_class
    if driver not in DRIVERS:
        raise SpecError(f"{where}: {name} driver {driver!r} unknown (known: "
                        f"{', '.join(sorted(DRIVERS))}); give its driver_class")
    return DRIVERS[driver]


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
        commands: dict[str, str] = {}

        def driver(name: str, drv: str, cls: str, stage: str) -> None:
            _driver_target(where, name, drv, cls, stage)
            if drv and drv in commands:
                raise SpecError(f"{where}: driver {drv} named by both {commands[drv]} and {name}")
            commands[drv] = name

        for bus in self.spi:
            for dev in bus.devices:
                driver(dev.name, dev.driver, dev.driver_class, dev.stage)
                if dev.model not in MODELS and not _is_target(dev.model):
                    raise SpecError(f"{where}: {bus.name} device {dev.name} has unknown model "
                                    f"{dev.model!r}")
                if dev.name in names:
                    raise SpecError(f"{where}: device name {dev.name} used twice")
                names.add(dev.name)
                claim(dev.cs, f"{dev.name} chip select")
                for p in dev.drdy:
                    claim(p, f"{dev.name} data-ready")
        for ibus in self.i2c:
            addrs: set[int] = set()
            for idev in ibus.devices:
                driver(idev.name, idev.driver, idev.driver_class, idev.stage)
                if idev.model not in MODELS and not _is_target(idev.model):
                    raise SpecError(f"{where}: {ibus.name} device {idev.name} has unknown model "
                                    f"{idev.model!r}")
                for p in idev.drdy:
                    claim(p, f"{idev.name} data-ready")
                if not 0x08 <= idev.address <= 0x77:
                    raise SpecError(f"{where}: {idev.name} address 0x{idev.address:02X} is "
                                    f"reserved or not 7-bit")
                if idev.address in addrs:
                    raise SpecError(f"{where}: {ibus.name} address 0x{idev.address:02X} used twice")
                addrs.add(idev.address)
                if idev.name in names:
                    raise SpecError(f"{where}: device name {idev.name} used twice")
                names.add(idev.name)
        seen_uarts: set[str] = set()
        for u in self.uarts:
            if u.name in seen_uarts:
                raise SpecError(f"{where}: UART {u.name} listed twice")
            seen_uarts.add(u.name)
            if u.external_model is not None and u.external_model not in MODELS \
                    and not _is_target(u.external_model):
                raise SpecError(f"{where}: {u.name} external model {u.external_model!r} unknown")
            driver(u.role, u.driver, u.driver_class, u.stage)
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

    # -- devices and their drivers ---------------------------------------------------------

    def drivers(self, *stages: str) -> list[DriverStart]:
        """The drivers this board starts, in spec order (SPI buses, I2C buses, then the UARTs'
        connector devices, each in spec order), of the given stages (none given: all)."""
        for st in stages:
            if st not in STAGES:
                raise SpecError(f"board {self.name}: no driver stage {st!r} (stages: "
                                f"{', '.join(STAGES)})")
        where = f"board {self.name}"
        out: list[DriverStart] = []
        entries: list[tuple[str, str, str, tuple[str, ...], str]] = []
        for bus in self.spi:
            entries += [(d.name, d.driver, d.driver_class, d.driver_args, d.stage)
                        for d in bus.devices]
        for ibus in self.i2c:
            entries += [(d.name, d.driver, d.driver_class, d.driver_args, d.stage)
                        for d in ibus.devices]
        entries += [(u.role, u.driver, u.driver_class, u.driver_args, u.stage)
                    for u in self.uarts if u.external_model is not None]
        for name, drv, cls, args, st in entries:
            if drv and (not stages or st in stages):
                out.append(DriverStart(name, drv, _driver_target(where, name, drv, cls, st),
                                       args, st))
        return out

    def driver_modules(self) -> dict[str, str]:
        """Shell name -> shell module target of every driver of this board."""
        return {d.command: d.target for d in self.drivers()}

    def place(self, name: str) -> DevicePlace:
        """Where device ``name`` (or the device of driver ``name``) sits: :class:`DevicePlace`."""
        for bus in self.spi:
            for dev in bus.devices:
                if name in (dev.name, dev.driver):
                    return DevicePlace(dev.name, "spi", bus.name, bus.number, cs=dev.cs,
                                       drdy=dev.drdy, rotation=dev.rotation)
        for ibus in self.i2c:
            for idev in ibus.devices:
                if name in (idev.name, idev.driver):
                    return DevicePlace(idev.name, "i2c", ibus.name, ibus.number,
                                       address=idev.address, external=ibus.external,
                                       drdy=idev.drdy, rotation=idev.rotation)
        for u in self.uarts:
            if u.external_model is not None and name in (u.role, u.driver):
                n = u.device[-1]
                return DevicePlace(u.role, "uart", u.name, int(n) if n.isdigit() else 0,
                                   external=True, device=u.device)
        raise KeyError(f"{self.name} has no device {name!r}")

    def with_device(self, bus: str, device: Device) -> BoardSpecData:
        """This spec with ``device`` added at the end of ``bus`` (validated, as a new board)."""
        if isinstance(device, SpiDevice):
            if bus not in {b.name for b in self.spi}:
                raise SpecError(f"board {self.name}: no SPI bus {bus!r}")
            spi = tuple(replace(b, devices=b.devices + (device,)) if b.name == bus else b
                        for b in self.spi)
            return replace(self, spi=spi)
        if bus not in {b.name for b in self.i2c}:
            raise SpecError(f"board {self.name}: no I2C bus {bus!r}")
        i2c = tuple(replace(b, devices=b.devices + (device,)) if b.name == bus else b
                    for b in self.i2c)
        return replace(self, i2c=i2c)

    def without_device(self, name: str) -> BoardSpecData:
        """This spec without device ``name`` (a bus device, or the device plugged into a
        UART's connector, by its role): its model is not built and its driver not started."""
        spi = tuple(replace(b, devices=tuple(d for d in b.devices if d.name != name))
                    for b in self.spi)
        i2c = tuple(replace(b, devices=tuple(d for d in b.devices if d.name != name))
                    for b in self.i2c)
        uarts = tuple(replace(u, external_model=None, driver="", driver_class="",
                              driver_args=()) if u.role == name and u.external_model else u
                      for u in self.uarts)
        out = replace(self, spi=spi, i2c=i2c, uarts=uarts)
        if out == self:
            raise SpecError(f"board {self.name}: no device {name!r} to remove")
        return out

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
                      about="6-axis IMU, INT on PD15", driver="mpu6000"),
            SpiDevice("l3gd20", "l3gd20", cs="PC13", drdy=("PB0",), about="gyro, DRDY/INT2",
                      driver="l3gd20"),
            SpiDevice("lsm303d", "lsm303d", cs="PC15", drdy=("PB4", "PB1"),
                      about="accel (INT1 PB4) + mag (INT2 PB1)", driver="lsm303d"),
            SpiDevice("ms5611", "ms5611", cs="PD7", about="barometer", driver="ms5611",
                      stage="baro"),
        )),
        SpiBusSpec("SPI2", 2, 42_000_000, (
            SpiDevice("fram", "fm25v01", cs="PD10", about="16 KiB FRAM: parameters, dataman",
                      driver="mtd", stage="storage"),
        )),
    ),
    i2c=(
        I2cBusSpec("I2C1", 1, 400_000, external=True, devices=(
            I2cDevice("hmc5883", "hmc5883", 0x1E, external=True,
                      about="compass in the GPS module", driver="hmc5883", driver_args=("-X",)),
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
                 about="GPS port: u-blox M8 module", driver="gps",
                 driver_args=("-d", "/dev/ttyS3")),
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


#: The airspeed sensor of a fixed-wing's FMU: a TE MS4525DO (+-1 psi, output type A) at 0x28 on the
#: external I2C connector, as the Pixhawk airspeed kits plug in. Not on the standard board (a
#: quadrotor has none): ``FMU_V2.with_device("I2C1", MS4525DO_AIRSPEED)`` is the variant (a
#: plane's airframe adds it by name: ``FmuV2Board(extra_devices=("ms4525",))``).
MS4525DO_AIRSPEED = I2cDevice("ms4525", "ms4525do", 0x28, external=True,
                              about="airspeed sensor (differential pressure) on the external I2C",
                              driver="ms4525_airspeed")

#: Devices an FMUv2 may carry beyond the stock set, by name -> (bus, entry): what an airframe
#: adds (``hil.airframes.HostAirframe.fmu_devices``). Names, not specs, cross to the board's
#: process, so that a lockstep trace can record the board's arguments as plain data.
FMU_V2_OPTIONAL: dict[str, tuple[str, Device]] = {"ms4525": ("I2C1", MS4525DO_AIRSPEED)}


def with_optional_devices(spec: BoardSpecData, names: tuple[str, ...]) -> BoardSpecData:
    """``spec`` with the optional devices ``names`` (keys of :data:`FMU_V2_OPTIONAL`) added."""
    for name in names:
        try:
            bus, device = FMU_V2_OPTIONAL[name]
        except KeyError:
            raise SpecError(f"no optional device {name!r}; known: "
                            f"{', '.join(sorted(FMU_V2_OPTIONAL))}") from None
        spec = spec.with_device(bus, device)
    return spec


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
