"""Topic definitions: parse PX4-style ``.msg`` files and derive Python classes and binary layouts.

A ``.msg`` file declares typed fields, constants and optionally the topics that share the type::

    # a comment
    uint64 timestamp            # time since boot (us)
    float32[3] xyz              # fixed array
    char[16] name               # fixed-size text
    VehicleStatus nested        # another message type (by file name)
    uint8 ORB_QUEUE_LENGTH = 4  # queue length of every topic of this type
    uint8 MODE_X = 2            # a constant
    # TOPICS sensor_accel sensor_accel_fifo

Everything else (the Python class with ``__slots__``, ``pack``/``unpack``, ``copy``, the ULog
format string) is derived from that one definition. Layouts are little-endian and packed in the
declared order (no padding), which is what ULog readers expect when the format says so.
"""

from __future__ import annotations

import os
import re
import struct
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

__all__ = ["FieldDef", "MessageDef", "MessageRegistry", "MsgError", "default_registry",
           "snake_to_camel"]

# type name -> (struct code, size, python default, C type used in ULog formats)
PRIMITIVES: Final[dict[str, tuple[str, int, Any, str]]] = {
    "bool": ("?", 1, False, "bool"),
    "byte": ("B", 1, 0, "uint8_t"),
    "char": ("c", 1, "", "char"),
    "uint8": ("B", 1, 0, "uint8_t"),
    "int8": ("b", 1, 0, "int8_t"),
    "uint16": ("H", 2, 0, "uint16_t"),
    "int16": ("h", 2, 0, "int16_t"),
    "uint32": ("I", 4, 0, "uint32_t"),
    "int32": ("i", 4, 0, "int32_t"),
    "uint64": ("Q", 8, 0, "uint64_t"),
    "int64": ("q", 8, 0, "int64_t"),
    "float32": ("f", 4, 0.0, "float"),
    "float64": ("d", 8, 0.0, "double"),
}

_INT_RANGES: Final = {
    "uint8": (0, 0xFF), "byte": (0, 0xFF), "int8": (-0x80, 0x7F),
    "uint16": (0, 0xFFFF), "int16": (-0x8000, 0x7FFF),
    "uint32": (0, 0xFFFFFFFF), "int32": (-0x80000000, 0x7FFFFFFF),
    "uint64": (0, 0xFFFFFFFFFFFFFFFF), "int64": (-0x8000000000000000, 0x7FFFFFFFFFFFFFFF),
}

_NAME_RE: Final = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
_TYPE_RE: Final = re.compile(r"^([A-Za-z][A-Za-z0-9_]*)(?:\[(\d+)\])?$")


class MsgError(ValueError):
    """A malformed .msg definition; the message names the file and line."""


def snake_to_camel(name: str) -> str:
    return "".join(part[:1].upper() + part[1:] for part in name.split("_"))


@dataclass(frozen=True)
class FieldDef:
    name: str
    type: str            # primitive name or nested message name
    array: int | None    # fixed array length, or None for a scalar
    comment: str = ""

    @property
    def is_primitive(self) -> bool:
        return self.type in PRIMITIVES


@dataclass
class MessageDef:
    """One message type: its fields, constants and the topics that carry it."""

    name: str                                # snake_case, from the file name
    fields: list[FieldDef]
    constants: dict[str, tuple[str, Any]]    # name -> (type, value)
    topics: list[str]
    source: str = ""
    queue_length: int = 1
    cls: type | None = field(default=None, repr=False)
    struct: struct.Struct | None = field(default=None, repr=False)

    @property
    def size(self) -> int:
        assert self.struct is not None
        return self.struct.size

    def ulog_format(self) -> str:
        """The ULog 'F' message body for this type: ``name:type field;...``."""
        parts = []
        for f in self.fields:
            ctype = PRIMITIVES[f.type][3] if f.is_primitive else f.type
            parts.append(f"{ctype}[{f.array}] {f.name};" if f.array else f"{ctype} {f.name};")
        return f"{self.name}:" + "".join(parts)


