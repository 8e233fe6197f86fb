"""Parameters: declared with metadata next to their module, stored in FRAM, crash-safe.

Declaration (in a module, next to the code that uses them)::

    PARAMS = (
        ParamDef("MC_ROLL_P", "FLOAT", 6.5, min=0.0, max=12.0, group="Multicopter Attitude",
                 short="Roll P gain", decimals=2),
        ParamDef("SYS_AUTOSTART", "INT32", 0, group="System", short="Airframe",
                 reboot_required=True),
    )

Values follow PX4's types: INT32 parameters are Python ints in the int32 range; FLOAT
parameters are rounded to float32 on every set, so a value survives BSON (double), MAVLink
(float) and QGroundControl files unchanged.

Storage (see docs/parameters.md for the byte layout): the FRAM ``params`` partition holds two
slots; each slot is a 16-byte header (magic, sequence number, length, CRC-32) followed by the
PX4-format BSON document. A save writes the slot not holding the newest copy that loads (CRC
and document both good), so a power cut during a save leaves that copy intact: at most the
change being saved is lost.
Nothing unverified is read at boot: a bare PX4 document (what real PX4 keeps at offset 0) is
imported on request with ``param load FILE`` (:meth:`Params.load_document`).
"""

from __future__ import annotations

import fnmatch
import math
import struct
import zlib
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, Final, Iterable, Literal, Protocol, overload

from firmware.platform import bson
from firmware.platform.bson import INT32_MAX, INT32_MIN

if TYPE_CHECKING:
    from firmware.platform import Platform
    from firmware.platform.hrt import HrtCall

__all__ = ["ParamDef", "Params", "ParamError", "ParamStorage", "MemoryPartition",
           "export_qgc", "import_qgc", "markdown_reference", "f32", "FLT_MAX", "INT32_MIN",
           "INT32_MAX"]

MAV_PARAM_TYPE_INT32, MAV_PARAM_TYPE_REAL32 = 6, 9


class ParamError(ValueError):
    pass


#: The largest finite float32 (C's FLT_MAX); larger magnitudes round to infinity on the STM32.
#: The one definition: other modules import it from here.
FLT_MAX: Final = 3.4028234663852886e38


def f32(x: Any, name: str = "value") -> float:
    """A number rounded to the nearest float32, as the STM32 stores it: the one conversion
    every parameter value goes through (shell, QGC files, MAVLink, FRAM, scenarios, ``--param``).

    NaN, the infinities and magnitudes that round beyond FLT_MAX raise :class:`ParamError`
    naming ``name``: PX4's ``param_set`` would store their bit pattern, but no controller can
    use them, and Python's own conversion raises OverflowError, which nobody expects."""
    if isinstance(x, bool) or not isinstance(x, (int, float)):
        raise ParamError(f"{name}: {x!r} is not a number")
    try:
        v = float(x)
    except OverflowError:  # an int beyond even a double
        raise ParamError(f"{name}: an integer of {int(x).bit_length()} bits is outside the float32 "
                         f"range (magnitude at most {FLT_MAX:.7g})") from None
    if math.isnan(v) or math.isinf(v):
        raise ParamError(f"{name}: {x} is not a finite number")
    try:
        return float(_F32.unpack(_F32.pack(v))[0])
    except OverflowError:
        raise ParamError(f"{name}: {v:.7g} is outside the float32 range (magnitude at most "
                         f"{FLT_MAX:.7g})") from None


_F32 = struct.Struct("<f")


@dataclass(frozen=True)
class ParamDef:
    name: str
    type: str                    # "INT32" or "FLOAT"
    default: int | float
    min: float | None = None
    max: float | None = None
    unit: str = ""
    group: str = "Miscellaneous"
    short: str = ""
    long: str = ""
    decimals: int | None = None
    reboot_required: bool = False
    values: dict[int, str] = field(default_factory=dict)  # enumerations

    def __post_init__(self) -> None:
        if not 1 <= len(self.name) <= 16 or not self.name.replace("_", "").isalnum() \
                or self.name.upper() != self.name:
            raise ParamError(f"parameter name {self.name!r}: 1..16 upper-case letters, digits, _")
        if self.type not in ("INT32", "FLOAT"):
            raise ParamError(f"parameter {self.name}: type must be INT32 or FLOAT")
        object.__setattr__(self, "default", self.coerce(self.default))

    def coerce(self, value: object) -> int | float:
        """The value as this parameter's type, or ParamError saying why not."""
        if self.type == "INT32":
            if isinstance(value, float):
                if not value.is_integer():
                    raise ParamError(f"{self.name} is an integer parameter, got {value}")
                value = int(value)
            if isinstance(value, bool) or not isinstance(value, int):
                raise ParamError(f"{self.name} is an integer parameter, got {value!r}")
            if not INT32_MIN <= value <= INT32_MAX:
                raise ParamError(f"{self.name}: {value} is outside the int32 range")
            return value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ParamError(f"{self.name} is a float parameter, got {value!r}")
        return f32(value, self.name)

    def in_range(self, value: int | float) -> bool:
        return (self.min is None or value >= self.min) and (self.max is None or value <= self.max)


