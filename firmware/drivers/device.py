"""What every PX4-style device driver shares: the device id, perf counters, life cycle.

A driver is a work item with a state machine (reset -> wait -> configure -> read) whose steps
end by scheduling the next run, as in PX4's modern drivers. ``start()`` probes the device over
its bus; a wrong or missing ID makes the driver refuse to start and say why in dmesg.

Drivers reach their chip through a *bus handle*, a small typed protocol rather than a class of
the emulated board, so the same driver code runs on a real Linux bus (``hil/hostbus.py`` adapts
an ``smbus2.SMBus`` or a ``spidev.SpiDev`` to these protocols; ``hil hostdrv`` runs a driver on
one):

* :class:`I2cBusHandle`: one combined transaction per call, ``transfer(addr, write, read_len)``
  (write phase, repeated START, read phase: one Linux ``I2C_RDWR``), returning ``(0, data)`` or
  ``(-errno, b"")``; a NAK or any bus error is a result, never an exception, so a driver counts
  it. ``board.i2c.I2cBus`` is one.
* :class:`I2cDeviceHandle`: the same with the address bound (``bus.device(addr)``), which is what
  a driver holds. ``board.i2c.I2cHandle`` is one, :class:`I2cAddress` binds any bus handle.
* :class:`SpiDeviceHandle`: one chip select, full duplex ``transfer(tx) -> rx`` (CS held for the
  call, as spidev's ``xfer2``), with the ``mode`` and ``max_speed_hz`` spidev has.
  ``board.spi.SpiHandle`` is one.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from mypy_extensions import mypyc_attr

from firmware.platform import Platform
from firmware.platform.perf import PC_COUNT, PC_ELAPSED, PC_INTERVAL, PerfCounter
from firmware.platform.uorb import Publication
from firmware.platform.workqueue import WorkItem

__all__ = ["DeviceId", "BUS_TYPE_I2C", "BUS_TYPE_SPI", "BUS_TYPE_SERIAL", "I2cAddress",
           "I2cBusHandle", "I2cDeviceHandle", "SensorDriver", "SpiDeviceHandle"]

BUS_TYPE_UNKNOWN, BUS_TYPE_I2C, BUS_TYPE_SPI, BUS_TYPE_UAVCAN, BUS_TYPE_SIMULATION, \
    BUS_TYPE_SERIAL, BUS_TYPE_MAVLINK = range(7)


class I2cDeviceHandle(Protocol):
    """One I2C device as a driver sees it: its 7-bit address and combined transactions."""

    addr: int

    def transfer(self, write: bytes = b"", read_len: int = 0) -> tuple[int, bytes]:
        """Write ``write``, repeated START, read ``read_len`` bytes; ``(0, data)`` or
        ``(-errno, b"")`` (a NAK, a bus error): never raises for the bus's sake."""
        ...


class I2cBusHandle(Protocol):
    """An I2C controller: the emulated one (``board.i2c.I2cBus``) or a host adapter."""

    def transfer(self, addr: int, write: bytes = b"", read_len: int = 0) -> tuple[int, bytes]:
        """:meth:`I2cDeviceHandle.transfer` at ``addr``."""
        ...


class SpiDeviceHandle(Protocol):
    """One SPI chip select: spidev's ``mode`` and ``max_speed_hz``, and a full-duplex
    transfer that holds CS for the whole call and returns as many bytes as it sent."""

    mode: int
    max_speed_hz: int

    def transfer(self, tx: bytes) -> bytes:
        ...


class I2cAddress:
    """Any :class:`I2cBusHandle` with one address bound: a driver's :class:`I2cDeviceHandle`."""

    __slots__ = ("addr", "bus")

    def __init__(self, bus: I2cBusHandle, addr: int) -> None:
        if type(addr) is not int or not 0 <= addr <= 0x7F:
            raise ValueError(f"I2C address must be a 7-bit int, got {addr!r}")
        self.bus = bus
        self.addr = addr

    def transfer(self, write: bytes = b"", read_len: int = 0) -> tuple[int, bytes]:
        return self.bus.transfer(self.addr, write, read_len)

    def __repr__(self) -> str:
        return f"<I2cAddress {self.bus!r}@0x{self.addr:02x}>"


