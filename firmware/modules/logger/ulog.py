"""ULog (version 1) encoder: the binary log format PX4's logger writes and every PX4 tool reads.

A file is a 16-byte header (magic ``ULog`` 01 12 35, version, start timestamp in us) followed by
messages, each ``uint16 size`` (payload bytes) + ``uint8 type`` + payload, little-endian:

* definitions section: ``B`` flag bits (must come first), ``F`` formats, ``I`` info, ``M`` multi
  info, ``P`` initial parameters, ``Q`` parameter defaults;
* data section, opened by the first ``A``/``L``/``C``: ``A`` add subscription, ``R`` remove,
  ``D`` data, ``L``/``C`` logged strings, ``P`` changed parameters, ``S`` sync, ``O`` dropout.

This module only encodes: it writes bytes to a file-like object and holds no time, buffering or
drop policy (that is the logger's job). The message builders (``*_message`` functions) return
the encoded bytes, so a caller can size a message before deciding to write it.
"""

from __future__ import annotations

import struct
from typing import Any, Final, Protocol

from mypy_extensions import mypyc_attr

from firmware.platform.msgdef import PRIMITIVES, MessageDef, MessageRegistry

__all__ = [
    "COMPAT_DEFAULT_PARAMETERS",
    "INCOMPAT_DATA_APPENDED",
    "LOG_LEVELS",
    "MAGIC",
    "SYNC_MAGIC",
    "UlogError",
    "UlogWriter",
    "formats_for",
    "level_char",
    "message",
    "topic_format",
]

MAGIC: Final = b"ULog\x01\x12\x35"
FILE_VERSION: Final = 1
SYNC_MAGIC: Final = bytes((0x2F, 0x73, 0x13, 0x20, 0x25, 0x0C, 0xBB, 0x12))
HEADER_SIZE: Final = 16
MAX_PAYLOAD: Final = 0xFFFF

#: compat_flags[0] bit 0: the file has 'Q' default-parameter messages
COMPAT_DEFAULT_PARAMETERS: Final = 0x01
#: incompat_flags[0] bit 0: data appended after the file (offsets in the flag-bits message)
INCOMPAT_DATA_APPENDED: Final = 0x01

#: syslog levels as written in 'L'/'C' messages (ASCII digit)
LOG_LEVELS: Final = {"EMERG": 0, "ALERT": 1, "CRIT": 2, "ERR": 3, "WARNING": 4, "NOTICE": 5,
              "INFO": 6, "DEBUG": 7}

# Python value types of info/parameter messages -> struct code
_INFO_CODES: Final = {"int8_t": "b", "uint8_t": "B", "int16_t": "h", "uint16_t": "H",
               "int32_t": "i", "uint32_t": "I", "int64_t": "q", "uint64_t": "Q",
               "float": "f", "double": "d", "bool": "?"}


@mypyc_attr(native_class=False)
class UlogError(ValueError):
    """A message that cannot be encoded, or one written in the wrong section."""


def level_char(level: int) -> int:
    """The byte a 'L'/'C' message carries for a syslog level 0..7 (ASCII '0'..'7')."""
    if not 0 <= level <= 7:
        raise UlogError(f"log level must be 0..7, got {level}")
    return 0x30 + level


def message(msg_type: str, payload: bytes) -> bytes:
    """One encoded message: header (size, type) + payload."""
    if len(payload) > MAX_PAYLOAD:
        raise UlogError(f"ULog '{msg_type}' message payload of {len(payload)} bytes exceeds "
                        f"{MAX_PAYLOAD}")
    return struct.pack("<HB", len(payload), ord(msg_type)) + payload


def _key_value(key: str, value: Any, type_name: str | None) -> bytes:
    """The ``uint8 key_len, key ('type name'), value`` body shared by I, M, P and Q."""
    if type_name is None:
        if isinstance(value, bool):
            raise UlogError(f"{key}: give an explicit type for a bool value")
        if isinstance(value, str):
            type_name = "char"
        elif isinstance(value, int):
            type_name = "int32_t"
        elif isinstance(value, float):
            type_name = "float"
        elif isinstance(value, (bytes, bytearray)):
            type_name = "uint8_t[]"
        else:
            raise UlogError(f"{key}: unsupported info/parameter value type {type(value).__name__}")
    if type_name == "char" or type_name.startswith("char["):
        raw = value.encode("utf-8") if isinstance(value, str) else bytes(value)
        tkey = f"char[{len(raw)}] {key}"
    elif type_name == "uint8_t[]":
        raw = bytes(value)
        tkey = f"uint8_t[{len(raw)}] {key}"
    elif type_name in _INFO_CODES:
        try:
            raw = struct.pack("<" + _INFO_CODES[type_name], value)
        except struct.error as exc:
            raise UlogError(f"{key}: value {value!r} does not fit {type_name}: {exc}") from None
        tkey = f"{type_name} {key}"
    else:
        raise UlogError(f"{key}: unsupported info/parameter type {type_name!r}")
    if " " in key or not key:
        raise UlogError(f"bad info/parameter key {key!r}")
    kb = tkey.encode("ascii")
    if len(kb) > 255:
        raise UlogError(f"info/parameter key too long: {key!r}")
    return bytes((len(kb),)) + kb + raw


