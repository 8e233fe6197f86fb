"""dataman: mission storage for the navigator and MAVLink's mission protocol.

The module owns one :class:`MissionStore`. Whoever changes the mission (MAVLink after an upload,
a test, ``dataman`` itself after loading from FRAM) goes through the store, and the module
publishes the ``mission`` topic after each change so the navigator reloads: PX4's contract
between the mission manager and the navigator.

The persistence partition comes from the ``partition`` argument, else from
``system.waypoints_partition`` (the FRAM ``waypoints`` partition, when the board wires it), else
the mission lives in memory only.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

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

__all__ = ["MISSION_SLOTS", "DatamanModule", "MissionStore", "SaveError", "StoreError",
           "find_store"]


class DatamanModule(ModuleBase):
    NAME = "dataman"
    DESCRIPTION = "mission storage (two waypoint slots, optional FRAM persistence)"
    USAGE = ("clear             remove the stored mission",)

    def __init__(self, system: System, args: Sequence[str] = (),
                 partition: Partition | None = None) -> None:
        super().__init__(system, args)
        part = partition if partition is not None else getattr(system, "waypoints_partition",
                                                               None)
        self.store = MissionStore(part, system.platform.orb.registry)
        self._msg = system.platform.orb.new("mission")

    def _start(self) -> None:
        self._pub = self.advertise("mission")
        if self.store.partition is not None:
            self.info(self.store.load())
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
                 f"{s.save_failures} failed)")]

    def custom_command(self, args: list[str]) -> int:
        if args[0] == "clear":
            try:
                self.store.clear()
            except SaveError as exc:
                self.print(f"{exc}")
                return 1
            self.print("dataman: mission cleared")
            return 0
        return super().custom_command(args)


def find_store(system: System) -> MissionStore | None:
    """The running dataman's store (the navigator's way in), or None."""
    mod: Any = system.modules.get("dataman")
    return mod.store if isinstance(mod, DatamanModule) else None
