"""Register files declared as data: the datasheet's register map, as a table.

A device model lists its registers in datasheet names and order::

    REGISTERS = [
        Reg(0x1B, "GYRO_CONFIG", fields=[Field("XG_ST", 7), Field("YG_ST", 6),
                                         Field("ZG_ST", 5), Field("FS_SEL", 3, 2)]),
        Reg(0x3A, "INT_STATUS", access="r"),
        Reg(0x6B, "PWR_MGMT_1", reset=0x40, fields=[...]),
        Reg(0x75, "WHO_AM_I", reset=0x68, access="r"),
    ]
    regs = RegisterFile("mpu6000", REGISTERS)

Rules the file enforces so models behave like chips and mistakes show up early:

* Two registers at one address, or two fields sharing a bit, are rejected when the table is
  built (a typo in a bit position is a silent bug otherwise).
* Access: ``"rw"``, ``"r"`` (writes are ignored, as the chip ignores them, and counted),
  ``"w"`` (reads return 0; strobe registers), ``"rc"`` (read clears the register).
* Bits not covered by a field of a register that declares fields are *reserved*: a write keeps
  them at their reset value (``reserved="keep"``, the common case) or stores them
  (``reserved="store"``). Writing a reserved bit to a value other than its reset value is logged
  once per register, because a driver doing so is usually wrong.
* An address with no register reads ``undefined_value`` and ignores writes (logged once).
* ``on_write(value, old)`` and ``on_read(value) -> value`` hooks give registers behaviour
  (a reset strobe, read-to-clear status) without if/elif chains on addresses.

Burst access with auto-increment is a method of the file; a model with a non-incrementing
register (a FIFO port) handles that register itself and calls :meth:`RegisterFile.read` for the
rest.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field
from typing import Callable, Final, Iterable, Mapping

from mypy_extensions import mypyc_attr

__all__ = ["Field", "Reg", "RegisterFile", "RegisterMapError", "check_names"]

log = logging.getLogger(__name__)

ACCESS: Final[tuple[str, ...]] = ("rw", "r", "w", "rc")


@mypyc_attr(native_class=False)
class RegisterMapError(ValueError):
    """A register table that cannot describe a real chip (overlap, bad width, bad access)."""


@dataclass(frozen=True)
class Field:
    name: str
    lsb: int
    width: int = 1
    doc: str = ""

    @property
    def mask(self) -> int:
        return ((1 << self.width) - 1) << self.lsb


@dataclass
class Reg:
    addr: int
    name: str
    reset: int = 0
    access: str = "rw"
    fields: list[Field] = field(default_factory=list)
    doc: str = ""
    reserved: str = "keep"  # "keep": reserved bits stay at reset; "store": stored as written
    on_write: Callable[[int, int], None] | None = None
    on_read: Callable[[int], int] | None = None

    def __post_init__(self) -> None:
        where = f"register {self.name} (0x{self.addr:02X})"
        if self.access not in ACCESS:
            raise RegisterMapError(f"{where}: access {self.access!r} not one of {ACCESS}")
        if not 0 <= self.reset <= 0xFF:
            raise RegisterMapError(f"{where}: reset value 0x{self.reset:X} is not a byte")
        if self.reserved not in ("keep", "store"):
            raise RegisterMapError(f"{where}: reserved must be 'keep' or 'store'")
        used = 0
        names = set()
        for f in self.fields:
            if f.width < 1 or f.lsb < 0 or f.lsb + f.width > 8:
                raise RegisterMapError(f"{where}: field {f.name} bits {f.lsb}+{f.width} "
                                       f"outside the byte")
            if used & f.mask:
                raise RegisterMapError(f"{where}: field {f.name} overlaps another field")
            if f.name in names:
                raise RegisterMapError(f"{where}: field {f.name} declared twice")
            names.add(f.name)
            used |= f.mask

    @property
    def field_mask(self) -> int:
        """Bits covered by fields (all bits if the register declares no fields)."""
        if not self.fields:
            return 0xFF
        m = 0
        for f in self.fields:
            m |= f.mask
        return m


def check_names(names: Mapping[str, object], regs: Iterable[Reg], where: str = "") -> int:
    """Tie a module's register constants to a register table: ``REG`` (a register's name,
    upper-cased) must hold its address and ``REG_FIELD`` its field's mask.

    Behaviour and drivers name registers and bits with plain ``Final`` ints (mypyc inlines
    them; a table lookup per access would cost on the hot paths), so a typo in one would go
    unseen; this finds it. Other names (``CTRL1_AODR_1600HZ``, a field value) are not looked
    at. Returns how many names were checked; raises :class:`RegisterMapError` naming the first
    that disagrees.
    """
    table = list(regs)
    expected: dict[str, tuple[int, str]] = {}
    for reg in table:
        for f in reg.fields:
            expected[f"{reg.name}_{f.name}".upper()] = (f.mask, f"field {reg.name}.{f.name}")
    for reg in table:  # a register's own name wins over a REG_FIELD spelling it
        expected[reg.name.upper()] = (reg.addr, f"register {reg.name}")
    checked = 0
    for name, value in names.items():
        want = expected.get(name)
        if want is None or type(value) is not int:
            continue
        checked += 1
        if value != want[0]:
            raise RegisterMapError(f"{where}{name} = 0x{value:02X}, but the table's {want[1]} "
                                   f"is 0x{want[0]:02X}")
    return checked


class RegisterFile:
    """The registers of one chip: values, access rules, hooks, reset."""

    def __init__(self, name: str, regs: Iterable[Reg], size: int = 128,
                 undefined_value: int = 0x00) -> None:
        self.name = name
        self.size = size
        self.undefined_value = undefined_value
        self.values = bytearray(size)
        self.by_addr: dict[int, Reg] = {}
        self.by_name: dict[str, Reg] = {}
        self._fields: dict[str, tuple[Reg, Field]] = {}
        for reg in regs:
            # Each file gets its own copies: hooks bind to one chip, and a table defined once at
            # module level may serve several chips (two boards in one process).
            reg = dataclasses.replace(reg)
            if not 0 <= reg.addr < size:
                raise RegisterMapError(f"{name}: register {reg.name} address 0x{reg.addr:02X} "
                                       f"outside 0..0x{size - 1:02X}")
            if reg.addr in self.by_addr:
                raise RegisterMapError(f"{name}: registers {self.by_addr[reg.addr].name} and "
                                       f"{reg.name} both at 0x{reg.addr:02X}")
            if reg.name in self.by_name:
                raise RegisterMapError(f"{name}: register name {reg.name} used twice")
            self.by_addr[reg.addr] = reg
            self.by_name[reg.name] = reg
            for f in reg.fields:
                self._fields[f"{reg.name}.{f.name}"] = (reg, f)
        # "REG.FIELD" -> (address, mask, lsb): get() runs per sample in the ST models, and
        # Field.mask is a computed property.
        self._field_bits: dict[str, tuple[int, int, int]] = {
            path: (reg.addr, f.mask, f.lsb) for path, (reg, f) in self._fields.items()}
        # Per-address fast tables for the hot paths.
        self._readable = bytearray(size)  # 1 = plain read (no hook, not write-only/rc)
        for addr, reg in self.by_addr.items():
            self._readable[addr] = 1 if (reg.access in ("rw", "r") and reg.on_read is None) else 0
        self._warned: set[tuple[str, int]] = set()
        self.ignored_writes = 0
        self.undefined_accesses = 0
        self.reset()

    # -- state ---------------------------------------------------------------------------------

    def reset(self) -> None:
        """Every register to its reset value (power-on or a soft reset of the chip)."""
        v = self.values
        for i in range(self.size):
            v[i] = 0
        for addr, reg in self.by_addr.items():
            v[addr] = reg.reset

    def __getitem__(self, name: str) -> int:
        """The stored value of a register by name (model-internal, no side effects)."""
        return self.values[self.by_name[name].addr]

    def __setitem__(self, name: str, value: int) -> None:
        """Set a register's stored value by name (the model updating its own state)."""
        self.values[self.by_name[name].addr] = value & 0xFF

    def get(self, path: str) -> int:
        """A field's value: ``regs.get("GYRO_CONFIG.FS_SEL")``."""
        addr, mask, lsb = self._field_bits[path]
        return (self.values[addr] & mask) >> lsb

    def set(self, path: str, value: int) -> None:
        a, mask, lsb = self._field_bits[path]
        self.values[a] = (self.values[a] & ~mask & 0xFF) | ((value << lsb) & mask)

    def addr(self, name: str) -> int:
        return self.by_name[name].addr

    # -- bus-side access -------------------------------------------------------------------------

    def _warn_once(self, key: str, addr: int, message: str) -> None:
        if (key, addr) not in self._warned:
            self._warned.add((key, addr))
            log.warning("%s: %s", self.name, message)

    def read(self, addr: int) -> int:
        """A read from the bus, with the register's access rules and hook."""
        if self._readable[addr]:
            return self.values[addr]
        reg = self.by_addr.get(addr)
        if reg is None:
            self.undefined_accesses += 1
            self._warn_once("undef-r", addr, f"read of undefined register 0x{addr:02X}")
            return self.undefined_value
        if reg.access == "w":
            return 0
        value = self.values[addr]
        if reg.on_read is not None:
            value = reg.on_read(value) & 0xFF
        if reg.access == "rc":
            self.values[addr] = 0
        return value

    def read_block(self, addr: int, n: int) -> bytes:
        """An auto-incrementing burst read of ``n`` registers from ``addr`` (wrapping at the end
        of the address space); plain registers are sliced, others go through :meth:`read`."""
        end = addr + n
        if end <= self.size and all(self._readable[addr:end]):
            return bytes(self.values[addr:end])
        size = self.size
        return bytes(self.read((addr + i) % size) for i in range(n))

    def write(self, addr: int, value: int) -> None:
        """A write from the bus, with access rules, reserved bits and the register's hook."""
        value &= 0xFF
        reg = self.by_addr.get(addr)
        if reg is None:
            self.undefined_accesses += 1
            self._warn_once("undef-w", addr, f"write 0x{value:02X} to undefined register "
                                             f"0x{addr:02X} ignored")
            return
        if reg.access in ("r", "rc"):
            self.ignored_writes += 1
            self._warn_once("ro", addr, f"write 0x{value:02X} to read-only {reg.name} ignored")
            return
        old = self.values[addr]
        if reg.fields and reg.reserved == "keep":
            fm = reg.field_mask
            if (value ^ reg.reset) & ~fm & 0xFF:
                self._warn_once("resv", addr, f"write 0x{value:02X} to {reg.name} changes "
                                              f"reserved bits (kept at reset value)")
            value = (value & fm) | (reg.reset & ~fm & 0xFF)
        self.values[addr] = value
        if reg.on_write is not None:
            reg.on_write(value, old)

    def write_block(self, addr: int, data: bytes) -> None:
        size = self.size
        for i, b in enumerate(data):
            self.write((addr + i) % size, b)

    def hook(self, name: str, on_write: Callable[[int, int], None] | None = None,
             on_read: Callable[[int], int] | None = None) -> None:
        """Attach behaviour to a register after the table is built (models bind their methods
        here, keeping the table itself plain data)."""
        reg = self.by_name[name]
        if on_write is not None:
            reg.on_write = on_write
        if on_read is not None:
            reg.on_read = on_read
            self._readable[reg.addr] = 0

    def dump(self) -> dict[str, int]:
        return {reg.name: self.values[a] for a, reg in sorted(self.by_addr.items())}
