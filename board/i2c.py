"""I2C bus: a controller, 7-bit device models, and smbus2 / MicroPython shaped wrappers.

Controller side. :meth:`I2cBus.transfer` is the primitive (a write phase, a read phase, or a
write then a read joined by a repeated START, like one Linux ``I2C_RDWR`` with two messages). It
returns ``(0, data)`` or ``(-errno.EIO, b"")``: a NAK is a result of the bus, not an exception.
The convenience wrappers (smbus2: ``read_byte_data`` …; MicroPython ``machine.I2C``:
``readfrom_mem`` …) raise ``OSError(errno.EIO, ...)`` on a NAK, as smbus2 does on Linux, so a
driver fails at the call site.

Device side: subclass :class:`I2cTarget` and override ``_start`` (ACK the address?),
``_write`` (how many bytes ACKed), ``_read`` and ``_stop``. A target must act only on the bytes
it ACKs: the controller stops after the first NAKed byte.

Timing (no clock stretching, no arbitration): the transaction is counted in SCL clocks,

    START 1 + address byte 9 + 9 per written byte
    [+ repeated START 1 + address byte 9 + 9 per read byte]   (write-then-read)
    + STOP 1

(a read-only transfer is START 1 + address 9 + 9 per byte + STOP 1). Each byte is 8 data
clocks plus the ACK clock. A NAKed address ends the transaction after the address byte and
STOP; a NAKed data byte after that byte and STOP. The duration
``clocks * 10**9 // clock_hz`` ns is added to ``kernel.busy_ns``. The target sees each phase at
``t0 + clocks_before_it * 10**9 // clock_hz`` where ``t0 = kernel.context_ns`` at the call:
``_start`` when its START (or repeated START) begins, ``_write``/``_read`` when the first data
byte begins, ``_stop`` when STOP begins.

Example at 100 kHz: ``read_byte_data`` = 1 + 9 + 9 + 1 + 9 + 9 + 1 = 39 clocks = 390 us; an
absent device = 1 + 9 + 1 = 11 clocks = 110 us.
"""

from __future__ import annotations

import errno
from collections.abc import Sequence
from typing import Final

from mypy_extensions import mypyc_attr

from board.kernel import Kernel

__all__ = ["SMBUS_BLOCK_MAX", "I2cBus", "I2cFault", "I2cHandle", "I2cTarget"]

#: smbus2 / Linux I2C_SMBUS_BLOCK_MAX: longest block an SMBus block call may move.
SMBUS_BLOCK_MAX: Final = 32

_EIO: Final = -errno.EIO
_ETIMEDOUT: Final = -errno.ETIMEDOUT


class I2cFault:
    """A fault on an I2C bus's wires, consulted before each transaction.

    * ``nak_rate``: the fraction of transactions whose address byte is not acknowledged
      (a device browning out, EMI on SCL, a marginal pull-up); 1.0 NAKs everything. Drawn from
      a seeded generator. A NAKed transaction takes its real 11 clocks.
    * ``sda_stuck``: SDA held low (a device reset mid-byte keeps driving it, a short to
      ground): the controller cannot make a START; every transaction fails with
      ``-ETIMEDOUT`` after the controller's ``timeout_ns`` wait for the bus (the STM32's BUSY
      flag never clears), until the fault is removed.
    """

    def __init__(self, nak_rate: float = 0.0, sda_stuck: bool = False, seed: int = 0,
                 name: str = "i2c", timeout_ns: int = 1_000_000) -> None:
        import random

        if not 0.0 <= nak_rate <= 1.0:
            raise ValueError(f"I2C {name}: nak_rate must be in [0, 1], got {nak_rate!r}")
        self.nak_rate = float(nak_rate)
        self.sda_stuck = bool(sda_stuck)
        self.timeout_ns = int(timeout_ns)
        self._rng = random.Random(f"{seed}:{name}:i2c-fault")
        self.naks = 0
        self.timeouts = 0

    def intercept(self, bus: I2cBus, addr: int) -> tuple[int, bytes] | None:
        """None: the transaction runs normally; else its (failed) result."""
        if self.sda_stuck:
            self.timeouts += 1
            bus.timeouts += 1
            bus.kernel.busy_ns += self.timeout_ns
            return _ETIMEDOUT, b""
        if self.nak_rate and (self.nak_rate >= 1.0 or self._rng.random() < self.nak_rate):
            self.naks += 1
            bus._nak(address=True)
            bus.kernel.busy_ns += bus.duration_ns(1 + 9 + 1)
            return _EIO, b""
        return None


