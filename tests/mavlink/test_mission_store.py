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
    assert MissionStore(MemoryPartition(8192)).capacity == 75  # two records of 4 KiB
    assert MissionStore().capacity == 500  # memory only: the slot size


def test_a_mission_beyond_capacity_raises_and_the_old_one_stays():
    """Defect 3: commit() of 76 items (one more than fits) used to activate them unsaved
    (save()'s False ignored), so a power cycle brought back the previous mission."""
    part = MemoryPartition(8192)
    store = MissionStore(part)
    store.store_mission(_items(store, 4))
    with pytest.raises(SaveError):
        store.store_mission(_items(store, 76, alt=20.0))
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


class _PowerCut(MemoryPartition):
    """A partition that loses power after ``budget`` more bytes: the write in progress stops
    there (its first bytes stored) and nothing after it is written."""

    budget: int | None = None

    def write(self, offset, data):
        if self.budget is None:
            return super().write(offset, data)
        n = min(len(data), self.budget)
        super().write(offset, data[:n])
        self.budget -= n
        return n == len(data)


def _alts(store):
    return [it.altitude for it in store.items()]


@pytest.mark.parametrize("op", ["mission", "current"])
def test_a_power_cut_at_any_byte_of_a_save_keeps_the_old_or_the_new_mission(op):
    """Review of defect 3: the single record was written body first, header last, over the
    old one, so a cut between the two left the old header over the new body: CRC failed and
    both missions were lost. A cut at every byte of a save now brings back one of them."""
    part = _PowerCut(8192)
    store = MissionStore(part)
    store.store_mission(_items(store, 3, alt=10.0))
    store.store_mission(_items(store, 5, alt=20.0))  # both records of the partition used
    old = (_alts(store), store.current_seq)
    new = ([30.0] * 4, 0) if op == "mission" else (old[0], 2)
    saved = bytes(part.data)
    outcomes = set()
    for cut in range(0, store.record_size(5) + 8):
        part.data[:] = saved
        store = MissionStore(part)
        assert store.load().startswith("mission of")
        part.budget = cut
        try:
            if op == "mission":
                store.store_mission(_items(store, 4, alt=30.0))
            else:
                store.set_current(2)
        except SaveError:
            pass
        part.budget = None
        again = MissionStore(part)
        message = again.load()
        got = (_alts(again), again.current_seq)
        assert got in (old, new), f"cut after {cut} bytes: {message}, {got}"
        outcomes.add(got == new)
    assert outcomes == {False, True}
