"""Mission storage: PX4's dataman reduced to what missions need, in memory, optionally persistent.

PX4 keeps two waypoint slots (``dataman_id`` 0 and 1) so that a mission can be uploaded into the
unused slot while the vehicle flies the other; the ``mission`` topic then switches the active slot
in one step. The same scheme is kept here: :meth:`MissionStore.write_item` fills a slot item by
item (the MAVLink mission protocol delivers one item per message), :meth:`MissionStore.commit`
makes it the active mission.

Persistence is a hook: any object with ``size``, ``read(offset, n)`` and ``write(offset, data)``
(the mission region of the FRAM ``waypoints`` partition, a
:class:`~firmware.platform.params.MemoryPartition`). Only the active mission is written, as one
record guarded by a CRC-32, into one of two records that alternate (each half the partition):
:class:`~firmware.modules.dataman.records.RecordPair`, the scheme the fence and rally stores
share, as PX4 alternates DM_KEY_WAYPOINTS_OFFBOARD_0/1. A power cut at any byte of a save
therefore leaves either the old or the new mission, never a mix and never none.

The partition bounds the mission: :attr:`MissionStore.capacity` items, what one record (half the
partition) holds: 65 in the FMUv2's 7 KiB mission region (the waypoint partition's last KiB
holds the fence and rally points, see :mod:`firmware.modules.dataman`). The FRAM's other half
holds the parameters, so the partition cannot grow; real PX4 on FMUv2 keeps dataman on the SD
card, and the demo's missions have 6-7 items. The mission protocol refuses a longer one before
it is sent (MAV_MISSION_NO_SPACE, as PX4 does). A mission becomes active only once it is saved:
a save that fails raises :class:`SaveError` and leaves the previous mission active, in memory
and in storage, so an accepted mission is always the one that comes back after a power cycle.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterable
from typing import Any

from firmware.modules.dataman.records import RECORDS, Partition, RecordPair
from firmware.platform.msgdef import MessageRegistry, default_registry

__all__ = ["MAX_ITEMS", "MISSION_SLOTS", "RECORDS", "MissionStore", "Partition", "SaveError",
           "StoreError"]

#: number of mission slots (PX4's DM_KEY_WAYPOINTS_OFFBOARD_0 / _1)
MISSION_SLOTS = 2
#: most items one slot holds (PX4's DM_KEY_WAYPOINTS_OFFBOARD_0_MAX is 500 on FMUv2)
MAX_ITEMS = 500

_MAGIC = b"DMM2"
#: after the magic and save number: dataman_id, count, current_seq, update counter
#: (the record is magic, save number, these, CRC-32: :class:`RecordPair`)
_META = "BHiH"


class StoreError(ValueError):
    """A bad index, slot or item: a bug in the caller (MAVLink, a test), so it raises."""


class SaveError(RuntimeError):
    """The mission could not be written to its partition (full, or the device refused the
    write). Raised, not returned, so that no caller can report a mission as stored when it
    is not; the previous mission is still the active one."""


class MissionStore:
    """Two mission slots in memory; the active one mirrored to a partition if given."""

    def __init__(self, partition: Partition | None = None,
                 registry: MessageRegistry | None = None) -> None:
        self.registry = registry or default_registry()
        #: the generated mission_item class (its fields, ``pack`` and ``unpack`` come from the
        #: .msg definition at run time)
        self.item_cls: Any = self.registry.cls("mission_item")
        self._item_size = len(self.item_cls().pack())
        self.records = RecordPair(partition, _MAGIC, _META, self._body_len)
        self.slots: list[list[Any]] = [[] for _ in range(MISSION_SLOTS)]
        #: the active mission: slot, item count, item to start/resume at, upload counter
        self.dataman_id = 0
        self.count = 0
        self.current_seq = 0
        self.update_counter = 0
        #: called after the active mission or its current item changed (the module publishes
        #: the ``mission`` topic from here, as PX4's mavlink mission manager does)
        self.listeners: list[Callable[[], None]] = []

    # -- items --------------------------------------------------------------------------------

    def new_item(self, **fields: Any) -> Any:
        """A mission_item with PX4's defaults for what MAVLink leaves out (autocontinue on)."""
        item = self.item_cls()
        item.autocontinue = True
        item.yaw = float("nan")
        for k, v in fields.items():
            setattr(item, k, v)
        return item

    def _slot(self, dataman_id: int) -> list[Any]:
        if type(dataman_id) is not int or not 0 <= dataman_id < MISSION_SLOTS:
            raise StoreError(f"dataman: mission slot must be 0..{MISSION_SLOTS - 1}, "
                             f"got {dataman_id!r}")
        return self.slots[dataman_id]

    def write_item(self, dataman_id: int, index: int, item: Any) -> None:
        """Store ``item`` (a copy) at ``index`` of a slot; indexes fill in order from 0."""
        slot = self._slot(dataman_id)
        if type(index) is not int or not 0 <= index <= len(slot) or index >= MAX_ITEMS:
            raise StoreError(f"dataman: item index {index!r} outside 0..{min(len(slot), MAX_ITEMS - 1)}"
                             f" of slot {dataman_id}")
        if index == len(slot):
            slot.append(item.copy())
        else:
            slot[index] = item.copy()

    def read_item(self, dataman_id: int, index: int) -> Any | None:
        """The stored item (read-only, do not modify) or None past the end."""
        slot = self._slot(dataman_id)
        return slot[index] if 0 <= index < len(slot) else None

    def item(self, index: int) -> Any | None:
        """Item ``index`` of the active mission, or None."""
        if not 0 <= index < self.count:
            return None
        return self.slots[self.dataman_id][index]

    def items(self) -> list[Any]:
        return self.slots[self.dataman_id][: self.count]

    # -- missions -----------------------------------------------------------------------------

    def inactive_slot(self) -> int:
        return (self.dataman_id + 1) % MISSION_SLOTS

    @property
    def capacity(self) -> int:
        """Most items a mission may have: what one record (half the partition) holds, and at
        most :data:`MAX_ITEMS`, the slot size."""
        part = self.partition
        if part is None:
            return MAX_ITEMS
        return max(0, min(MAX_ITEMS, self.records.body_room() // self._item_size))

    def commit(self, dataman_id: int, count: int, current_seq: int = 0) -> None:
        """Make ``count`` items of slot ``dataman_id`` the active mission and save it.

        The new mission is saved first and activated only when the save succeeded; otherwise
        :class:`SaveError` is raised and the old mission stays active (its record was not
        touched: the save went to the other one).
        """
        slot = self._slot(dataman_id)
        if not 0 <= count <= len(slot):
            raise StoreError(f"dataman: commit of {count} items but slot {dataman_id} "
                             f"holds {len(slot)}")
        if count > self.capacity:
            raise SaveError(f"dataman: a mission of {count} items does not fit the storage "
                            f"({self.capacity} items)")
        current_seq = current_seq if 0 <= current_seq < max(count, 1) else 0
        counter = (self.update_counter + 1) & 0xFFFF
        if not self._write_record(dataman_id, slot[:count], current_seq, counter):
            raise SaveError("dataman: the mission could not be written to storage; "
                            "the previous mission stays active")
        del slot[count:]
        self.dataman_id = dataman_id
        self.count = count
        self.current_seq = current_seq
        self.update_counter = counter
        self._changed()

    def store_mission(self, items: Iterable[Any], current_seq: int = 0) -> int:
        """Write a whole mission into the inactive slot and activate it; returns the slot."""
        dm = self.inactive_slot()
        self.slots[dm] = []
        n = 0
        for n, item in enumerate(items, 1):
            self.write_item(dm, n - 1, item)
        self.commit(dm, n, current_seq)
        return dm

    def clear(self) -> None:
        """No mission (MAVLink MISSION_CLEAR_ALL)."""
        self.store_mission(())

    def set_current(self, seq: int) -> bool:
        """Jump to item ``seq`` (MAVLink MISSION_SET_CURRENT); False if out of range.

        Raises :class:`SaveError` (the current item unchanged) if it cannot be saved."""
        if not 0 <= seq < self.count:
            return False
        counter = (self.update_counter + 1) & 0xFFFF
        if not self._write_record(self.dataman_id, self.items(), seq, counter):
            raise SaveError(f"dataman: the current item {seq} could not be saved")
        self.current_seq = seq
        self.update_counter = counter
        self._changed()
        return True

    def _changed(self) -> None:
        for fn in self.listeners:
            fn()

    # -- persistence ----------------------------------------------------------------------------

    @property
    def partition(self) -> Partition | None:
        """Where the mission is saved (None: memory only); the records' partition."""
        return self.records.part

    @partition.setter
    def partition(self, part: Partition | None) -> None:
        self.records.part = part

    @property
    def saves(self) -> int:
        return self.records.saves

    @property
    def save_failures(self) -> int:
        return self.records.failures

    def record_size(self, count: int) -> int:
        """Bytes a saved mission of ``count`` items takes (header and items)."""
        return self.records.header_size + count * self._item_size

    def _body_len(self, meta: tuple[int, ...]) -> int:
        dm, count = meta[0], meta[1]
        if dm >= MISSION_SLOTS:
            raise ValueError("no such slot")
        return count * self._item_size

    def save(self) -> None:
        """Write the active mission to the partition (no-op without one); :class:`SaveError`
        if it does not fit or the write fails."""
        if not self._write_record(self.dataman_id, self.items(), self.current_seq,
                                  self.update_counter):
            raise SaveError("dataman: the mission could not be written to storage")

    def _write_record(self, dataman_id: int, items: list[Any], current_seq: int,
                      counter: int) -> bool:
        """The mission into the record that does not hold the newest save; False (and
        counted) if it failed, the newest record still the one a load finds."""
        if self.partition is None:
            return True
        try:
            body = b"".join(it.pack() for it in items)
        except (struct.error, OverflowError, ValueError):
            self.records.failures += 1  # a field the record cannot hold (no upload stores one)
            return False
        return self.records.write((dataman_id, len(items), current_seq, counter), body)

    def load(self) -> str:
        """Read the newest valid mission saved in the partition; the message says what
        happened (a damaged record is named, the other one still loads)."""
        if self.partition is None:
            return "no mission storage"
        got = self.records.load()
        note = self.records.note()
        if got is None:
            return ("no mission stored" if not self.records.problems
                    else "no valid mission stored") + note
        (dm, count, cur, counter), body = got
        size = self._item_size
        self.slots[dm] = [self.item_cls.unpack(body[i * size:(i + 1) * size])
                          for i in range(count)]
        self.dataman_id, self.count, self.current_seq, self.update_counter = dm, count, cur, counter
        return f"mission of {count} items loaded" + note
