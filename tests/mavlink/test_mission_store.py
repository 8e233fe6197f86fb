"""dataman's MissionStore against a partition: what fits, and what a failed save leaves."""

import pytest

from firmware.modules.dataman.store import MissionStore, SaveError
from firmware.platform.params import MemoryPartition


def _items(store, n, alt=10.0):
    return [store.new_item(nav_cmd=16, lat=47.0 + i * 1e-5, lon=8.5, altitude=alt)
            for i in range(n)]


class _Refusing(MemoryPartition):
    """A partition whose writes start failing on demand (a worn or missing FRAM)."""

    fail = False

    def write(self, offset, data):
        return False if self.fail else super().write(offset, data)


def test_capacity_is_what_the_fram_partition_holds():
    assert MissionStore(MemoryPartition(8192)).capacity == 151
    assert MissionStore().capacity == 500  # memory only: the slot size


def test_a_mission_beyond_capacity_raises_and_the_old_one_stays():
    """Defect 3: commit() of 152 items used to activate them unsaved (save()'s False ignored),
    so a power cycle brought back the previous mission."""
    part = MemoryPartition(8192)
    store = MissionStore(part)
    store.store_mission(_items(store, 4))
    with pytest.raises(SaveError):
        store.store_mission(_items(store, 152, alt=20.0))
    assert store.count == 4 and store.items()[0].altitude == 10.0
    again = MissionStore(part)
    assert again.load() == "mission of 4 items loaded"


def test_a_failed_write_raises_and_keeps_the_old_mission_stored():
    part = _Refusing(8192)
    store = MissionStore(part)
    store.store_mission(_items(store, 3))
    part.fail = True
    with pytest.raises(SaveError):
        store.store_mission(_items(store, 2, alt=30.0))
    with pytest.raises(SaveError):
        store.set_current(2)
    assert (store.count, store.current_seq) == (3, 0)
    part.fail = False
    store.save()
    again = MissionStore(part)
    assert again.load() == "mission of 3 items loaded"
    assert again.items()[0].altitude == 10.0