@mypyc_attr(allow_interpreted_subclasses=True)
class I2cTarget:
    """Base class for an I2C device model at one 7-bit address.

    Hooks default to an always-ACKing device that reads 0xFF. The public methods are what the
    bus calls; they keep the counters (``starts``) and enforce the reply shapes.
    """

    name: str = ""
    address: int = -1

    def start(self, t_ns: int, is_read: bool) -> bool:
        """(Repeated) START plus our address: True to ACK."""
        return bool(self._start(t_ns, is_read))

    def write(self, t_ns: int, data: bytes) -> int:
        """Bytes written by the controller; returns how many were ACKed (0..len)."""
        n = self._write(t_ns, data)
        if type(n) is not int or not 0 <= n <= len(data):
            raise ValueError(f"I2C device model {type(self).__name__} at 0x{self.address:02x}: "
                             f"_write must return 0..{len(data)} ACKed bytes, got {n!r}")
        return n

    def read(self, t_ns: int, n: int) -> bytes:
        """The controller reads ``n`` bytes; a short answer is padded with 0xFF (SDA idles
        high when nobody drives it)."""
        data = bytes(self._read(t_ns, n))
        if len(data) < n:
            data += b"\xff" * (n - len(data))
        return data[:n]

    def stop(self, t_ns: int) -> None:
        """STOP condition."""
        self._stop(t_ns)

    # -- hooks ----------------------------------------------------------------------------------

    def _start(self, t_ns: int, is_read: bool) -> bool:
        return True

    def _write(self, t_ns: int, data: bytes) -> int:
        return len(data)

    def _read(self, t_ns: int, n: int) -> bytes:
        return b"\xff" * n

    def _stop(self, t_ns: int) -> None:
        pass


def _check_addr(bus: str, addr: object, where: str) -> int:
    if type(addr) is not int or not 0 <= addr <= 0x7F:
        raise ValueError(f"I2C {bus}.{where}: address must be a 7-bit int 0x00..0x7f, "
                         f"got {addr!r}")
    return addr


def _check_byte(bus: str, value: object, what: str, where: str) -> int:
    if type(value) is not int or not 0 <= value <= 0xFF:
        raise ValueError(f"I2C {bus}.{where}: {what} must be an int 0..255, got {value!r}")
    return value