class Partition(Protocol):
    size: int

    def read(self, offset: int, n: int) -> bytes | None: ...

    def write(self, offset: int, data: bytes) -> bool: ...


class MemoryPartition:
    """A partition in host memory (tests, boards without FRAM); starts erased (0xFF)."""

    def __init__(self, size: int = 8192, fill: int = 0xFF) -> None:
        self.size = size
        self.data = bytearray([fill]) * size

    def read(self, offset: int, n: int) -> bytes | None:
        return bytes(self.data[offset:offset + n])

    def write(self, offset: int, data: bytes) -> bool:
        self.data[offset:offset + len(data)] = data
        return True


_MAGIC = b"PRM1"
_HEADER = struct.Struct("<4sIII")  # magic, sequence, document length, CRC-32
_SEQ_MOD = 1 << 32
_ERASED = "erased"

#: How a load is reported on the console: the severity of its dmesg line.
LogLevel = Literal["info", "warn", "error"]


def seq_newer(a: int, b: int) -> bool:
    """Whether save number ``a`` is newer than ``b`` in 32-bit serial-number arithmetic
    (RFC 1982): the numbers wrap at 2**32, and the newer is the one less than 2**31 ahead, so
    save #0 after save #0xFFFFFFFF is still the newest."""
    return 0 < (a - b) % _SEQ_MOD < (1 << 31)


