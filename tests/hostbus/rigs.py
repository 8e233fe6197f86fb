"""Rigs shared by the host-bus tests: an HMC5883/MS5611 on an emulated bus with its driver, a
real ``smbus2.SMBus`` whose ``I2C_RDWR`` ioctl is answered by an emulated bus, and recording
fakes of an SMBus and a SpiDev."""

from __future__ import annotations

import errno
import os
from collections.abc import Callable
from typing import Any

import smbus2.smbus2
from smbus2 import SMBus, i2c_msg
from smbus2.smbus2 import I2C_RDWR

from board.i2c import I2cBus
from board.kernel import Kernel
from board.spi import SpiBus
from firmware.drivers.barometer.ms5611 import Ms5611Driver
from firmware.drivers.magnetometer.hmc5883 import Hmc5883Driver
from firmware.platform import Platform
from firmware.platform.uorb import TopicNode
from hil.smbus_emulated import EmulatedSMBus
from peripherals.errors import rng_for
from peripherals.hmc5883 import Hmc5883
from peripherals.ms5611 import Ms5611
from peripherals.physics import Environment

MS = 1_000_000


def environment() -> Environment:
    return Environment(pressure_pa=97_500.0, board_temperature_c=28.5,
                       mag_gauss=(0.18, -0.07, 0.41))


def record_publications(kernel: Kernel, topic: str) -> tuple[list[tuple[int, bytes]], Any]:
    """(list that fills with (publish time ns, packed message) of ``topic``, undo function)."""
    out: list[tuple[int, bytes]] = []
    original = TopicNode.publish

    def publish(node: TopicNode, msg: Any) -> None:
        original(node, msg)
        if node.name == topic and node._kernel is kernel:
            out.append((kernel.now_ns + kernel.busy_ns, msg.pack()))

    TopicNode.publish = publish  # type: ignore[method-assign]

    def undo() -> None:
        TopicNode.publish = original  # type: ignore[method-assign]

    return out, undo


def run_mag(handle_for: Callable[[I2cBus], Any], seed: int = 5, duration_ns: int = 400 * MS,
            ) -> tuple[list[tuple[int, bytes]], Hmc5883Driver, Hmc5883]:
    """The HMC5883 driver on ``handle_for(emulated I2C1)`` for ``duration_ns``: what it
    published (time, bytes), the driver and the chip."""
    k = Kernel("hostbus")
    p = Platform(k)
    bus = I2cBus(k, "I2C1", clock_hz=400_000)
    chip = Hmc5883(k, environment(), rng_for(seed, "hmc5883"))
    bus.attach(0x1E, chip)
    published, undo = record_publications(k, "sensor_mag")
    try:
        drv = Hmc5883Driver(p, handle_for(bus), bus=1)
        assert drv.start(), p.dmesg_text()
        k.run(duration_ns)
    finally:
        undo()
    return published, drv, chip


def run_baro(handle_for: Callable[[Any], Any], seed: int = 5, duration_ns: int = 300 * MS,
             ) -> tuple[list[tuple[int, bytes]], Ms5611Driver]:
    """The MS5611 driver on ``handle_for(emulated SPI1 chip select)``."""
    k = Kernel("hostbus")
    p = Platform(k)
    spi = SpiBus(k, "SPI1", pclk_hz=84_000_000)
    spi.attach("PD7", Ms5611(k, environment(), rng_for(seed, "ms5611")))
    published, undo = record_publications(k, "sensor_baro")
    try:
        drv = Ms5611Driver(p, handle_for(spi.device("PD7", mode=3, clock_hz=1_000_000)))
        assert drv.start(), p.dmesg_text()
        k.run(duration_ns)
    finally:
        undo()
    return published, drv


def real_smbus_on(bus: I2cBus, monkeypatch: Any) -> SMBus:
    """smbus2's own ``SMBus`` class, unchanged, with the one system call it makes for
    ``i2c_rdwr`` (``ioctl(fd, I2C_RDWR, i2c_rdwr_ioctl_data)``) answered by ``bus``: the
    messages the kernel would get are handed, as smbus2 built them, to the emulated adapter."""
    emulated = EmulatedSMBus(bus)

    def ioctl(fd: int, request: int, arg: Any = 0, *rest: Any) -> int:
        if request != I2C_RDWR:
            raise OSError(errno.ENOTTY, f"fake ioctl: request 0x{request:x} not modelled")
        emulated.i2c_rdwr(*(arg.msgs[i] for i in range(arg.nmsgs)))
        return 0

    monkeypatch.setattr(smbus2.smbus2, "ioctl", ioctl)
    sm = SMBus()  # no bus: nothing opened
    sm.fd = os.open(os.devnull, os.O_RDONLY)  # what close() will close
    return sm


class RecordingSMBus:
    """Records every call (name, arguments) and answers from ``delegate`` (an SMBus-like) or,
    when ``fail`` says so for that call number, raises ``OSError(fail_errno)``."""

    def __init__(self, delegate: Any = None, fail: Callable[[int], bool] = lambda n: False,
                 fail_errno: int = errno.EREMOTEIO) -> None:
        self.delegate = delegate
        self.fail = fail
        self.fail_errno = fail_errno
        self.calls: list[tuple[str, tuple]] = []

    def _call(self, name: str, *args: Any) -> Any:
        self.calls.append((name, args))
        if self.fail(len(self.calls)):
            raise OSError(self.fail_errno, os.strerror(self.fail_errno))
        if self.delegate is None:
            return None
        return getattr(self.delegate, name)(*args)

    def i2c_rdwr(self, *msgs: i2c_msg) -> None:
        self._call("i2c_rdwr", *msgs)

    def write_quick(self, addr: int) -> None:
        self._call("write_quick", addr)

    def close(self) -> None:
        self._call("close")


def describe(call: tuple[str, tuple]) -> tuple:
    """A recorded call in plain values: i2c_msg -> ("w"/"r", addr, bytes or length)."""
    name, args = call
    out = []
    for a in args:
        if isinstance(a, i2c_msg):
            out.append(("r", a.addr, a.len) if a.flags & 1 else ("w", a.addr, bytes(a)))
        else:
            out.append(a)
    return (name, *out)


class RecordingSpiDev:
    """spidev's API on the emulated chip select ``dev`` (``xfer2`` through its own ``xfer2``),
    recording attribute writes and transfers; ``fail(n)`` makes transfer n raise ``OSError``."""

    def __init__(self, dev: Any, fail: Callable[[int], bool] = lambda n: False) -> None:
        object.__setattr__(self, "_dev", dev)
        object.__setattr__(self, "log", [])
        object.__setattr__(self, "fail", fail)
        object.__setattr__(self, "n", 0)

    def __setattr__(self, name: str, value: Any) -> None:
        self.log.append(("set", name, value))
        setattr(self._dev, name, value)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._dev, name)

    def xfer2(self, values: list[int]) -> list[int]:
        object.__setattr__(self, "n", self.n + 1)
        self.log.append(("xfer2", list(values)))
        if self.fail(self.n):
            raise OSError(errno.EIO, "spidev: transfer failed")
        return self._dev.xfer2(values)
