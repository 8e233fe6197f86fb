"""The project's I2C/SPI drivers on a real Linux bus: smbus2 and spidev as bus handles.

The FMU's drivers reach their chip through the small protocols of
``firmware/drivers/device.py`` (``I2cBusHandle`` / ``I2cDeviceHandle``: a combined
write-then-read transaction that returns ``(status, data)``; ``SpiDeviceHandle``: a full-duplex
transfer). These adapters give a driver such a handle on top of the libraries people use on a
Linux computer:

* :class:`SMBusHandle` wraps an ``smbus2.SMBus`` (``/dev/i2c-N``). Every transaction is one
  ``I2C_RDWR`` ioctl made with smbus2's documented ``i2c_rdwr(i2c_msg.write(...),
  i2c_msg.read(...))``: write phase, repeated START, read phase, as the emulated bus and PX4's
  ``I2C::transfer`` do, so a register read is never split by a STOP that some chips treat as
  the end of the access. An address-only probe is smbus2's ``write_quick``.
* :class:`SpiDevHandle` wraps a ``spidev.SpiDev`` (``/dev/spidevB.C``): ``xfer2`` keeps CS
  asserted for the whole transfer. spidev is not a dependency (it needs Linux headers to
  build); any object with its API (``xfer2``, ``mode``, ``max_speed_hz``) will do, the emulated
  ``board.spi.SpiHandle`` included.

An ``OSError`` from the host bus (a NAK is ``ENXIO``/``EREMOTEIO``/``EIO`` depending on the
adapter, a bus timeout ``ETIMEDOUT``) is a result, never an exception for the driver: I2C gives
``(-errno, b"")``, which the driver counts as a bad transfer; SPI has no status, so a failed
transfer reads as an idle MISO (all 0xFF), which a driver already treats as a missing chip.
Each adapter counts its errors and keeps the last one for ``hil hostdrv``'s report.
"""

from __future__ import annotations

import errno
from typing import Any

from smbus2 import i2c_msg

from firmware.drivers.device import I2cAddress

__all__ = ["SMBusHandle", "SpiDevHandle"]


class SMBusHandle:
    """An ``smbus2.SMBus`` (or any object with its API) as the drivers' ``I2cBusHandle``."""

    def __init__(self, smbus: Any, bus_number: int) -> None:
        if type(bus_number) is not int or bus_number < 0:
            raise ValueError(f"I2C bus number must be an int >= 0, got {bus_number!r}")
        self.smbus = smbus
        self.bus_number = bus_number
        #: host bus errors seen (each one an OSError turned into a status)
        self.errors = 0
        self.last_error: OSError | None = None
        self.transactions = 0

    def transfer(self, addr: int, write: bytes = b"", read_len: int = 0) -> tuple[int, bytes]:
        """Write ``write``, repeated START, read ``read_len`` bytes: one ``I2C_RDWR``.

        Returns ``(0, data)`` or ``(-errno, b"")`` when the host bus raises ``OSError``.
        """
        if type(addr) is not int or not 0 <= addr <= 0x7F:
            raise ValueError(f"I2C-{self.bus_number}: address must be a 7-bit int, got {addr!r}")
        if type(read_len) is not int or read_len < 0:
            raise ValueError(f"I2C-{self.bus_number}: read_len must be an int >= 0, "
                             f"got {read_len!r}")
        self.transactions += 1
        try:
            if not write and not read_len:
                self.smbus.write_quick(addr)
                return 0, b""
            msgs = []
            if write:
                msgs.append(i2c_msg.write(addr, bytes(write)))
            if read_len:
                rd = i2c_msg.read(addr, read_len)
                msgs.append(rd)
            self.smbus.i2c_rdwr(*msgs)
        except OSError as exc:
            return self._failed(exc)
        if not read_len:
            return 0, b""
        data = bytes(rd)
        if len(data) != read_len:  # an object that is not quite an SMBus
            return self._failed(OSError(errno.EIO, f"read {len(data)} of {read_len} bytes"))
        return 0, data

    def _failed(self, exc: OSError) -> tuple[int, bytes]:
        self.errors += 1
        self.last_error = exc
        return -(exc.errno or errno.EIO), b""

    def device(self, addr: int) -> I2cAddress:
        """The driver's handle: this bus with ``addr`` bound."""
        return I2cAddress(self, addr)

    def close(self) -> None:
        self.smbus.close()

    def __repr__(self) -> str:
        return f"<SMBusHandle i2c-{self.bus_number}>"


class SpiDevHandle:
    """A ``spidev.SpiDev`` (or any object with its API) as the drivers' ``SpiDeviceHandle``."""

    def __init__(self, spidev: Any, name: str = "spidev") -> None:
        self.spidev = spidev
        self.name = name
        self.errors = 0
        self.last_error: OSError | None = None
        self.transfers = 0

    @property
    def mode(self) -> int:
        return int(self.spidev.mode)

    @mode.setter
    def mode(self, mode: int) -> None:
        self.spidev.mode = mode

    @property
    def max_speed_hz(self) -> int:
        return int(self.spidev.max_speed_hz)

    @max_speed_hz.setter
    def max_speed_hz(self, hz: int) -> None:
        self.spidev.max_speed_hz = hz

    def transfer(self, tx: bytes) -> bytes:
        """``xfer2``: CS held for the whole transfer; a failed one reads as idle MISO (0xFF)."""
        self.transfers += 1
        n = len(tx)
        try:
            rx = self.spidev.xfer2(list(tx))
            data = bytes(rx)
        except OSError as exc:
            return self._failed(exc, n)
        except (TypeError, ValueError) as exc:  # not a list of bytes: a broken SpiDev-like
            return self._failed(OSError(errno.EIO, f"bad reply {exc}"), n)
        if len(data) != n:
            return self._failed(OSError(errno.EIO, f"{len(data)} bytes back for {n}"), n)
        return data

    def _failed(self, exc: OSError, n: int) -> bytes:
        self.errors += 1
        self.last_error = exc
        return b"\xff" * n

    def close(self) -> None:
        self.spidev.close()

    def __repr__(self) -> str:
        return f"<SpiDevHandle {self.name}>"