class ParamStorage:
    """Two-slot crash-safe store of a BSON document in a partition.

    A boot trusts only what it can verify: a slot whose header and CRC-32 check out. Anything
    else (a torn save, damage, a partition this store never wrote) is reported and left alone;
    it never hides the other slot's good copy."""

    def __init__(self, partition: Partition, medium: str = "FRAM") -> None:
        if partition.size < 2 * 64:
            raise ParamError(f"parameter partition of {partition.size} bytes is too small")
        self.part = partition
        #: what holds the partition, as the boot messages name it (the FMU's FRAM, a disk file)
        self.medium = medium
        self.slot_size = partition.size // 2
        self.sequence = 0
        self.last_slot: int | None = None
        self._scanned = False  # the slots were read (load or the first save)

    def _read_slot(self, slot: int) -> tuple[int, bytes] | str:
        """(sequence, document) of a valid slot, or why it is not valid (``_ERASED`` for a
        slot never written)."""
        base = slot * self.slot_size
        head = self.part.read(base, _HEADER.size)
        if head is None or len(head) < _HEADER.size:
            return "header not readable"
        if head == b"\xff" * _HEADER.size:
            rest = self.part.read(base + _HEADER.size, self.slot_size - _HEADER.size)
            if rest is None or rest.count(0xFF) == len(rest):
                return _ERASED  # never written
            return "erased header before a document (a first save cut short)"
        magic, seq, length, crc = _HEADER.unpack(head)
        if magic != _MAGIC:
            hint = ""
            if slot == 0 and 5 <= int.from_bytes(magic, "little") <= self.part.size:
                hint = ": a bare PX4 document? `param load FILE` imports one"
            return f"no slot header (magic {magic!r}{hint})"
        if not 5 <= length <= self.slot_size - _HEADER.size:
            return f"save #{seq}: document length {length} does not fit the slot"
        doc = self.part.read(base + _HEADER.size, length)
        if doc is None or len(doc) != length:
            return f"save #{seq}: document not readable"
        if zlib.crc32(head[4:12] + doc) != crc:
            return f"save #{seq}: CRC mismatch (a save cut short, or a damaged copy)"
        return seq, doc

    def _scan(self) -> tuple[list[tuple[int, int, dict]], dict[int, str]]:
        """The slots that load, as (sequence, slot, values), newest first, and why the others
        do not. A slot whose CRC checks out but whose document does not decode does not load.

        Remembers where the next save goes: ``last_slot`` is the newest slot that loads, so
        the save overwrites the other one and never the only good copy; ``sequence`` is the
        newest save number seen in any slot with a good CRC, so the next save is newer than
        every copy, the undecodable one included."""
        loaded: list[tuple[int, int, dict]] = []
        invalid: dict[int, str] = {}
        newest: int | None = None
        for slot in (0, 1):
            r = self._read_slot(slot)
            if isinstance(r, str):
                invalid[slot] = r
                continue
            seq, doc = r
            if newest is None or seq_newer(seq, newest):
                newest = seq
            try:
                values = bson.decode(doc)
            except bson.BsonError as exc:  # CRC passed but the content is not ours
                invalid[slot] = f"save #{seq} does not decode ({exc})"
                continue
            loaded.append((seq, slot, values or {}))
        if len(loaded) == 2 and seq_newer(loaded[1][0], loaded[0][0]):
            loaded.reverse()
        if newest is not None:
            self.sequence = newest
        self.last_slot = loaded[0][1] if loaded else None
        self._scanned = True
        return loaded, invalid

    def load(self) -> tuple[dict | None, str, LogLevel]:
        """(values or None, message, level). None means: use the defaults; the message says
        why. Loading from anything but the newest save, or with a damaged slot beside the
        good one, is a warning naming the slot and the reason."""
        loaded, invalid = self._scan()
        problems = [f"slot {s}: {why}" for s, why in invalid.items() if why != _ERASED]
        if loaded:
            seq, slot, values = loaded[0]
            msg = f"parameters loaded from slot {slot} (save #{seq})"
            if problems:
                return values, (f"{'; '.join(problems)}; {msg}, the last good copy: "
                                f"the newest save may be lost"), "warn"
            empty = [s for s, why in invalid.items() if why == _ERASED]
            return values, msg + ("; the other slot is empty" if empty else ""), "info"
        if not problems:
            return None, f"no parameters stored (erased {self.medium}); defaults loaded", "warn"
        return None, f"parameter store corrupt ({'; '.join(problems)}); defaults loaded", "error"

    def save(self, values: dict[str, int | float]) -> tuple[bool, str]:
        """Write the slot not holding the newest copy that loads: the document first, the header
        (with the CRC over both) last, so a power cut at any byte keeps the previous copy."""
        doc = bson.encode(values)
        if len(doc) > self.slot_size - _HEADER.size:
            return False, (f"parameter document of {len(doc)} bytes does not fit a slot of "
                           f"{self.slot_size - _HEADER.size}")
        if not self._scanned:  # never loaded: do not overwrite a good copy blindly
            self._scan()
        slot = 0 if self.last_slot in (None, 1) else 1
        seq = (self.sequence + 1) % _SEQ_MOD
        body = struct.pack("<II", seq, len(doc)) + doc
        head = _HEADER.pack(_MAGIC, seq, len(doc), zlib.crc32(body))
        base = slot * self.slot_size
        if not self.part.write(base + _HEADER.size, doc) or not self.part.write(base, head):
            return False, f"write to parameter slot {slot} failed"
        self.sequence, self.last_slot = seq, slot
        return True, f"saved {len(values)} parameters to slot {slot} (save #{seq})"


