"""The shell face of the device drivers: ``mpu6000 start``, ``gps start -d /dev/ttyS3``, ...

A driver module finds its bus handle and pins on the board it runs on (``system.hw``: the
board object, which offers ``spi_handle(device)``, ``gpio``, ``i2c``, ``uart_by_device(tty)``),
builds the driver, and probes it. A missing or wrong chip makes ``start`` fail with the
driver's own reason, as ``mpu6000 start`` prints "no instance started" on a real board.
"""

from __future__ import annotations

from typing import Any, ClassVar

from firmware.platform.module import ModuleBase, ModuleError, UsageError

__all__ = ["DriverModule", "Mpu6000Module", "L3gd20Module", "Lsm303dModule", "Ms5611Module",
           "Hmc5883Module", "GpsModule", "MtdModule"]


class DriverModule(ModuleBase):
    """A module owning one driver object with ``start() -> bool``, ``stop()``, ``status()``."""

    OPTIONS: ClassVar[str] = ""  # single-letter flags accepted before/after ``start``

    def __init__(self, system: Any, args: list[str] | tuple = ()) -> None:
        super().__init__(system, args)
        self.driver: Any = None
        self.opts: dict[str, str | bool] = {}

    @classmethod
    def instantiate(cls, system: Any, args: list[str]) -> DriverModule:
        inst = cls(system, args)
        i = 0
        while i < len(args):
            a = args[i]
            if not a.startswith("-") or len(a) != 2 or a[1] not in cls.OPTIONS.replace(":", ""):
                raise UsageError(f"unknown option {a!r}")
            key = a[1]
            takes_value = f"{key}:" in cls.OPTIONS
            if takes_value:
                if i + 1 >= len(args):
                    raise UsageError(f"option {a} needs a value")
                inst.opts[key] = args[i + 1]
                i += 2
            else:
                inst.opts[key] = True
                i += 1
        return inst

    @property
    def hw(self) -> Any:
        hw = getattr(self.system, "hw", None)
        if hw is None:
            raise ModuleError("this system has no board hardware")
        return hw

    def make_driver(self) -> Any:  # pragma: no cover - abstract
        raise NotImplementedError

    def _start(self) -> None:
        self.driver = self.make_driver()
        if not self.driver.start():
            why = next((text for _t, sev, mod, text in reversed(self.platform.dmesg)
                        if mod == self.driver.name and sev <= 3), "probe failed")
            self.driver.stop()
            raise ModuleError(f"no instance started ({why})")

    def _stop(self) -> None:
        if self.driver is not None:
            self.driver.stop()

    def status_lines(self) -> list[str]:
        return self.driver.status().splitlines() if self.driver is not None else []


class Mpu6000Module(DriverModule):
    NAME = "mpu6000"
    DESCRIPTION = ("InvenSense MPU6000 IMU on SPI1 (accel + gyro, 8 kHz FIFO read at "
                   "IMU_GYRO_RATEMAX)")

    def make_driver(self) -> Any:
        from firmware.drivers.imu.mpu6000 import Mpu6000Driver, gyro_rate_limit

        return Mpu6000Driver(self.platform, self.hw.spi_handle("mpu6000"),
                             drdy_pin=self.hw.gpio.pin("PD15"),
                             max_rate_hz=gyro_rate_limit(getattr(self.system, "params", None)))


class L3gd20Module(DriverModule):
    NAME = "l3gd20"
    DESCRIPTION = "ST L3GD20 gyroscope on SPI1 (760 Hz, DRDY on PB0)"

    def make_driver(self) -> Any:
        from firmware.drivers.imu.l3gd20 import L3gd20Driver

        return L3gd20Driver(self.platform, self.hw.spi_handle("l3gd20"),
                            drdy_pin=self.hw.gpio.pin("PB0"))


class Lsm303dModule(DriverModule):
    NAME = "lsm303d"
    DESCRIPTION = "ST LSM303D accelerometer + magnetometer on SPI1 (polled)"

    def make_driver(self) -> Any:
        from firmware.drivers.imu.lsm303d import Lsm303dDriver

        return Lsm303dDriver(self.platform, self.hw.spi_handle("lsm303d"))


class Ms5611Module(DriverModule):
    NAME = "ms5611"
    DESCRIPTION = "MEAS MS5611 barometer on SPI1"

    def make_driver(self) -> Any:
        from firmware.drivers.barometer.ms5611 import Ms5611Driver

        return Ms5611Driver(self.platform, self.hw.spi_handle("ms5611"))


class Hmc5883Module(DriverModule):
    NAME = "hmc5883"
    DESCRIPTION = "Honeywell HMC5883L magnetometer (-X: external I2C1, -I: internal I2C2)"
    OPTIONS = "XIT"
    USAGE = ("-X  external bus (the GPS module's compass, default)", "-I  internal bus",
             "-T  run the self-test at start")

    def make_driver(self) -> Any:
        from firmware.drivers.magnetometer.hmc5883 import Hmc5883Driver

        bus = 2 if self.opts.get("I") else 1
        return Hmc5883Driver(self.platform, self.hw.i2c[f"I2C{bus}"].device(0x1E), bus=bus,
                             external=bus == 1, self_test=bool(self.opts.get("T")))


class GpsModule(DriverModule):
    NAME = "gps"
    DESCRIPTION = "u-blox GPS driver with baud detection and UBX configuration"
    OPTIONS = "d:"
    USAGE = ("-d DEV  serial device (default /dev/ttyS3, the GPS port)",)

    def make_driver(self) -> Any:
        from firmware.drivers.gps.gps import GpsDriver

        dev = str(self.opts.get("d", "/dev/ttyS3"))
        uart = self.hw.uart_by_device(dev)
        if uart is None:
            raise ModuleError(f"no serial device {dev}")
        return GpsDriver(self.platform, uart, tty=dev.rsplit("/", 1)[-1])


class MtdModule(DriverModule):
    NAME = "mtd"
    DESCRIPTION = "FM25V01 FRAM on SPI2: parameter and waypoint partitions"

    def make_driver(self) -> Any:
        from firmware.drivers.mtd.fram import FramMtd

        return FramMtd(self.platform, self.hw.spi_handle("fram"))

    def _start(self) -> None:
        self.driver = self.make_driver()
        if not self.driver.start():
            raise ModuleError("no FRAM found on SPI2")

    def _stop(self) -> None:
        self.driver.running = False

    def partition(self, name: str) -> Any:
        return self.driver.partition(name)
