"""The shell face of the device drivers: ``mpu6000 start``, ``gps start -d /dev/ttyS3``, ...

A driver module finds where its device sits in the board's spec (``system.hw.spec.place(name)``:
bus, address or chip select, data-ready pins, rotation: :class:`board.specs.DevicePlace`), takes
the bus handle and pins from the board it runs on (``system.hw``: the board object, which offers
``spi_handle(device)``, ``gpio``, ``i2c``, ``uart_by_device(tty)``), builds the driver and starts
it. Nothing about where a device is wired is written here: it is one entry in the spec.

The module owns its driver's life cycle: the driver is its work item, and the perf counters
and uORB advertisements the driver takes are the module's (``SensorDriver.own_perf`` and
``own_pubs`` are the module's own lists), so ``stop`` releases them and ``start`` after
``stop`` publishes on the same uORB instance again with one set of counters. A missing or
wrong chip makes ``start`` fail with the driver's own reason (``SensorDriver.try_start``), as
``mpu6000 start`` prints "no instance started" on a real board.

``firmware="sensors"`` boards start the same drivers without a shell: :meth:`DriverModule.build`
is what both use.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, ClassVar

from firmware.platform.module import ModuleBase, ModuleError, UsageError

if TYPE_CHECKING:
    from board.gpio import Pin
    from board.protocols import BoardHardware
    from board.specs import DevicePlace
    from firmware.platform import Platform
    from firmware.platform.params import Params
    from firmware.system import System

__all__ = ["DriverModule", "Mpu6000Module", "L3gd20Module", "Lsm303dModule", "Ms5611Module",
           "Hmc5883Module", "GpsModule", "MtdModule", "Ms4525AirspeedModule"]


class DriverModule(ModuleBase):
    """A module owning one driver object with ``try_start() -> str | None``, ``stop()``,
    ``status()`` (a :class:`~firmware.drivers.device.SensorDriver`).

    Subclasses implement :meth:`build`: the driver for a device at a
    :class:`~board.specs.DevicePlace` on a board, from the start options and parameters.
    """

    OPTIONS: ClassVar[str] = ""  # single-letter flags accepted before/after ``start``

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.driver: Any = None
        self.opts: dict[str, str | bool] = {}

    @classmethod
    def instantiate(cls, system: System, args: Sequence[str]) -> DriverModule:
        inst = cls(system, args)
        inst.opts = cls.parse_options(args)
        return inst

    @classmethod
    def parse_options(cls, args: Sequence[str]) -> dict[str, str | bool]:
        """``OPTIONS`` flags (``X``, or ``d:`` with a value) from a start command line."""
        opts: dict[str, str | bool] = {}
        i = 0
        while i < len(args):
            a = args[i]
            if not a.startswith("-") or len(a) != 2 or a[1] not in cls.OPTIONS.replace(":", ""):
                raise UsageError(f"unknown option {a!r}")
            key = a[1]
            if f"{key}:" in cls.OPTIONS:
                if i + 1 >= len(args):
                    raise UsageError(f"option {a} needs a value")
                opts[key] = args[i + 1]
                i += 2
            else:
                opts[key] = True
                i += 1
        return opts

    @property
    def hw(self) -> BoardHardware:
        hw: BoardHardware | None = getattr(self.system, "hw", None)
        if hw is None:
            raise ModuleError("this system has no board hardware")
        return hw

    @classmethod
    def build(cls, platform: Platform, hw: BoardHardware, place: DevicePlace,
              opts: dict[str, str | bool],
              params: Params | None) -> Any:  # pragma: no cover - abstract
        """The driver for the device at ``place`` (:class:`board.specs.DevicePlace`) on the
        board ``hw``; not started."""
        raise NotImplementedError

    def make_driver(self) -> Any:
        hw = self.hw
        try:
            place = hw.spec.place(self.name)
        except KeyError:
            raise ModuleError(f"no {self.name} device in the board's spec") from None
        return self.build(self.platform, hw, place, self.opts,
                          getattr(self.system, "params", None))

    def _start(self) -> None:
        driver = self.driver = self.make_driver()
        # The driver's resources are this module's: released by ModuleBase.stop (also when
        # this start fails), whatever the driver takes later (a lazy advertisement).
        self.add_work_item(driver)
        own_perf = getattr(driver, "own_perf", None)
        if own_perf is not None:
            self.perf_counters = own_perf
        own_pubs = getattr(driver, "own_pubs", None)
        if own_pubs is not None:
            self.publications = own_pubs
        why = driver.try_start()
        if why is not None:
            driver.stop()
            raise ModuleError(f"no instance started ({why})")

    def _stop(self) -> None:
        if self.driver is not None:
            self.driver.stop()

    def status_lines(self) -> list[str]:
        """The driver's own status, less what the module has printed above it: the perf
        counters (they are the module's) and the driver's ``NAME: running on WQ`` header (the
        module's work item line says it), so ``DRIVER status`` shows each fact once."""
        driver = self.driver
        if driver is None:
            return []
        shown = {pc.summary() for pc in self.perf_counters}
        wq = getattr(driver, "wq", None)
        if wq is not None:
            shown |= {f"{driver.name}: {state} on {wq.name}" for state in ("running", "stopped")}
        rest = [line for line in driver.status().splitlines() if line.strip() not in shown]
        return textwrap.dedent("\n".join(rest)).splitlines()


def _pin(hw: BoardHardware, place: DevicePlace, i: int = 0) -> Pin | None:
    """The board pin of the device's ``i``-th data-ready line, or None (poll)."""
    return hw.gpio.pin(place.drdy[i]) if len(place.drdy) > i else None


def _rotation(place: DevicePlace) -> dict[str, Any]:
    """The spec's rotation as a keyword, or nothing (the driver's own default)."""
    return {} if place.rotation is None else {"rotation": place.rotation}


class Mpu6000Module(DriverModule):
    NAME = "mpu6000"
    DESCRIPTION = ("InvenSense MPU6000 IMU on SPI1 (accel + gyro, 8 kHz FIFO read at "
                   "IMU_GYRO_RATEMAX)")

    @classmethod
    def build(cls, platform: Platform, hw: BoardHardware, place: DevicePlace,
              opts: dict[str, str | bool], params: Params | None) -> Any:
        from firmware.drivers.imu.mpu6000 import Mpu6000Driver, gyro_rate_limit

        return Mpu6000Driver(platform, hw.spi_handle(place.name), drdy_pin=_pin(hw, place),
                             bus=place.bus_number, max_rate_hz=gyro_rate_limit(params),
                             **_rotation(place))


class L3gd20Module(DriverModule):
    NAME = "l3gd20"
    DESCRIPTION = "ST L3GD20 gyroscope on SPI1 (760 Hz, DRDY on PB0)"

    @classmethod
    def build(cls, platform: Platform, hw: BoardHardware, place: DevicePlace,
              opts: dict[str, str | bool], params: Params | None) -> Any:
        from firmware.drivers.imu.l3gd20 import L3gd20Driver

        return L3gd20Driver(platform, hw.spi_handle(place.name), drdy_pin=_pin(hw, place),
                            bus=place.bus_number, **_rotation(place))


class Lsm303dModule(DriverModule):
    NAME = "lsm303d"
    DESCRIPTION = "ST LSM303D accelerometer + magnetometer on SPI1 (polled)"

    @classmethod
    def build(cls, platform: Platform, hw: BoardHardware, place: DevicePlace,
              opts: dict[str, str | bool], params: Params | None) -> Any:
        from firmware.drivers.imu.lsm303d import Lsm303dDriver

        # polled: PX4's driver does not use INT1/INT2 (the spec wires them for the model)
        return Lsm303dDriver(platform, hw.spi_handle(place.name), **_rotation(place))


class Ms5611Module(DriverModule):
    NAME = "ms5611"
    DESCRIPTION = "MEAS MS5611 barometer on SPI1"

    @classmethod
    def build(cls, platform: Platform, hw: BoardHardware, place: DevicePlace,
              opts: dict[str, str | bool], params: Params | None) -> Any:
        from firmware.drivers.barometer.ms5611 import Ms5611Driver

        return Ms5611Driver(platform, hw.spi_handle(place.name), bus=place.bus_number)


class Hmc5883Module(DriverModule):
    NAME = "hmc5883"
    DESCRIPTION = "Honeywell HMC5883L magnetometer (-X: external I2C1, -I: internal I2C2)"
    OPTIONS = "XIT"
    USAGE = ("-X  external bus (the GPS module's compass, default)", "-I  internal bus",
             "-T  run the self-test at start")

    @classmethod
    def build(cls, platform: Platform, hw: BoardHardware, place: DevicePlace,
              opts: dict[str, str | bool], params: Params | None) -> Any:
        from firmware.drivers.magnetometer.hmc5883 import Hmc5883Driver

        bus_name, bus, external = place.bus, place.bus_number, place.external
        if opts.get("I") or opts.get("X"):  # PX4's bus choice: the spec's address on it
            want_external = not opts.get("I")
            ibus = next((b for b in hw.spec.i2c if b.external == want_external), None)
            if ibus is None:
                raise ModuleError(f"no {'external' if want_external else 'internal'} I2C bus")
            bus_name, bus, external = ibus.name, ibus.number, ibus.external
        return Hmc5883Driver(platform, hw.i2c[bus_name].device(place.address), bus=bus,
                             external=external, self_test=bool(opts.get("T")))


class Ms4525AirspeedModule(DriverModule):
    NAME = "ms4525_airspeed"
    DESCRIPTION = "TE MS4525DO airspeed sensor (differential pressure) on the external I2C"

    @classmethod
    def build(cls, platform: Platform, hw: BoardHardware, place: DevicePlace,
              opts: dict[str, str | bool], params: Params | None) -> Any:
        from firmware.drivers.airspeed.ms4525 import Ms4525Driver

        return Ms4525Driver(platform, hw.i2c[place.bus].device(place.address),
                            bus=place.bus_number, params=params)


class GpsModule(DriverModule):
    NAME = "gps"
    DESCRIPTION = "u-blox GPS driver with baud detection and UBX configuration"
    OPTIONS = "d:"
    USAGE = ("-d DEV  serial device (default /dev/ttyS3, the GPS port)",)

    @classmethod
    def build(cls, platform: Platform, hw: BoardHardware, place: DevicePlace,
              opts: dict[str, str | bool], params: Params | None) -> Any:
        from firmware.drivers.gps.gps import GpsDriver

        dev = str(opts.get("d", place.device))
        uart = hw.uart_by_device(dev)
        if uart is None:
            raise ModuleError(f"no serial device {dev}")
        return GpsDriver(platform, uart, tty=dev.rsplit("/", 1)[-1])


class MtdModule(DriverModule):
    NAME = "mtd"
    DESCRIPTION = "FM25V01 FRAM on SPI2: parameter and waypoint partitions"

    @classmethod
    def build(cls, platform: Platform, hw: BoardHardware, place: DevicePlace,
              opts: dict[str, str | bool], params: Params | None) -> Any:
        from firmware.drivers.mtd.fram import FramMtd

        return FramMtd(platform, hw.spi_handle(place.name))

    def _start(self) -> None:
        self.driver = self.make_driver()
        self.perf_counters = self.driver.own_perf  # the module's: freed at stop
        if not self.driver.start():
            raise ModuleError(f"no FRAM found on {self.hw.spec.place(self.name).bus}")

    def _stop(self) -> None:
        self.driver.running = False

    def partition(self, name: str) -> Any:
        return self.driver.partition(name)