class Params:
    """The parameter set of one board: values, defaults, change notification, persistence."""

    def __init__(self, platform: Platform, defs: Iterable[ParamDef],
                 storage: ParamStorage | None = None, autosave_delay_us: int = 300_000) -> None:
        self.platform = platform
        self.defs: dict[str, ParamDef] = {}
        for d in defs:
            if d.name in self.defs and self.defs[d.name] != d:
                raise ParamError(f"parameter {d.name} declared twice with different metadata")
            self.defs[d.name] = d
        self.names = sorted(self.defs)          # index order, as PX4 (alphabetical)
        self._index = {n: i for i, n in enumerate(self.names)}
        self.values: dict[str, int | float] = {n: d.default for n, d in self.defs.items()}
        self.storage = storage
        self.autosave_delay_us = autosave_delay_us
        self._autosave: HrtCall | None = None
        self._pub = platform.orb.advertise("parameter_update")
        self._msg = platform.orb.new("parameter_update")
        self.set_count = 0
        self.save_count = 0
        self.listeners: list[Callable[[str, int | float], None]] = []

    # -- access ----------------------------------------------------------------------------

    def __contains__(self, name: str) -> bool:
        return name in self.defs

    def __getitem__(self, name: str) -> int | float:
        try:
            return self.values[name]
        except KeyError:
            raise ParamError(f"unknown parameter {name}") from None

    @overload
    def get(self, name: str, default: int | float) -> int | float: ...
    @overload
    def get(self, name: str, default: None = None) -> int | float | None: ...

    def get(self, name: str, default: int | float | None = None) -> int | float | None:
        return self.values.get(name, default)

    def index(self, name: str) -> int | None:
        return self._index.get(name)

    def set(self, name: str, value: object, notify: bool = True) -> int | float:
        d = self.defs.get(name)
        if d is None:
            raise ParamError(f"unknown parameter {name}")
        v = d.coerce(value)
        if self.values[name] != v:
            self.values[name] = v
            self.set_count += 1
            for fn in self.listeners:
                fn(name, v)
            if notify:
                self.notify()
        return v

    def reset(self, name: str) -> None:
        self.set(name, self.defs[name].default)

    def reset_all(self, exclude: Iterable[str] = ()) -> int:
        pats = list(exclude)
        n = 0
        for name in self.names:
            if any(fnmatch.fnmatchcase(name, p) for p in pats):
                continue
            if self.values[name] != self.defs[name].default:
                self.values[name] = self.defs[name].default
                n += 1
        if n:
            self.notify()
        return n

    def changed(self) -> list[str]:
        return [n for n in self.names if self.values[n] != self.defs[n].default]

    def match(self, pattern: str | None) -> list[str]:
        if not pattern:
            return list(self.names)
        pat = pattern if any(c in pattern for c in "*?[") else pattern + "*"
        return [n for n in self.names if fnmatch.fnmatchcase(n, pat.upper())]

    def notify(self) -> None:
        """Publish parameter_update (modules reload) and arm the delayed autosave."""
        m = self._msg
        m.timestamp = self.platform.hrt.absolute_time()
        m.instance += 1
        m.set_count = self.set_count
        m.active = len(self.names)
        m.changed = len(self.changed())
        self._pub.publish(m)
        if self.storage is not None and self.autosave_delay_us >= 0:
            if self._autosave is not None:
                self._autosave.cancel()
            self._autosave = self.platform.hrt.call_after(self.autosave_delay_us,
                                                          self._autosave_now)

    def _autosave_now(self) -> None:
        self._autosave = None
        self.save()

    # -- persistence -------------------------------------------------------------------------

    def save(self) -> bool:
        """Save the values that differ from their defaults (what current PX4 saves)."""
        if self.storage is None:
            self.platform.error("param", "save: no parameter storage")
            return False
        doc: dict[str, int | float] = {n: self.values[n] for n in self.changed()}
        ok, msg = self.storage.save(doc)
        (self.platform.info if ok else self.platform.error)("param", msg)
        if ok:
            self.save_count += 1
        return ok

    def load(self, merge: bool = False) -> bool:
        """Load from storage; without ``merge`` everything is reset to defaults first."""
        if self.storage is None:
            self.platform.error("param", "load: no parameter storage")
            return False
        values, msg, level = self.storage.load()
        log = {"info": self.platform.info, "warn": self.platform.warn,
               "error": self.platform.error}[level]
        if not merge:
            for n in self.names:
                self.values[n] = self.defs[n].default
        if values is None:
            log("param", msg)
            self.notify_quiet()
            return False
        skipped = self._apply(values, "storage")
        log("param", msg + (f", {skipped} skipped" if skipped else ""))
        self.notify_quiet()
        return True

    def load_document(self, data: bytes, source: str) -> tuple[int, int]:
        """Load a PX4 parameter file: the bare BSON document real PX4 keeps at the start of
        its FRAM (``/fs/mtd_params``) or writes with ``param save FILE``. As PX4's ``param
        load``, everything else goes back to its default; the result is announced and saved.
        Returns (loaded, skipped); BsonError, before anything changed, if it does not decode."""
        values = bson.decode(data)
        if values is None:
            raise bson.BsonError("the document is erased memory (0xFF)")
        for n in self.names:
            self.values[n] = self.defs[n].default
        skipped = self._apply(values, source)
        self.set_count += 1
        self.notify()
        self.platform.info("param", f"{source}: {len(values) - skipped} parameters loaded"
                           + (f", {skipped} skipped" if skipped else ""))
        return len(values) - skipped, skipped

    def notify_quiet(self) -> None:
        """Publish parameter_update without arming an autosave (after load)."""
        saved = self.autosave_delay_us
        self.autosave_delay_us = -1
        try:
            self.notify()
        finally:
            self.autosave_delay_us = saved

    def _apply(self, values: dict, source: str) -> int:
        skipped = 0
        for name, v in values.items():
            d = self.defs.get(name)
            if d is None:
                self.platform.warn("param", f"{source}: unknown parameter {name} skipped")
                skipped += 1
                continue
            if (d.type == "INT32") != (isinstance(v, int) and not isinstance(v, bool)):
                self.platform.warn("param", f"{source}: {name} has the wrong type, skipped")
                skipped += 1
                continue
            try:
                self.values[name] = d.coerce(v)
            except ParamError as exc:
                self.platform.warn("param", f"{source}: {exc}; skipped")
                skipped += 1
        return skipped