@dataclass(frozen=True)
class DeviceId:
    """PX4's 32-bit device id: bus type (3 bits), bus (5), address (8), device type (8)."""

    bus_type: int
    bus: int
    address: int
    devtype: int

    @property
    def value(self) -> int:
        return ((self.bus_type & 0x7) | ((self.bus & 0x1F) << 3) | ((self.address & 0xFF) << 8)
                | ((self.devtype & 0xFF) << 16))

    @classmethod
    def decode(cls, value: int) -> DeviceId:
        return cls(value & 0x7, (value >> 3) & 0x1F, (value >> 8) & 0xFF, (value >> 16) & 0xFF)


@mypyc_attr(allow_interpreted_subclasses=True)
class SensorDriver(WorkItem):
    """Base of sensor drivers: perf counters, start/stop/status, messages in PX4's words."""

    def __init__(self, platform: Platform, name: str, wq: str) -> None:
        super().__init__(platform, name, wq)
        #: what this driver took from the platform, so that whoever owns it (its shell module,
        #: :class:`firmware.drivers.modules.DriverModule`) can give it back at ``stop``: a
        #: restarted driver then has one set of counters and its old uORB instance again
        self.own_perf: list[PerfCounter] = []
        self.own_pubs: list[Publication] = []
        self.perf_cycle = self.perf_alloc(PC_ELAPSED, "read")
        self.perf_interval = self.perf_alloc(PC_INTERVAL, "run interval")
        self.perf_bad_register = self.perf_alloc(PC_COUNT, "bad register")
        self.perf_bad_transfer = self.perf_alloc(PC_COUNT, "bad transfer")
        self.perf_missed = self.perf_alloc(PC_COUNT, "missed samples")
        self.running = False
        self.error_count = 0

    def perf_alloc(self, kind: str, what: str) -> PerfCounter:
        """A perf counter named ``"<driver>: <what>"`` (PX4's names), recorded in ``own_perf``."""
        pc = self.platform.perf.alloc(kind, f"{self.name}: {what}")
        self.own_perf.append(pc)
        return pc

    def advertise(self, topic: str, instance: int) -> Publication:
        """Instance ``instance`` of ``topic`` (a fixed one), recorded in ``own_pubs``."""
        pub = self.platform.orb.advertise(topic, instance)
        self.own_pubs.append(pub)
        return pub

    def advertise_multi(self, topic: str) -> Publication:
        """The first free instance of ``topic`` (redundant sensors), recorded in ``own_pubs``."""
        pub = self.platform.orb.advertise_multi(topic)
        self.own_pubs.append(pub)
        return pub

    # Drivers implement probe() (return None when OK, else the reason) and _start().
    def probe(self) -> str | None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _start(self) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def start(self) -> bool:
        """Probe and start; False (and a message in dmesg) if the device is not right."""
        return self.try_start() is None

    def try_start(self) -> str | None:
        """Probe and start: None when running, else the reason it did not start (also in
        dmesg), handed to the caller directly (``mpu6000 start`` prints it)."""
        if self.running:
            return None
        why = self.probe()
        if why is not None:
            self.platform.error(self.name, f"not starting: {why}")
            return why
        self.running = True
        self._start()
        self.platform.info(self.name, "started")
        return None

    def stop(self) -> None:
        self.schedule_clear()
        self.running = False

    def status(self) -> str:
        lines = [f"{self.name}: {'running' if self.running else 'stopped'} on {self.wq.name}"]
        for pc in (self.perf_cycle, self.perf_interval, self.perf_bad_register,
                   self.perf_bad_transfer, self.perf_missed):
            lines.append("  " + pc.summary())
        return "\n".join(lines)
