"""dataman: mission, geofence and rally point storage for the navigator, the commander and
MAVLink's mission protocol.

The module owns one :class:`MissionStore` and two :class:`PointStore` s (``fence``, ``rally``).
Whoever changes the mission (MAVLink after an upload, a test, ``dataman`` itself after loading
from FRAM) goes through the store, and the module publishes the ``mission`` topic after each
change so the navigator reloads: PX4's contract between the mission manager and the
navigator. The fence and rally lists are read from their stores by their users (the
commander's geofence, the navigator's RTL), which follow the stores' update counters.

The persistence partition comes from the ``partition`` argument, else from
``system.waypoints_partition`` (the FRAM ``waypoints`` partition, when the board wires it), else
everything lives in memory only. The partition is cut into three regions (:data:`LAYOUT`), each
holding two alternating records (:class:`~firmware.modules.dataman.records.RecordPair`): on the
FMUv2's 8 KiB partition the mission 0x0000-0x19FF (61 items), the fence 0x1A00-0x1DFF (23
items) and the rally points 0x1E00-0x1FFF (11 items). PX4 keeps the same three lists
(DM_KEY_WAYPOINTS_OFFBOARD, DM_KEY_FENCE_POINTS, DM_KEY_SAFE_POINTS), on the SD card.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from firmware.modules.dataman.points import PointStore, fence_problem
from firmware.modules.dataman.records import Window
from firmware.modules.dataman.store import (
    MISSION_SLOTS,
    MissionStore,
    Partition,
    SaveError,
    StoreError,
)
from firmware.platform.module import ModuleBase

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["LAYOUT", "MISSION_SLOTS", "DatamanModule", "MissionStore", "PointStore",
           "SaveError", "StoreError", "find_fence", "find_rally", "find_store"]

#: regions of the waypoint partition, as fractions of 8 KiB (offset, size in bytes on 8 KiB;
#: a partition of another size is scaled): mission, fence, rally
LAYOUT: dict[str, tuple[int, int]] = {"mission": (0x0000, 0x1A00), "fence": (0x1A00, 0x0400),
                                      "rally": (0x1E00, 0x0200)}
#: PX4's DM_KEY_FENCE_POINTS_MAX and DM_KEY_SAFE_POINTS_MAX
FENCE_MAX_ITEMS = 64
RALLY_MAX_ITEMS = 32


def _region(part: Partition | None, name: str) -> Partition | None:
    if part is None:
        return None
    offset, size = LAYOUT[name]
    return Window(part, offset * part.size // 8192, size * part.size // 8192)


class DatamanModule(ModuleBase):
    NAME = "dataman"
    DESCRIPTION = "mission, fence and rally point storage (optional FRAM persistence)"
    USAGE = ("clear             remove the stored mission, fence and rally points",)

    def __init__(self, system: System, args: Sequence[str] = (),
                 partition: Partition | None = None) -> None:
        super().__init__(system, args)
        part = partition if partition is not None else getattr(system, "waypoints_partition",
                                                               None)
        self.store = MissionStore(_region(part, "mission"), system.platform.orb.registry)
        self.fence = PointStore("fence", _region(part, "fence"), b"DMF1", FENCE_MAX_ITEMS,
                                fence_problem)
        self.rally = PointStore("rally points", _region(part, "rally"), b"DMR1",
                                RALLY_MAX_ITEMS)
        self._msg = system.platform.orb.new("mission")

    def _start(self) -> None:
        self._pub = self.advertise("mission")
        if self.store.partition is not None:
            self.info(self.store.load())
            self.info(self.fence.load())
            self.info(self.rally.load())
        self.store.listeners.append(self.publish_mission)
        self.publish_mission()

    def _stop(self) -> None:
        if self.publish_mission in self.store.listeners:
            self.store.listeners.remove(self.publish_mission)

    def publish_mission(self) -> None:
        """Tell the navigator (and MAVLink) which mission is active."""
        s, m = self.store, self._msg
        m.timestamp = self.platform.time_us()
        m.dataman_id = s.dataman_id
        m.count = s.count
        m.current_seq = s.current_seq
        m.mission_update_counter = s.update_counter
        self._pub.publish(m)

    def status_lines(self) -> list[str]:
        s = self.store
        where = "memory only" if s.partition is None else f"saved to {s.partition!r}"
        return [(f"mission: {s.count} of at most {s.capacity} items in slot {s.dataman_id}, "
                 f"current {s.current_seq}, "
                 f"update #{s.update_counter} ({where}, {s.saves} saves, "
                 f"{s.save_failures} failed)")] + [
            f"{p.name}: {p.count} of at most {p.capacity} items, update #{p.update_counter} "
            f"({p.records.saves} saves, {p.records.failures} failed)"
            for p in (self.fence, self.rally)]

    def custom_command(self, args: list[str]) -> int:
        if args[0] == "clear":
            try:
                self.store.clear()
                self.fence.clear()
                self.rally.clear()
            except (SaveError, StoreError) as exc:
                self.print(f"{exc}")
                return 1
            self.print("dataman: mission, fence and rally points cleared")
            return 0
        return super().custom_command(args)


def find_store(system: System) -> MissionStore | None:
    """The running dataman's store (the navigator's way in), or None."""
    mod: Any = system.modules.get("dataman")
    return mod.store if isinstance(mod, DatamanModule) else None


def find_fence(system: System) -> PointStore | None:
    """The running dataman's fence list (the commander's geofence reads it), or None."""
    mod: Any = system.modules.get("dataman")
    return mod.fence if isinstance(mod, DatamanModule) else None


def find_rally(system: System) -> PointStore | None:
    """The running dataman's rally points (the navigator's RTL reads them), or None."""
    mod: Any = system.modules.get("dataman")
    return mod.rally if isinstance(mod, DatamanModule) else None
