"""DroneCAN (UAVCAN v0) 29-bit CAN identifiers: compose and parse.

Shared by the FMU's uavcan driver and the CAN node models, as libuavcan/libcanard is by the
firmware of both ends of a real bus. The layout is the DroneCAN specification's (4.2.1):

* message: priority (5 bits) | data type ID (16) | service 0 (1) | source node ID (7)
* anonymous message (source 0): priority | discriminator (14) | data type ID low 2 bits |
  service 0 | source 0
* service: priority | data type ID (8) | request-not-response (1) | destination (7) |
  service 1 | source node ID (7)

The tail byte, the last byte of every frame: start of transfer (bit 7), end of transfer (6),
toggle (5), transfer ID (4..0).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

__all__ = ["CanId", "PRIORITY_DEFAULT", "PRIORITY_LOWEST", "TAIL_EOT", "TAIL_SOT", "TAIL_TOGGLE",
           "anonymous_id", "message_id", "parse_id", "service_id"]

#: libuavcan's default transfer priority (0 highest .. 31 lowest)
PRIORITY_DEFAULT: Final = 16
PRIORITY_LOWEST: Final = 31
TAIL_SOT: Final = 0x80
TAIL_EOT: Final = 0x40
TAIL_TOGGLE: Final = 0x20


@dataclass(frozen=True)
class CanId:
    """A parsed identifier. ``dest`` is None for messages; ``data_type_id`` of an anonymous
    message holds only the two bits the identifier carries."""

    priority: int
    service: bool
    source: int
    data_type_id: int
    dest: int | None = None
    request: bool = False
    discriminator: int = 0

    @property
    def anonymous(self) -> bool:
        return not self.service and self.source == 0


def _check(name: str, value: int, hi: int, lo: int = 0) -> None:
    if type(value) is not int or not lo <= value <= hi:
        raise ValueError(f"DroneCAN CAN ID: {name} must be {lo}..{hi}, got {value!r}")


def message_id(priority: int, data_type_id: int, source: int) -> int:
    """The identifier of a message from node ``source`` (1..127)."""
    _check("priority", priority, 31)
    _check("data type ID", data_type_id, 0xFFFF)
    _check("source node ID", source, 127, 1)
    return priority << 24 | data_type_id << 8 | source


def anonymous_id(priority: int, data_type_id: int, discriminator: int) -> int:
    """The identifier of an anonymous message (a node without an ID: dynamic allocation)."""
    _check("priority", priority, 31)
    _check("anonymous data type ID", data_type_id, 3)
    _check("discriminator", discriminator, 0x3FFF)
    return priority << 24 | discriminator << 10 | data_type_id << 8


def service_id(priority: int, data_type_id: int, request: bool, dest: int, source: int) -> int:
    """The identifier of a service request (``request``) or response from ``source`` to
    ``dest``."""
    _check("priority", priority, 31)
    _check("service type ID", data_type_id, 0xFF)
    _check("destination node ID", dest, 127, 1)
    _check("source node ID", source, 127, 1)
    return (priority << 24 | data_type_id << 16 | int(bool(request)) << 15 | dest << 8 | 0x80
            | source)


def parse_id(can_id: int) -> CanId:
    """Any 29-bit value parses (a service from source 0 is the caller's to reject)."""
    can_id &= 0x1FFFFFFF
    prio = can_id >> 24
    src = can_id & 0x7F
    if can_id & 0x80:
        return CanId(prio, True, src, (can_id >> 16) & 0xFF, (can_id >> 8) & 0x7F,
                     bool(can_id & 0x8000))
    if src == 0:
        return CanId(prio, False, 0, (can_id >> 8) & 0x3, None, False, (can_id >> 10) & 0x3FFF)
    return CanId(prio, False, src, (can_id >> 8) & 0xFFFF)