def parse_msg(text: str, name: str, source: str = "<string>") -> MessageDef:
    """Parse the text of one .msg file into a MessageDef (types are resolved later)."""
    fields: list[FieldDef] = []
    constants: dict[str, tuple[str, Any]] = {}
    topics: list[str] = []
    seen: set[str] = set()
    for lineno, raw in enumerate(text.splitlines(), 1):
        where = f"{source}:{lineno}"
        stripped = raw.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            body = stripped.lstrip("#").strip()
            if body.startswith("TOPICS"):
                topics.extend(body.split()[1:])
            continue
        code, _, comment = stripped.partition("#")
        code = code.strip()
        comment = comment.strip()
        if "=" in code:
            decl, _, value_text = code.partition("=")
            parts = decl.split()
            if len(parts) != 2:
                raise MsgError(f"{where}: constant must be 'type NAME = value', got {raw!r}")
            ctype, cname = parts
            if ctype not in PRIMITIVES or ctype == "char":
                raise MsgError(f"{where}: constant {cname} has unsupported type {ctype!r}")
            constants[cname] = (ctype, _parse_constant(ctype, value_text.strip(), where))
            continue
        parts = code.split()
        if len(parts) != 2:
            raise MsgError(f"{where}: expected 'type name', got {raw!r}")
        type_text, fname = parts
        m = _TYPE_RE.match(type_text)
        if not m:
            raise MsgError(f"{where}: bad type {type_text!r}")
        if not _NAME_RE.match(fname):
            raise MsgError(f"{where}: bad field name {fname!r}")
        if fname in seen:
            raise MsgError(f"{where}: duplicate field {fname!r}")
        seen.add(fname)
        base, arr = m.group(1), m.group(2)
        length = int(arr) if arr is not None else None
        if length is not None and length <= 0:
            raise MsgError(f"{where}: array length must be positive")
        fields.append(FieldDef(fname, base, length, comment))
    if not topics:
        topics = [name]
    queue_length = 1
    if "ORB_QUEUE_LENGTH" in constants:
        queue_length = int(constants["ORB_QUEUE_LENGTH"][1])
        if queue_length < 1:
            raise MsgError(f"{source}: ORB_QUEUE_LENGTH must be >= 1")
    return MessageDef(name, fields, constants, topics, source, queue_length)


def _parse_constant(ctype: str, text: str, where: str) -> Any:
    try:
        if ctype in ("float32", "float64"):
            return float(text)
        if ctype == "bool":
            if text.lower() in ("true", "1"):
                return True
            if text.lower() in ("false", "0"):
                return False
            raise ValueError(text)
        value = int(text, 0)
    except ValueError:
        raise MsgError(f"{where}: bad {ctype} constant value {text!r}") from None
    lo, hi = _INT_RANGES[ctype]
    if not lo <= value <= hi:
        raise MsgError(f"{where}: constant {value} out of range for {ctype}")
    return value


