"""An ``smbus2.SMBus`` look-alike on an emulated I2C bus, for scripts written against smbus2.

``EmulatedSMBus(board.i2c["I2C1"])`` answers the calls of smbus2's ``SMBus`` (``read_byte``,
``write_byte``, ``read_byte_data``, ``write_byte_data``, ``read_word_data``,
``write_word_data``, ``read_i2c_block_data``, ``write_i2c_block_data``, ``write_quick``,
``i2c_rdwr`` with smbus2's own ``i2c_msg`` objects, ``close``, ``with``) from the device models
on that bus, so a script or a driver written for a Linux I2C bus runs against the virtual board
unchanged: ``hil/hostbus.py``'s :class:`~hil.hostbus.SMBusHandle` makes the very same calls on it
as on a real ``smbus2.SMBus``.

Faithful where it matters to such code:

* Each call is one transaction on the emulated bus, with its bus time and device timing
  (``board.i2c.I2cBus.transfer``); calls made outside the board's kernel events take effect at
  the kernel's current time.
* Failures raise ``OSError`` with the codes of Linux's I2C fault-code conventions: ``ENXIO``
  when the address is not acknowledged, ``EIO`` for a NAKed data byte, ``ETIMEDOUT`` when SDA
  is held low (the START times out).
* ``i2c_rdwr`` takes what the emulated controller can do in one transaction: one write, one
  read, or a write then a read to the same address. Other chains raise ``EOPNOTSUPP``, as a
  Linux adapter with the ``I2C_AQ_COMB_WRITE_THEN_READ`` quirk does. Ten-bit addresses are not
  supported either.
* Argument errors raise ``ValueError``/``TypeError`` before anything reaches the bus; a closed
  object raises ``OSError(EBADF)``.
"""

from __future__ import annotations

import ctypes
import errno
from collections.abc import Sequence
from typing import Any

from smbus2 import i2c_msg
from smbus2.smbus2 import I2C_M_RD, I2C_SMBUS_BLOCK_MAX

from board.i2c import I2cBus

__all__ = ["EmulatedSMBus"]

#: Linux's I2C_M_TEN: a 10-bit address (not on the emulated bus).
_I2C_M_TEN = 0x0010


