"""The crash-safe storage every dataman list uses: two alternating CRC-guarded records.

A save goes to the record that does not hold the newest valid save, numbered one past it; a
load takes the valid record with the newer save number (wrap-safe,
:func:`~firmware.platform.params.seq_newer`). A power cut at any byte of a save therefore leaves
the old or the new contents, never a mix and never none: the parameter store's scheme, and
PX4's alternation of DM_KEY_WAYPOINTS_OFFBOARD_0/1, DM_KEY_FENCE_POINTS_0/1 and
DM_KEY_SAFE_POINTS_0/1. The mission store (:mod:`.store`) and the fence and rally stores
(:mod:`.points`) keep their lists in a :class:`RecordPair` each.

A record is ``magic | save number | meta | CRC-32`` followed by the body; the CRC covers the
save number, the meta fields and the body. What the meta fields are and how long the body is
are the owner's (:class:`RecordPair` is given the meta layout and a function from the meta
fields to the body length), so the mission's record format is unchanged by this split.

:class:`Window` cuts a partition into regions (mission, fence, rally in the FRAM's waypoint
partition), each a partition of its own to a :class:`RecordPair`.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Callable
from typing import Protocol

from firmware.platform.params import seq_newer

__all__ = ["RECORDS", "Partition", "RecordPair", "Window"]

#: records in a region, written in turn
RECORDS = 2


class Partition(Protocol):
    size: int

    def read(self, offset: int, n: int) -> bytes | None: ...

    def write(self, offset: int, data: bytes) -> bool: ...


class Window:
    """``size`` bytes of ``part`` from ``offset``: a region of a partition that its owner
    sees as a partition starting at 0. Accesses outside the window are refused (a read gives
    None, a write False), so no region's save can touch its neighbour's bytes."""

    def __init__(self, part: Partition, offset: int, size: int) -> None:
        if offset < 0 or size < 0 or offset + size > part.size:
            raise ValueError(f"window 0x{offset:X}+{size} outside a partition of {part.size}")
        self.part = part
        self.offset = offset
        self.size = size

    def read(self, offset: int, n: int) -> bytes | None:
        if offset < 0 or n < 0 or offset + n > self.size:
            return None
        return self.part.read(self.offset + offset, n)

    def write(self, offset: int, data: bytes) -> bool:
        if offset < 0 or offset + len(data) > self.size:
            return False
        return bool(self.part.write(self.offset + offset, data))

    def __repr__(self) -> str:
        return f"{self.part!r}[0x{self.offset:04X}..0x{self.offset + self.size - 1:04X}]"


class RecordPair:
    """Two alternating records in ``part`` (each half of it), with ``magic`` and a ``meta``
    layout of the owner's; ``body_len(meta)`` says how long a record's body is."""

    def __init__(self, part: Partition | None, magic: bytes, meta: str,
                 body_len: Callable[[tuple[int, ...]], int]) -> None:
        if len(magic) != 4:
            raise ValueError("a record magic is 4 bytes")
        self.part = part
        self.magic = magic
        self._meta = struct.Struct("<" + meta)
        self._head = struct.Struct("<4sI" + meta + "I")
        self._crc_fields = struct.Struct("<I" + meta)
        self.body_len = body_len
        #: save number of the newest valid record, and which record holds it (None: no valid
        #: record yet, the next save goes to record 0)
        self.save_seq = 0
        self.newest: int | None = None
        self.saves = 0
        self.failures = 0
        #: what the last load found wrong (a damaged record, named)
        self.problems: list[str] = []

    @property
    def header_size(self) -> int:
        return self._head.size

    @property
    def record_size(self) -> int:
        """Bytes of each record (half the partition; 0 without one)."""
        return 0 if self.part is None else self.part.size // RECORDS

    def body_room(self) -> int:
        """Most body bytes one record holds."""
        return max(0, self.record_size - self._head.size)

    def write(self, meta: tuple[int, ...], body: bytes) -> bool:
        """Save ``meta`` and ``body`` into the record that does not hold the newest save;
        False (and counted) if it does not fit or the device refused, the newest record still
        the one a load finds. Without a partition nothing is written and it is True."""
        part = self.part
        if part is None:
            return True
        if self._head.size + len(body) > self.record_size:
            self.failures += 1
            return False
        try:
            fields = self._crc_fields.pack((self.save_seq + 1) & 0xFFFFFFFF, *meta)
        except struct.error:
            self.failures += 1
            return False
        record = 0 if self.newest is None else (self.newest + 1) % RECORDS
        seq = (self.save_seq + 1) & 0xFFFFFFFF
        head = self._head.pack(self.magic, seq, *meta, zlib.crc32(fields + body))
        base = record * self.record_size
        ok = part.write(base + self._head.size, body) if body else True
        ok = ok and part.write(base, head)
        if ok:
            self.save_seq, self.newest = seq, record
            self.saves += 1
        else:
            self.failures += 1
        return bool(ok)

    def _read(self, record: int) -> tuple[int, tuple[int, ...], bytes] | str:
        """Record ``record``'s save number, meta fields and body, or why it holds none."""
        part = self.part
        assert part is not None
        base = record * self.record_size
        head = part.read(base, self._head.size)
        if head is None or len(head) < self._head.size:
            return "unreadable"
        fields = self._head.unpack(head)
        if fields[0] != self.magic:
            return "empty"
        seq, meta, crc = int(fields[1]), tuple(int(v) for v in fields[2:-1]), int(fields[-1])
        try:
            n = self.body_len(meta)
        except ValueError:
            return "header invalid"
        if n < 0 or self._head.size + n > self.record_size:
            return "header invalid"
        body = part.read(base + self._head.size, n) if n else b""
        if body is None or len(body) != n or \
                zlib.crc32(self._crc_fields.pack(seq, *meta) + body) != crc:
            return "corrupt (CRC)"
        return seq, meta, body

    def load(self) -> tuple[tuple[int, ...], bytes] | None:
        """The newest valid record's meta fields and body; None if there is none. The
        problems met (a damaged record, named) are in :attr:`problems` afterwards."""
        self.problems = []
        if self.part is None:
            return None
        best: tuple[int, int, tuple[int, ...], bytes] | None = None
        for record in range(RECORDS):
            got = self._read(record)
            if isinstance(got, str):
                if got != "empty":
                    self.problems.append(f"record {record} {got}")
                continue
            if best is None or seq_newer(got[0], best[1]):
                best = (record, *got)
        if best is None:
            return None
        record, seq, meta, body = best
        self.save_seq, self.newest = seq, record
        return meta, body

    def note(self) -> str:
        """The last load's problems as a suffix for a status line ("" if none)."""
        return f" ({', '.join(self.problems)}; ignored)" if self.problems else ""