class MessageRegistry:
    """All message types and topics from a folder of .msg files, with derived classes.

    Definitions are static data, so sharing one registry between boards is safe; live topic
    state lives in each board's broker.
    """

    def __init__(self) -> None:
        self.messages: dict[str, MessageDef] = {}
        self.topics: dict[str, MessageDef] = {}

    @classmethod
    def from_dir(cls, path: str | os.PathLike) -> MessageRegistry:
        reg = cls()
        files = sorted(Path(path).glob("*.msg"))
        for f in files:
            reg.add(parse_msg(f.read_text(), f.stem, str(f)))
        reg.build()
        return reg

    def add(self, mdef: MessageDef) -> None:
        if mdef.name in self.messages:
            raise MsgError(f"{mdef.source}: message {mdef.name} defined twice")
        self.messages[mdef.name] = mdef

    def build(self) -> None:
        """Resolve nested types, compute layouts and generate classes (dependencies first)."""
        by_camel = {snake_to_camel(n): n for n in self.messages}
        done: set[str] = set()
        visiting: set[str] = set()

        def resolve(name: str) -> None:
            if name in done:
                return
            if name in visiting:
                raise MsgError(f"message {name}: recursive nesting")
            visiting.add(name)
            mdef = self.messages[name]
            new_fields = []
            for f in mdef.fields:
                if not f.is_primitive:
                    target = f.type if f.type in self.messages else by_camel.get(f.type)
                    if target is None:
                        raise MsgError(f"{mdef.source}: field {f.name} has unknown type {f.type!r}")
                    resolve(target)
                    f = FieldDef(f.name, target, f.array, f.comment)
                new_fields.append(f)
            mdef.fields = new_fields
            _generate(mdef, self.messages)
            visiting.discard(name)
            done.add(name)

        for name in list(self.messages):
            resolve(name)
        self.topics.clear()
        for mdef in self.messages.values():
            for topic in mdef.topics:
                if topic in self.topics:
                    raise MsgError(f"{mdef.source}: topic {topic} already defined by "
                                   f"{self.topics[topic].source}")
                self.topics[topic] = mdef

    def topic(self, name: str) -> MessageDef:
        try:
            return self.topics[name]
        except KeyError:
            raise KeyError(f"unknown uORB topic {name!r}") from None

    def cls(self, topic: str) -> type:
        cls = self.topic(topic).cls
        assert cls is not None
        return cls


# -- class generation ------------------------------------------------------------------------

def _struct_code(mdef: MessageDef, messages: dict[str, MessageDef]) -> str:
    code = []
    for f in mdef.fields:
        n = f.array or 1
        if f.is_primitive:
            if f.type == "char":
                code.append(f"{n}s")
            else:
                code.append(PRIMITIVES[f.type][0] * n)
        else:
            sub = _struct_code(messages[f.type], messages)
            code.append(sub * n)
    return "".join(code)