# -- QGroundControl .params files -------------------------------------------------------------

def export_qgc(params: Params, sysid: int = 1, compid: int = 1) -> str:
    lines = ["# Onboard parameters for Vehicle 1", "#", "# Stack: PX4 Pro (fmu-hil)", "#",
             "# Vehicle-Id Component-Id Name Value Type"]
    for name in params.names:
        d = params.defs[name]
        v = params.values[name]
        if d.type == "INT32":
            lines.append(f"{sysid}\t{compid}\t{name}\t{v}\t{MAV_PARAM_TYPE_INT32}")
        else:
            lines.append(f"{sysid}\t{compid}\t{name}\t{v:.18g}\t{MAV_PARAM_TYPE_REAL32}")
    return "\n".join(lines) + "\n"


def import_qgc(params: Params, text: str) -> tuple[int, list[str]]:
    """Import a .params file; returns (parameters set, problems with their line numbers).
    Malformed lines are reported and skipped; the rest still import."""
    problems: list[str] = []
    count = 0
    for lineno, raw in enumerate(text.splitlines(), 1):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        if len(parts) != 5:
            problems.append(f"line {lineno}: expected 5 fields "
                            f"(vehicle component name value type), got {len(parts)}")
            continue
        _sys, _comp, name, value_text, type_text = parts
        d = params.defs.get(name)
        if d is None:
            problems.append(f"line {lineno}: unknown parameter {name}")
            continue
        try:
            mav_type = int(type_text)
            value: int | float = int(value_text) if mav_type == MAV_PARAM_TYPE_INT32 \
                else float(value_text)
            if mav_type not in (MAV_PARAM_TYPE_INT32, MAV_PARAM_TYPE_REAL32):
                raise ParamError(f"type {mav_type} is neither 6 (INT32) nor 9 (REAL32)")
            if (mav_type == MAV_PARAM_TYPE_INT32) != (d.type == "INT32"):
                raise ParamError(f"{name} is {d.type}, the file says type {mav_type}")
            params.set(name, value, notify=False)
            count += 1
        except (ValueError, ParamError) as exc:
            problems.append(f"line {lineno}: {exc}")
    if count:
        params.notify()
    return count, problems


def _num(v: int | float | None) -> str:
    """A value as a person writes it: float32 defaults without their binary tail."""
    if v is None:
        return ""
    return f"{v:.7g}" if isinstance(v, float) else str(v)


def markdown_reference(defs: Iterable[ParamDef]) -> str:
    """The parameter reference page, generated from the metadata."""
    by_group: dict[str, list[ParamDef]] = {}
    for d in sorted(defs, key=lambda d: d.name):
        by_group.setdefault(d.group, []).append(d)
    out = ["# Parameter reference", "",
           "Generated from the parameter declarations (`hil params --out "
           "docs/parameter_reference.md`); do not edit.", ""]
    for group in sorted(by_group):
        out += [f"## {group}", "", "| Name | Description | Min > Max | Default | Unit |",
                "|---|---|---|---|---|"]
        for d in by_group[group]:
            desc = d.short + (f"<br>{d.long}" if d.long else "")
            if d.values:
                desc += "<br>" + ", ".join(f"{k}: {v}" for k, v in sorted(d.values.items()))
            if d.reboot_required:
                desc += "<br>Reboot required"
            rng = f"{_num(d.min)} > {_num(d.max)}"
            out.append(f"| `{d.name}` ({d.type}) | {desc} | {rng} | {_num(d.default)} | "
                       f"{d.unit} |")
        out.append("")
    return "\n".join(out)
