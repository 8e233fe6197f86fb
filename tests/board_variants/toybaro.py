"""A toy I2C barometer and its driver: the smallest device a board variant can add.

The chip has two registers that matter: WHO_AM_I (0x0F, reads 0x5A) and one data register,
PRESS (0x00..0x02: the static pressure in 1/16 Pa, 24 bits big endian, sampled when a read
of it starts). The driver probes WHO_AM_I, then reads PRESS every 20 ms and publishes
``sensor_baro``. Neither is part of the product: the board-variant tests and the example of
docs/driver_guide.md ("Adding a device") put them on an FMUv2 through its spec alone.
"""

from __future__ import annotations

from typing import Any, Final

from board.i2c import I2cTarget
from board.kernel import Kernel
from firmware.drivers.device import BUS_TYPE_I2C, DeviceId, I2cDeviceHandle, SensorDriver
from firmware.drivers.modules import DriverModule
from firmware.platform import Platform
from peripherals.physics import Environment
from peripherals.regs import Reg, RegisterFile

ADDRESS: Final = 0x77          # the usual address of such a chip (the spec says where it is)
WHO_AM_I: Final = 0x0F
WHO_AM_I_VALUE: Final = 0x5A
PRESS: Final = 0x00
LSB_PER_PA: Final = 16
DEVTYPE: Final = 0xF0          # a device type no real driver uses
INTERVAL_US: Final = 20_000

REGISTERS: Final = [
    Reg(PRESS, "PRESS_MSB", access="r", doc="pressure, 1/16 Pa, bits 23:16"),
    Reg(PRESS + 1, "PRESS_CSB", access="r", doc="bits 15:8"),
    Reg(PRESS + 2, "PRESS_LSB", access="r", doc="bits 7:0"),
    Reg(WHO_AM_I, "WHO_AM_I", reset=WHO_AM_I_VALUE, access="r"),
]


class ToyBaro(I2cTarget):
    """The chip: a register pointer written first, then auto-incrementing reads."""

    def __init__(self, kernel: Kernel, env: Environment, rng: Any, name: str = "toybaro",
                 drdy_pin: Any = None) -> None:
        self.kernel = kernel
        self.env = env
        self.name = name
        self.regs = RegisterFile(name, REGISTERS, size=16)
        self.pointer = 0
        self.samples = 0
        self._pointer_next = False

    def _start(self, t_ns: int, is_read: bool) -> bool:
        self._pointer_next = not is_read
        if is_read and self.pointer == PRESS:  # a read of PRESS latches a fresh sample
            counts = round(self.env.pressure_pa * LSB_PER_PA) & 0xFFFFFF
            for i, reg in enumerate(("PRESS_MSB", "PRESS_CSB", "PRESS_LSB")):
                self.regs[reg] = counts >> (16 - 8 * i)
            self.samples += 1
        return True

    def _write(self, t_ns: int, data: bytes) -> int:
        for b in data:
            if self._pointer_next:
                self.pointer = b & 0x0F
                self._pointer_next = False
            else:
                self.regs.write(self.pointer, b)
                self.pointer = (self.pointer + 1) & 0x0F
        return len(data)

    def _read(self, t_ns: int, n: int) -> bytes:
        out = self.regs.read_block(self.pointer, n)
        self.pointer = (self.pointer + n) & 0x0F
        return out


class ToyBaroDriver(SensorDriver):
    """Probe WHO_AM_I, then read PRESS on an interval and publish ``sensor_baro``."""

    def __init__(self, platform: Platform, i2c: I2cDeviceHandle, bus: int,
                 name: str = "toybaro") -> None:
        super().__init__(platform, name, f"wq:I2C{bus}")
        self.i2c = i2c
        self.device_id = DeviceId(BUS_TYPE_I2C, bus, i2c.addr, DEVTYPE).value
        self._pub: Any = None
        self._msg = platform.orb.new("sensor_baro", device_id=self.device_id)

    def probe(self) -> str | None:
        status, data = self.i2c.transfer(bytes((WHO_AM_I,)), 1)
        if status:
            return f"no ACK at I2C address 0x{self.i2c.addr:02X}"
        if data[0] != WHO_AM_I_VALUE:
            return f"WHO_AM_I 0x{data[0]:02X}, expected 0x{WHO_AM_I_VALUE:02X}"
        return None

    def _start(self) -> None:
        self._pub = self.advertise_multi("sensor_baro")
        self.schedule_on_interval(INTERVAL_US)

    def run(self) -> None:
        self.perf_interval.count()
        status, data = self.i2c.transfer(bytes((PRESS,)), 3)
        if status:
            self.perf_bad_transfer.count()
            self.error_count += 1
            return
        msg = self._msg
        msg.timestamp = msg.timestamp_sample = self.platform.time_us()
        msg.pressure = int.from_bytes(data, "big") / LSB_PER_PA
        msg.error_count = self.error_count
        self._pub.publish(msg)


class ToyBaroModule(DriverModule):
    """``toybaro start``: the driver for the device the board's spec puts on a bus."""

    NAME = "toybaro"
    DESCRIPTION = "toy I2C barometer (tests/board_variants)"

    @classmethod
    def build(cls, platform: Any, hw: Any, place: Any, opts: dict[str, str | bool],
              params: Any) -> Any:
        return ToyBaroDriver(platform, hw.i2c[place.bus].device(place.address),
                             bus=place.bus_number, name=place.name)