class I2cBus:
    """One I2C controller (e.g. the FMU's external I2C1) and the devices on its wires."""

    def __init__(self, kernel: Kernel, name: str, clock_hz: int = 400_000) -> None:
        if type(clock_hz) is not int or clock_hz <= 0:
            raise ValueError(f"I2C bus {name}: clock_hz must be a positive int, got {clock_hz!r}")
        self.kernel = kernel
        self.name = name
        self.clock_hz = clock_hz
        self._targets: dict[int, I2cTarget] = {}
        #: Transactions run, and NAKs seen (address and data), for status and fault tests.
        self.transactions = 0
        self.nak_count = 0
        self.addr_nak_count = 0
        self.data_nak_count = 0
        #: fault injection (see :meth:`set_fault`); None on a healthy bus
        self.fault: I2cFault | None = None
        self.timeouts = 0

    def set_fault(self, fault: I2cFault | None) -> None:
        """Put a fault on the wires (a NAK storm, SDA held low), or None to heal them."""
        self.fault = fault

    # -- wiring ---------------------------------------------------------------------------------

    def attach(self, addr: int, target: I2cTarget) -> None:
        """Put ``target`` on the bus at 7-bit ``addr`` (0x08..0x77; 0x00-0x07 and 0x78-0x7F
        are reserved by the I2C specification)."""
        _check_addr(self.name, addr, "attach")
        if addr < 0x08 or addr > 0x77:
            raise ValueError(f"I2C {self.name}.attach: address 0x{addr:02x} is reserved "
                             f"(usable 0x08..0x77)")
        if not isinstance(target, I2cTarget):
            raise TypeError(f"I2C {self.name}.attach(0x{addr:02x}): {target!r} is not an "
                             f"I2cTarget")
        if addr in self._targets:
            raise ValueError(f"I2C {self.name}.attach: address 0x{addr:02x} already taken by "
                             f"{self._targets[addr]!r}")
        self._targets[addr] = target
        target.address = addr
        if not target.name:
            target.name = f"{self.name}@0x{addr:02x}"

    def detach(self, addr: int) -> I2cTarget | None:
        """Remove the device at ``addr`` (it stops ACKing); returns it."""
        return self._targets.pop(_check_addr(self.name, addr, "detach"), None)

    def target(self, addr: int) -> I2cTarget | None:
        """The device model at ``addr``, if any."""
        return self._targets.get(addr)

    def scan(self) -> list[int]:
        """MicroPython ``I2C.scan``: addresses 0x08..0x77 that ACK a quick write."""
        return [a for a in range(0x08, 0x78) if self.transfer(a, b"", 0)[0] == 0]

    def device(self, addr: int) -> I2cHandle:
        """A driver's handle bound to one address."""
        return I2cHandle(self, _check_addr(self.name, addr, "device"))

    def duration_ns(self, clocks: int) -> int:
        """Duration of ``clocks`` SCL periods at this bus's clock."""
        return clocks * 1_000_000_000 // self.clock_hz

    # -- the primitive --------------------------------------------------------------------------

    def transfer(self, addr: int, write: bytes = b"", read_len: int = 0) -> tuple[int, bytes]:
        """Write ``write`` then read ``read_len`` bytes (repeated START between them).

        Returns ``(0, data)`` or ``(-errno.EIO, b"")`` on a NAK. With both empty it is an SMBus
        quick write (address only), the usual presence probe.
        """
        _check_addr(self.name, addr, "transfer")
        if type(read_len) is not int or read_len < 0:
            raise ValueError(f"I2C {self.name}.transfer(0x{addr:02x}): read_len must be an "
                             f"int >= 0, got {read_len!r}")
        if type(write) is not bytes:
            try:
                write = bytes(write)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"I2C {self.name}.transfer(0x{addr:02x}): cannot send "
                                 f"{write!r}: {exc}") from None
        kernel = self.kernel
        t0 = kernel.now_ns + kernel.busy_ns
        hz = self.clock_hz
        target = self._targets.get(addr)
        self.transactions += 1
        if self.fault is not None:
            failed = self.fault.intercept(self, addr)
            if failed is not None:
                return failed
        status = 0
        data = b""
        clocks = 0  # SCL clocks before the current bus phase
        if write or not read_len:
            acked = target is not None and target.start(t0, False)
            clocks += 1 + 9  # START, address byte + ACK
            if not acked:
                status = self._nak(address=True)
            elif write:
                assert target is not None
                n_ack = target.write(t0 + clocks * 1_000_000_000 // hz, write)
                if n_ack < len(write):
                    clocks += 9 * (n_ack + 1)  # the NAKed byte was clocked too
                    status = self._nak(address=False)
                else:
                    clocks += 9 * len(write)
        if status == 0 and read_len:
            acked = target is not None and target.start(t0 + clocks * 1_000_000_000 // hz, True)
            clocks += 1 + 9  # (repeated) START, address byte + ACK
            if not acked:
                status = self._nak(address=True)
            else:
                assert target is not None
                data = target.read(t0 + clocks * 1_000_000_000 // hz, read_len)
                clocks += 9 * read_len
        if target is not None:
            target.stop(t0 + clocks * 1_000_000_000 // hz)
        clocks += 1  # STOP
        kernel.busy_ns += clocks * 1_000_000_000 // hz
        return status, data

    def _nak(self, address: bool) -> int:
        self.nak_count += 1
        if address:
            self.addr_nak_count += 1
        else:
            self.data_nak_count += 1
        return _EIO

    def _checked(self, addr: int, write: bytes, read_len: int, where: str) -> bytes:
        status, data = self.transfer(addr, write, read_len)
        if status:
            if status == _ETIMEDOUT:
                raise OSError(errno.ETIMEDOUT, f"I2C {self.name}: {where} at address "
                                               f"0x{addr:02x}: bus busy, START timed out")
            raise OSError(errno.EIO, f"I2C {self.name}: {where} at address 0x{addr:02x}: "
                                     f"no ACK ({errno.errorcode[errno.EIO]})")
        return data

    # -- smbus2-shaped wrappers (raise OSError(EIO) on NAK) ------------------------------------

    def write_quick(self, i2c_addr: int, force: bool | None = None) -> None:
        """smbus2 ``write_quick``: address only."""
        self._checked(i2c_addr, b"", 0, "write_quick")

    def read_byte(self, i2c_addr: int, force: bool | None = None) -> int:
        """smbus2 ``read_byte``: one byte, no register."""
        return self._checked(i2c_addr, b"", 1, "read_byte")[0]

    def write_byte(self, i2c_addr: int, value: int, force: bool | None = None) -> None:
        """smbus2 ``write_byte``: one byte, no register."""
        _check_byte(self.name, value, "value", "write_byte")
        self._checked(i2c_addr, bytes((value,)), 0, "write_byte")

    def read_byte_data(self, i2c_addr: int, register: int, force: bool | None = None) -> int:
        """smbus2 ``read_byte_data``: register write, repeated START, one byte read."""
        _check_byte(self.name, register, "register", "read_byte_data")
        return self._checked(i2c_addr, bytes((register,)), 1, "read_byte_data")[0]

    def write_byte_data(self, i2c_addr: int, register: int, value: int,
                        force: bool | None = None) -> None:
        """smbus2 ``write_byte_data``."""
        _check_byte(self.name, register, "register", "write_byte_data")
        _check_byte(self.name, value, "value", "write_byte_data")
        self._checked(i2c_addr, bytes((register, value)), 0, "write_byte_data")

    def read_word_data(self, i2c_addr: int, register: int, force: bool | None = None) -> int:
        """smbus2 ``read_word_data`` (SMBus words are little-endian)."""
        _check_byte(self.name, register, "register", "read_word_data")
        data = self._checked(i2c_addr, bytes((register,)), 2, "read_word_data")
        return data[0] | data[1] << 8

    def write_word_data(self, i2c_addr: int, register: int, value: int,
                        force: bool | None = None) -> None:
        """smbus2 ``write_word_data`` (little-endian)."""
        _check_byte(self.name, register, "register", "write_word_data")
        if type(value) is not int or not 0 <= value <= 0xFFFF:
            raise ValueError(f"I2C {self.name}.write_word_data: value must be 0..65535, "
                             f"got {value!r}")
        self._checked(i2c_addr, bytes((register, value & 0xFF, value >> 8)), 0,
                      "write_word_data")

    def read_i2c_block_data(self, i2c_addr: int, register: int, length: int,
                            force: bool | None = None) -> list[int]:
        """smbus2 ``read_i2c_block_data``: at most 32 bytes, as on Linux."""
        _check_byte(self.name, register, "register", "read_i2c_block_data")
        if type(length) is not int or not 0 < length <= SMBUS_BLOCK_MAX:
            raise ValueError(f"I2C {self.name}.read_i2c_block_data: length must be "
                             f"1..{SMBUS_BLOCK_MAX}, got {length!r}")
        return list(self._checked(i2c_addr, bytes((register,)), length, "read_i2c_block_data"))

    def write_i2c_block_data(self, i2c_addr: int, register: int, data: Sequence[int],
                             force: bool | None = None) -> None:
        """smbus2 ``write_i2c_block_data``: at most 32 bytes, as on Linux."""
        _check_byte(self.name, register, "register", "write_i2c_block_data")
        if len(data) > SMBUS_BLOCK_MAX:
            raise ValueError(f"I2C {self.name}.write_i2c_block_data: {len(data)} bytes, more "
                             f"than {SMBUS_BLOCK_MAX}")
        payload = bytes((register,)) + self._bytes(data, "write_i2c_block_data")
        self._checked(i2c_addr, payload, 0, "write_i2c_block_data")

    # -- MicroPython machine.I2C shaped wrappers ------------------------------------------------

    def readfrom(self, addr: int, nbytes: int, stop: bool = True) -> bytes:
        """MicroPython ``readfrom`` (``stop`` is accepted; every call ends with STOP)."""
        return self._checked(addr, b"", self._len(nbytes, "readfrom"), "readfrom")

    def readfrom_into(self, addr: int, buf: bytearray | memoryview, stop: bool = True) -> None:
        """MicroPython ``readfrom_into``."""
        buf[:] = self.readfrom(addr, len(buf))

    def writeto(self, addr: int, buf: bytes, stop: bool = True) -> int:
        """MicroPython ``writeto``; returns the bytes ACKed (all of them: a NAK raises)."""
        data = self._bytes(buf, "writeto")
        self._checked(addr, data, 0, "writeto")
        return len(data)

    def readfrom_mem(self, addr: int, memaddr: int, nbytes: int, *, addrsize: int = 8) -> bytes:
        """MicroPython ``readfrom_mem``: register address (big-endian for 16 bits), repeated
        START, read."""
        mem = self._memaddr(memaddr, addrsize, "readfrom_mem")
        return self._checked(addr, mem, self._len(nbytes, "readfrom_mem"), "readfrom_mem")

    def readfrom_mem_into(self, addr: int, memaddr: int, buf: bytearray | memoryview, *,
                          addrsize: int = 8) -> None:
        """MicroPython ``readfrom_mem_into``."""
        buf[:] = self.readfrom_mem(addr, memaddr, len(buf), addrsize=addrsize)

    def writeto_mem(self, addr: int, memaddr: int, buf: bytes, *, addrsize: int = 8) -> None:
        """MicroPython ``writeto_mem``: register address then data, one write phase."""
        mem = self._memaddr(memaddr, addrsize, "writeto_mem")
        self._checked(addr, mem + self._bytes(buf, "writeto_mem"), 0, "writeto_mem")

    # -- argument helpers -----------------------------------------------------------------------

    def _len(self, n: object, where: str) -> int:
        if type(n) is not int or n < 0:
            raise ValueError(f"I2C {self.name}.{where}: byte count must be an int >= 0, "
                             f"got {n!r}")
        return n

    def _bytes(self, data: object, where: str) -> bytes:
        try:
            return bytes(data)  # type: ignore[call-overload]
        except (TypeError, ValueError) as exc:
            raise ValueError(f"I2C {self.name}.{where}: cannot send {data!r}: {exc}") from None

    def _memaddr(self, memaddr: int, addrsize: int, where: str) -> bytes:
        if addrsize not in (8, 16):
            raise ValueError(f"I2C {self.name}.{where}: addrsize must be 8 or 16, "
                             f"got {addrsize!r}")
        if type(memaddr) is not int or not 0 <= memaddr < 1 << addrsize:
            raise ValueError(f"I2C {self.name}.{where}: memaddr {memaddr!r} does not fit "
                             f"{addrsize} bits")
        return memaddr.to_bytes(addrsize // 8, "big")

    def __repr__(self) -> str:
        addrs = ", ".join(f"0x{a:02x}" for a in sorted(self._targets))
        return f"<I2cBus {self.name} {self.clock_hz} Hz [{addrs}]>"


class I2cHandle:
    """A driver's view of one device: the bus wrappers with the address bound."""

    __slots__ = ("addr", "bus")

    def __init__(self, bus: I2cBus, addr: int) -> None:
        self.bus = bus
        self.addr = addr

    def transfer(self, write: bytes = b"", read_len: int = 0) -> tuple[int, bytes]:
        """:meth:`I2cBus.transfer` at this address (returns the status, never raises on NAK)."""
        return self.bus.transfer(self.addr, write, read_len)

    def read_byte_data(self, register: int) -> int:
        return self.bus.read_byte_data(self.addr, register)

    def write_byte_data(self, register: int, value: int) -> None:
        self.bus.write_byte_data(self.addr, register, value)

    def read_i2c_block_data(self, register: int, length: int) -> list[int]:
        return self.bus.read_i2c_block_data(self.addr, register, length)

    def write_i2c_block_data(self, register: int, data: Sequence[int]) -> None:
        self.bus.write_i2c_block_data(self.addr, register, data)

    def readfrom_mem(self, memaddr: int, nbytes: int, *, addrsize: int = 8) -> bytes:
        return self.bus.readfrom_mem(self.addr, memaddr, nbytes, addrsize=addrsize)

    def writeto_mem(self, memaddr: int, buf: bytes, *, addrsize: int = 8) -> None:
        self.bus.writeto_mem(self.addr, memaddr, buf, addrsize=addrsize)

    def readfrom(self, nbytes: int) -> bytes:
        return self.bus.readfrom(self.addr, nbytes)

    def writeto(self, buf: bytes) -> int:
        return self.bus.writeto(self.addr, buf)

    def __repr__(self) -> str:
        return f"<I2cHandle {self.bus.name}@0x{self.addr:02x}>"