def _generate(mdef: MessageDef, messages: dict[str, MessageDef]) -> None:
    """Generate a slotted class with fast __init__, copy, pack and unpack for ``mdef``."""
    names = [f.name for f in mdef.fields]
    ns: dict[str, Any] = {"_nested": {}}
    init_args, init_body, copy_body, pack_items, unpack_body = [], [], [], [], []
    idx = 0  # position in the flat unpacked tuple
    for f in mdef.fields:
        n = f.array
        if f.is_primitive:
            default = PRIMITIVES[f.type][2]
            if f.type == "char":
                init_args.append(f"{f.name}=''")
                init_body.append(f"    self.{f.name} = {f.name}")
                copy_body.append(f"    n.{f.name} = self.{f.name}")
                pack_items.append(f"self.{f.name}.encode('latin-1')")
                unpack_body.append(
                    f"    o.{f.name} = v[{idx}].split(b'\\0', 1)[0].decode('latin-1')")
                idx += 1
            elif n:
                init_args.append(f"{f.name}=None")
                init_body.append(
                    f"    self.{f.name} = [{default!r}] * {n} if {f.name} is None else {f.name}")
                copy_body.append(f"    n.{f.name} = self.{f.name}[:]")
                pack_items.append(f"*self.{f.name}")
                unpack_body.append(f"    o.{f.name} = list(v[{idx}:{idx + n}])")
                idx += n
            else:
                init_args.append(f"{f.name}={default!r}")
                init_body.append(f"    self.{f.name} = {f.name}")
                copy_body.append(f"    n.{f.name} = self.{f.name}")
                pack_items.append(f"self.{f.name}")
                unpack_body.append(f"    o.{f.name} = v[{idx}]")
                idx += 1
        else:
            sub = messages[f.type]
            ns["_nested"][f.name] = sub.cls
            sub_len = len(_flat_values_template(sub, messages))
            init_args.append(f"{f.name}=None")
            if n:
                init_body.append(
                    f"    self.{f.name} = [_nested[{f.name!r}]() for _ in range({n})] "
                    f"if {f.name} is None else {f.name}")
                copy_body.append(f"    n.{f.name} = [x.copy() for x in self.{f.name}]")
                pack_items.append(f"*[y for x in self.{f.name} for y in x._flat()]")
                unpack_body.append(
                    f"    o.{f.name} = [_nested[{f.name!r}]._from_flat(v[{idx} + i * {sub_len}:"
                    f"{idx} + (i + 1) * {sub_len}]) for i in range({n})]")
                idx += sub_len * n
            else:
                init_body.append(
                    f"    self.{f.name} = _nested[{f.name!r}]() if {f.name} is None else {f.name}")
                copy_body.append(f"    n.{f.name} = self.{f.name}.copy()")
                pack_items.append(f"*self.{f.name}._flat()")
                unpack_body.append(
                    f"    o.{f.name} = _nested[{f.name!r}]._from_flat(v[{idx}:{idx + sub_len}])")
                idx += sub_len
    fmt = "<" + _struct_code(mdef, messages)
    st = struct.Struct(fmt)
    ns["_struct"] = st
    args = ", ".join(["self", "*"] + init_args) if init_args else "self"
    src = [f"def __init__({args}):"] + (init_body or ["    pass"])
    src += ["def copy(self):", "    n = _new(_cls)"] + copy_body + ["    return n"]
    src += ["def _flat(self):", f"    return ({', '.join(pack_items)}{',' if pack_items else ''})"]
    src += ["def pack(self):", "    return _struct.pack(*self._flat())"]
    src += ["def _from_flat(v):", "    o = _new(_cls)"] + unpack_body + ["    return o"]
    src += ["def unpack(data):", "    return _from_flat(_struct.unpack(data))"]
    code = "\n".join(src)
    exec(compile(code, f"<msg {mdef.name}>", "exec"), ns)  # noqa: S102 - generated from .msg data

    def __repr__(self: Any) -> str:
        body = ", ".join(f"{k}={getattr(self, k)!r}" for k in names)
        return f"{mdef.name}({body})"

    def __eq__(self: Any, other: Any) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(getattr(self, k) == getattr(other, k) for k in names)

    attrs: dict[str, Any] = {
        "__slots__": tuple(names),
        "__init__": ns["__init__"],
        "copy": ns["copy"],
        "_flat": ns["_flat"],
        "pack": ns["pack"],
        "unpack": staticmethod(ns["unpack"]),
        "_from_flat": staticmethod(ns["_from_flat"]),
        "__repr__": __repr__,
        "__eq__": __eq__,
        "__hash__": None,
        "_fields": tuple(names),
        "_def": mdef,
        "SIZE": st.size,
    }
    for cname, (_ctype, value) in mdef.constants.items():
        attrs[cname] = value
    cls = type(snake_to_camel(mdef.name), (), attrs)
    ns["_cls"] = cls
    ns["_new"] = object.__new__
    mdef.cls = cls
    mdef.struct = st


def _flat_values_template(mdef: MessageDef, messages: dict[str, MessageDef]) -> list[str]:
    out: list[str] = []
    for f in mdef.fields:
        n = f.array or 1
        if f.is_primitive:
            out.extend([f.name] * (1 if f.type == "char" else n))
        else:
            out.extend(_flat_values_template(messages[f.type], messages) * n)
    return out


_DEFAULT: MessageRegistry | None = None


def default_registry() -> MessageRegistry:
    """The registry built from firmware/msg (parsed once; definitions are immutable)."""
    global _DEFAULT
    if _DEFAULT is None:
        _DEFAULT = MessageRegistry.from_dir(Path(__file__).resolve().parent.parent / "msg")
    return _DEFAULT