def topic_format(topic: str, mdef: MessageDef) -> str:
    """The 'F' text for a logged topic: named by the topic (as PX4 does), typed by its fields."""
    fields = mdef.fields
    if not fields or fields[0].name != "timestamp" or fields[0].type != "uint64" \
            or fields[0].array:
        raise UlogError(f"topic {topic}: a logged topic must start with 'uint64 timestamp' "
                        f"({mdef.source or mdef.name})")
    return topic + ":" + mdef.ulog_format().split(":", 1)[1]


def formats_for(topic: str, mdef: MessageDef, registry: MessageRegistry) -> list[str]:
    """Format texts needed to log ``topic``: nested types first (depth-first), the topic last."""
    out: list[str] = []
    seen: set[str] = set()

    def visit(m: MessageDef) -> None:
        for f in m.fields:
            if f.type not in PRIMITIVES and f.type not in seen:
                seen.add(f.type)
                sub = registry.messages[f.type]
                visit(sub)
                out.append(sub.ulog_format())

    visit(mdef)
    out.append(topic_format(topic, mdef))
    return out


class ByteSink(Protocol):
    """Where a :class:`UlogWriter` writes: a binary file, or the logger's SD buffer."""

    def write(self, data: bytes, /) -> int: ...


class UlogWriter:
    """Encode one ULog file onto ``fileobj`` (anything with ``write(bytes)``).

    The constructor writes the header and the flag bits. Definitions (formats, info, initial
    parameters, defaults) must be written before the first subscription or logged string; the
    writer raises :class:`UlogError` otherwise, since readers would not see them.
    """

    def __init__(self, fileobj: ByteSink, start_timestamp_us: int, *,
                 compat_flags: int = 0, incompat_flags: int = 0) -> None:
        if start_timestamp_us < 0:
            raise UlogError(f"negative start timestamp {start_timestamp_us}")
        self.f = fileobj
        self.start_timestamp_us = start_timestamp_us
        self.bytes_written = 0
        self.in_data_section = False
        self.formats: set[str] = set()
        self.subscriptions: dict[int, tuple[str, int]] = {}   # msg_id -> (topic, multi_id)
        self._next_msg_id = 0
        self.counts: dict[str, int] = {}
        self._raw(MAGIC + bytes((FILE_VERSION,)) + struct.pack("<Q", start_timestamp_us))
        flags = struct.pack("<8B8B3Q", compat_flags & 0xFF, *([0] * 7),
                            incompat_flags & 0xFF, *([0] * 7), 0, 0, 0)
        self._msg("B", flags)

    # -- low level ------------------------------------------------------------------------

    def _raw(self, data: bytes) -> None:
        self.f.write(data)
        self.bytes_written += len(data)

    def _msg(self, msg_type: str, payload: bytes) -> None:
        self._raw(message(msg_type, payload))
        self.counts[msg_type] = self.counts.get(msg_type, 0) + 1

    def write_raw_message(self, encoded: bytes) -> None:
        """Write a message built by one of the ``*_message`` methods (already sized)."""
        self._raw(encoded)
        t = chr(encoded[2])
        self.counts[t] = self.counts.get(t, 0) + 1
        if t in "ALC":
            self.in_data_section = True

    def _definition(self, what: str) -> None:
        if self.in_data_section:
            raise UlogError(f"ULog {what} must be written before the first subscription or "
                            "logged string (definitions section)")

    # -- definitions section --------------------------------------------------------------

    def write_format(self, fmt: str) -> None:
        """Write one 'F' message ``name:type field;...`` (once per name)."""
        self._definition("format")
        name = fmt.split(":", 1)[0]
        if name in self.formats:
            return
        self.formats.add(name)
        self._msg("F", fmt.encode("ascii"))

    def write_topic_formats(self, topic: str, mdef: MessageDef,
                            registry: MessageRegistry) -> None:
        """Write the formats for a topic, nested types before their users."""
        for fmt in formats_for(topic, mdef, registry):
            self.write_format(fmt)

    def write_info(self, key: str, value: Any, type_name: str | None = None) -> None:
        """'I' message. ``str`` → ``char[N]``, ``int`` → ``int32_t``, ``float`` → ``float``,
        or give ``type_name`` ('uint32_t', 'int64_t', 'double', ...). Allowed in both sections.
        """
        self._msg("I", _key_value(key, value, type_name))

    def write_info_multiple(self, key: str, value: Any, type_name: str | None = None,
                            is_continued: bool = False) -> None:
        """'M' message: a value split over several messages (``is_continued`` on the rest)."""
        self._msg("M", bytes((1 if is_continued else 0,)) + _key_value(key, value, type_name))

    def write_parameter(self, name: str, value: Any) -> None:
        """'P' message: initial value in the definitions section, a change in the data section.
        ``value`` is an int (int32_t) or a float: typed Any, since compiled code (hil.native)
        would make a ``float`` argument a float."""
        self._msg("P", _key_value(name, value, _param_type(name, value)))

    def write_parameter_default(self, name: str, value: Any, default_types: int) -> None:
        """'Q' message: bit 0 system-wide default, bit 1 default of the current configuration."""
        self._definition("parameter default")
        self._msg("Q", bytes((default_types & 0xFF,))
                  + _key_value(name, value, _param_type(name, value)))

    # -- data section ---------------------------------------------------------------------

    def add_subscription(self, topic: str, multi_id: int = 0) -> int:
        """'A' message: announce (topic, instance); returns its msg_id for 'D' messages."""
        if topic not in self.formats:
            raise UlogError(f"subscription to {topic!r} before its format was written")
        if not 0 <= multi_id <= 255:
            raise UlogError(f"multi_id must be 0..255, got {multi_id}")
        msg_id = self._next_msg_id
        if msg_id > 0xFFFF:
            raise UlogError("too many subscriptions (msg_id is uint16)")
        self._next_msg_id += 1
        self.subscriptions[msg_id] = (topic, multi_id)
        self.in_data_section = True
        self._msg("A", struct.pack("<BH", multi_id, msg_id) + topic.encode("ascii"))
        return msg_id

    def remove_subscription(self, msg_id: int) -> None:
        if msg_id not in self.subscriptions:
            raise UlogError(f"remove of unknown msg_id {msg_id}")
        del self.subscriptions[msg_id]
        self._msg("R", struct.pack("<H", msg_id))

    @staticmethod
    def data_message(msg_id: int, payload: bytes) -> bytes:
        return message("D", struct.pack("<H", msg_id) + payload)

    def write_data(self, msg_id: int, payload: bytes) -> None:
        """'D' message: one sample of a subscribed topic (its packed struct)."""
        if msg_id not in self.subscriptions:
            raise UlogError(f"data for unknown msg_id {msg_id}")
        self._msg("D", struct.pack("<H", msg_id) + payload)

    @staticmethod
    def logged_string_message(level: int, timestamp_us: int, text: str) -> bytes:
        return message("L", struct.pack("<BQ", level_char(level), timestamp_us)
                       + text.encode("utf-8"))

    def write_logged_string(self, level: int, timestamp_us: int, text: str) -> None:
        """'L' message: a console message with syslog level 0..7 and its time."""
        self.write_raw_message(self.logged_string_message(level, timestamp_us, text))

    def write_tagged_string(self, level: int, tag: int, timestamp_us: int, text: str) -> None:
        """'C' message: like 'L' with a uint16 tag (e.g. the writing process or module)."""
        self.write_raw_message(message("C", struct.pack("<BHQ", level_char(level), tag & 0xFFFF,
                                                        timestamp_us) + text.encode("utf-8")))

    @staticmethod
    def sync_message() -> bytes:
        return message("S", SYNC_MAGIC)

    def write_sync(self) -> None:
        """'S' message: a magic sequence a reader can resynchronise on after corruption."""
        self._msg("S", SYNC_MAGIC)

    @staticmethod
    def dropout_message(duration_ms: int) -> bytes:
        return message("O", struct.pack("<H", max(0, min(0xFFFF, int(duration_ms)))))

    def write_dropout(self, duration_ms: int) -> None:
        """'O' message: data was lost for ``duration_ms`` (clamped to uint16)."""
        self.write_raw_message(self.dropout_message(duration_ms))


def _param_type(name: str, value: Any) -> str:
    if isinstance(value, bool):
        return "int32_t"
    if isinstance(value, int):
        return "int32_t"
    if isinstance(value, float):
        return "float"
    raise UlogError(f"parameter {name}: value must be int or float, got {type(value).__name__}")