class EmulatedSMBus:
    """smbus2's ``SMBus`` API backed by an emulated :class:`board.i2c.I2cBus`."""

    def __init__(self, bus: I2cBus, force: bool = False) -> None:
        if not isinstance(bus, I2cBus):
            raise TypeError(f"EmulatedSMBus needs an emulated I2cBus, got {bus!r}")
        self.bus = bus
        self.force = force
        self.closed = False
        #: transactions made on the emulated bus (for tests and tracing)
        self.calls = 0

    # -- the one path to the bus -------------------------------------------------------------

    def _xfer(self, addr: int, write: bytes, read_len: int, what: str) -> bytes:
        if self.closed:
            raise OSError(errno.EBADF, f"{what}: the bus is closed")
        if type(addr) is not int or not 0 <= addr <= 0x7F:
            raise ValueError(f"{what}: I2C address must be a 7-bit int, got {addr!r}")
        bus = self.bus
        addr_naks = bus.addr_nak_count
        self.calls += 1
        status, data = bus.transfer(addr, write, read_len)
        if status == 0:
            return data
        if status == -errno.ETIMEDOUT:
            code = errno.ETIMEDOUT
        elif bus.addr_nak_count != addr_naks:
            code = errno.ENXIO
        else:
            code = -status if status < 0 else errno.EIO
        raise OSError(code, f"{what} at 0x{addr:02x} on {bus.name}: {errno.errorcode[code]}")

    @staticmethod
    def _byte(value: Any, what: str, name: str) -> int:
        if type(value) is not int or not 0 <= value <= 0xFF:
            raise ValueError(f"{what}: {name} must be an int 0..255, got {value!r}")
        return value

    @staticmethod
    def _block(data: Any, what: str) -> bytes:
        try:
            out = bytes(data)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{what}: data must be bytes 0..255: {exc}") from None
        if len(out) > I2C_SMBUS_BLOCK_MAX:
            raise ValueError(f"{what}: data length cannot exceed {I2C_SMBUS_BLOCK_MAX} bytes, "
                             f"got {len(out)}")
        return out

    # -- smbus2.SMBus ------------------------------------------------------------------------

    def write_quick(self, i2c_addr: int, force: bool | None = None) -> None:
        self._xfer(i2c_addr, b"", 0, "write_quick")

    def read_byte(self, i2c_addr: int, force: bool | None = None) -> int:
        return self._xfer(i2c_addr, b"", 1, "read_byte")[0]

    def write_byte(self, i2c_addr: int, value: int, force: bool | None = None) -> None:
        self._xfer(i2c_addr, bytes((self._byte(value, "write_byte", "value"),)), 0, "write_byte")

    def read_byte_data(self, i2c_addr: int, register: int, force: bool | None = None) -> int:
        reg = self._byte(register, "read_byte_data", "register")
        return self._xfer(i2c_addr, bytes((reg,)), 1, "read_byte_data")[0]

    def write_byte_data(self, i2c_addr: int, register: int, value: int,
                        force: bool | None = None) -> None:
        what = "write_byte_data"
        payload = bytes((self._byte(register, what, "register"), self._byte(value, what, "value")))
        self._xfer(i2c_addr, payload, 0, what)

    def read_word_data(self, i2c_addr: int, register: int, force: bool | None = None) -> int:
        """SMBus words are little-endian."""
        reg = self._byte(register, "read_word_data", "register")
        data = self._xfer(i2c_addr, bytes((reg,)), 2, "read_word_data")
        return data[0] | data[1] << 8

    def write_word_data(self, i2c_addr: int, register: int, value: int,
                        force: bool | None = None) -> None:
        reg = self._byte(register, "write_word_data", "register")
        if type(value) is not int or not 0 <= value <= 0xFFFF:
            raise ValueError(f"write_word_data: value must be an int 0..65535, got {value!r}")
        self._xfer(i2c_addr, bytes((reg, value & 0xFF, value >> 8)), 0, "write_word_data")

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int,
                            force: bool | None = None) -> list[int]:
        what = "read_i2c_block_data"
        reg = self._byte(register, what, "register")
        if type(length) is not int or not 0 < length <= I2C_SMBUS_BLOCK_MAX:
            raise ValueError(f"{what}: length must be 1..{I2C_SMBUS_BLOCK_MAX}, got {length!r}")
        return list(self._xfer(i2c_addr, bytes((reg,)), length, what))

    def write_i2c_block_data(self, i2c_addr: int, register: int, data: Sequence[int],
                             force: bool | None = None) -> None:
        what = "write_i2c_block_data"
        reg = self._byte(register, what, "register")
        self._xfer(i2c_addr, bytes((reg,)) + self._block(data, what), 0, what)

    def i2c_rdwr(self, *i2c_msgs: i2c_msg) -> None:
        """Combined transaction: fills the read messages' buffers as the ioctl would."""
        what = "i2c_rdwr"
        if not i2c_msgs:
            raise ValueError(f"{what}: no messages")
        for m in i2c_msgs:
            if not isinstance(m, i2c_msg):
                raise TypeError(f"{what}: expected smbus2.i2c_msg objects, got {m!r}")
            if m.flags & _I2C_M_TEN:
                raise OSError(errno.EOPNOTSUPP, f"{what}: 10-bit addresses are not supported")
        reads = [m for m in i2c_msgs if m.flags & I2C_M_RD]
        writes = [m for m in i2c_msgs if not m.flags & I2C_M_RD]
        shape_ok = (len(i2c_msgs) == 1 or (
            len(i2c_msgs) == 2 and len(writes) == 1 and len(reads) == 1
            and i2c_msgs[0] is writes[0] and writes[0].addr == reads[0].addr))
        if not shape_ok:
            raise OSError(errno.EOPNOTSUPP, f"{what}: the emulated adapter does one write, one "
                                            f"read, or a write then a read to one address")
        addr = i2c_msgs[0].addr
        write = bytes(writes[0]) if writes else b""
        read_len = reads[0].len if reads else 0
        data = self._xfer(addr, write, read_len, what)
        if reads and data:
            ctypes.memmove(reads[0].buf, data, len(data))

    def close(self) -> None:
        """Nothing to release; later calls raise ``OSError(EBADF)`` like a closed file."""
        self.closed = True

    def __enter__(self) -> EmulatedSMBus:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"<EmulatedSMBus {self.bus.name}{' closed' if self.closed else ''}>"
